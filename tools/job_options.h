// Options every command that reads a mesh shares (DESIGN.md §3, batch/HPC behaviour): the
// memory limit, the work folder, the thread count, and the progress line on a terminal.
#pragma once

#include <CLI/CLI.hpp>
#include <tbb/global_control.h>

#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "streamcvd/core/mesh/progress.h"
#include "streamcvd/streaming/schedule/memory_budget.h"
#include "streamcvd/streaming/store/store_build.h"

namespace streamcvd::cli {

struct JobOptions {
  std::string memory;    ///< "" = default_memory_limit()
  std::string work_dir;  ///< "" = beside the store, else TMPDIR
  int threads = 0;       ///< 0 = all cores
  std::string progress = "auto";  ///< auto (on a terminal), always, never
};

/// Adds --memory, --work-dir, --threads and --progress to `cmd`, bound to `options`.
void add_job_options(CLI::App* cmd, JobOptions& options, bool with_threads = true);

/// The memory limit in bytes: --memory parsed, or the default (a share of the cgroup limit,
/// else of MemAvailable). Throws InputError for a malformed size.
uint64_t memory_limit(const JobOptions& options);

/// Limits TBB to --threads for its lifetime (nothing when 0).
std::unique_ptr<tbb::global_control> thread_limit(const JobOptions& options);

/// The progress display on stderr, one line per stage, redrawn in place while the stage runs:
/// "ingest: read 1.2 GB / 2.0 GB (60 %), 240 MB/s, 3.1 s, ETA 2 s",
/// "remesh: clustering loop 7, 3 / 5 chunks, 12.4 s". A stage reported as finished keeps its
/// line (its final count and time); finish() clears an unfinished one. Active on a terminal
/// (--progress auto, unless `quiet`) or when forced (always); never on a pipe or in CI logs
/// otherwise. Redraws at most 10 times a second; thread-safe (the reader and the builder of a
/// store report from two threads).
class ProgressLine {
 public:
  /// Lines start with "<command>: "; `quiet` (-q) turns --progress auto off, not always.
  ProgressLine(const std::string& command, const JobOptions& options, bool quiet = false);
  /// Clears an unfinished line (an exception on its way to the one-line error message).
  ~ProgressLine();
  /// Redraws the line for `p` (at most 10 times a second unless `p` ends its stage); a
  /// finished stage's line is ended with a newline and stays. Any thread.
  void update(const StageProgress& p);
  /// Clears the unfinished line, if any, before the command prints its own output.
  void finish();
  /// Whether anything is drawn at all (a job without a display skips the reports).
  bool active() const { return active_; }

 private:
  std::string command_;
  bool active_ = false;
  std::mutex mutex_;
  std::map<std::string, double> stage_starts_;
  double last_draw_ = 0;
  size_t width_ = 0;  // of the unfinished line on screen, 0 = none
};

/// "12.3 MB", "1.2 GB": decimal units, as throughput figures are quoted.
std::string format_bytes(double bytes);

}  // namespace streamcvd::cli
