// Options every command that reads a mesh shares (DESIGN.md §3, batch/HPC behaviour): the
// memory limit, the work folder, the thread count, and the progress line on a terminal.
#pragma once

#include <CLI/CLI.hpp>
#include <tbb/global_control.h>

#include <cstdint>
#include <map>
#include <memory>
#include <string>

#include "streaming/memory_budget.h"
#include "streaming/store_build.h"

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

/// A one-line progress display on stderr: "ingest: read 1.2/2.0 GB (60 %), 240 MB/s, ETA 3 s".
/// Active on a terminal (--progress auto) or when forced (always); never on a pipe or in CI
/// logs otherwise. Redraws at most 10 times a second; finish() clears the line.
class ProgressLine {
 public:
  ProgressLine(const std::string& command, const JobOptions& options);
  ~ProgressLine();
  void update(const BuildProgress& p);
  void finish();
  bool active() const { return active_; }

 private:
  std::string command_;
  bool active_ = false;
  std::string stage_;
  std::map<std::string, double> stage_starts_;
  double last_draw_ = 0;
  size_t width_ = 0;
};

/// "12.3 MB", "1.2 GB": decimal units, as throughput figures are quoted.
std::string format_bytes(double bytes);

}  // namespace streamcvd::cli
