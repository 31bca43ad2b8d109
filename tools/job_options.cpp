#include "tools/job_options.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

#include "tools/commands.h"

namespace streamcvd::cli {

void add_job_options(CLI::App* cmd, JobOptions& options, bool with_threads) {
  cmd->add_option("--memory", options.memory,
                  "Memory the job may use, e.g. 2G or 512M (default: 3/4 of the cgroup limit, else 1/2 of the "
                  "available memory). Changes what stays resident, never the result");
  cmd->add_option("--work-dir", options.work_dir,
                  "Folder of the scratch files (anonymous, removed whatever happens; default: beside the store, else "
                  "TMPDIR)");
  if (with_threads)
    cmd->add_option("--threads", options.threads, "Worker threads (0 = all cores)")->check(CLI::Range(0, 4096));
  cmd->add_option("--progress", options.progress, "Progress line on stderr: auto (on a terminal), always, never")
      ->check(CLI::IsMember({"auto", "always", "never"}))
      ->capture_default_str();
}

uint64_t memory_limit(const JobOptions& options) {
  return options.memory.empty() ? default_memory_limit() : parse_memory_size(options.memory);
}

std::unique_ptr<tbb::global_control> thread_limit(const JobOptions& options) {
  if (options.threads <= 0) return nullptr;
  return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(options.threads));
}

std::string format_bytes(double bytes) {
  char buf[32];
  if (bytes >= 1e9) std::snprintf(buf, sizeof buf, "%.2f GB", bytes / 1e9);
  else if (bytes >= 1e6) std::snprintf(buf, sizeof buf, "%.1f MB", bytes / 1e6);
  else std::snprintf(buf, sizeof buf, "%.0f kB", bytes / 1e3);
  return buf;
}

ProgressLine::ProgressLine(const std::string& command, const JobOptions& options, bool quiet) : command_(command) {
  active_ = options.progress == "always" || (options.progress == "auto" && !quiet && ::isatty(STDERR_FILENO));
}

ProgressLine::~ProgressLine() { finish(); }

void ProgressLine::update(const StageProgress& p) {
  if (!active_) return;
  std::lock_guard lock(mutex_);
  const double now = now_seconds();
  // Stages may interleave (the reader reports bytes while the builder reports faces): each keeps
  // its own start time. The end of a stage is always drawn, the rest at most 10 times a second.
  auto started = stage_starts_.try_emplace(p.stage, now).first;
  const bool complete = p.finished || (p.total > 0 && p.done >= p.total);
  if (now - last_draw_ < 0.1 && !complete) return;
  last_draw_ = now;
  const double elapsed = now - started->second;
  const double fraction = p.fraction >= 0 ? p.fraction : p.total > 0 ? double(p.done) / double(p.total) : -1;
  const bool bytes = std::strcmp(p.unit, "bytes") == 0;
  auto count = [&](uint64_t n) { return bytes ? format_bytes(double(n)) : std::to_string(n); };
  std::string line = command_ + ": " + p.stage;
  std::vector<std::string> parts;  // joined by ", " after the stage name
  if (p.round > 0) line += std::string(" ") + p.round_unit + " " + std::to_string(p.round);
  if (p.total > 0 || p.done > 0) {
    std::string what = count(p.done) + (p.total > 0 ? " / " + count(p.total) : "");
    if (!bytes && *p.unit) what += std::string(" ") + p.unit;
    if (!p.finished && fraction >= 0) what += " (" + std::to_string(int(std::min(1.0, fraction) * 100)) + " %)";
    parts.push_back(what);
  }
  char buf[64];
  if (bytes && elapsed > 0) parts.push_back(format_bytes(double(p.done) / elapsed) + "/s");
  std::snprintf(buf, sizeof buf, "%.1f s", elapsed);
  parts.push_back(buf);
  // An ETA only where the stage's end is known: a single pass with a total, well under way.
  if (!p.finished && p.round == 0 && fraction > 0 && fraction < 1 && elapsed > 0.5) {
    std::snprintf(buf, sizeof buf, "ETA %.0f s", elapsed * (1 - fraction) / fraction);
    parts.push_back(buf);
  }
  for (size_t i = 0; i < parts.size(); ++i) line += (i == 0 && p.round == 0 ? " " : ", ") + parts[i];
  // A shorter line first blanks the longer one it replaces: no trailing spaces are left.
  if (line.size() < width_) std::fprintf(stderr, "\r%*s", int(width_), "");
  std::fprintf(stderr, "\r%s%s", line.c_str(), p.finished ? "\n" : "");
  std::fflush(stderr);
  width_ = p.finished ? 0 : line.size();
}

void ProgressLine::finish() {
  if (!active_) return;
  std::lock_guard lock(mutex_);
  if (width_ == 0) return;
  std::fprintf(stderr, "\r%*s\r", int(width_), "");
  std::fflush(stderr);
  width_ = 0;
}

}  // namespace streamcvd::cli
