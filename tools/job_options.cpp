#include "tools/job_options.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>

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

ProgressLine::ProgressLine(const std::string& command, const JobOptions& options) : command_(command) {
  active_ = options.progress == "always" || (options.progress == "auto" && ::isatty(STDERR_FILENO));
}

ProgressLine::~ProgressLine() { finish(); }

void ProgressLine::update(const BuildProgress& p) {
  if (!active_) return;
  const double now = now_seconds();
  // Stages may interleave (the reader reports bytes while the builder reports faces): each keeps
  // its own start time, and the line is redrawn at most 10 times a second.
  auto started = stage_starts_.try_emplace(p.stage, now).first;
  if (now - last_draw_ < 0.1 && p.done < p.total) return;
  stage_ = p.stage;
  last_draw_ = now;
  const double elapsed = std::max(1e-6, now - started->second);
  const bool bytes = stage_ == "read";
  std::string line = command_ + ": " + stage_ + " ";
  char buf[160];
  if (bytes) {
    line += format_bytes(double(p.done));
    if (p.total > 0) {
      std::snprintf(buf, sizeof buf, " / %s (%.0f %%)", format_bytes(double(p.total)).c_str(), 100.0 * double(p.done) / double(p.total));
      line += buf;
    }
    line += ", " + format_bytes(double(p.done) / elapsed) + "/s";
  } else {
    std::snprintf(buf, sizeof buf, "%llu / %llu", (unsigned long long)p.done, (unsigned long long)p.total);
    line += buf;
  }
  if (p.total > 0 && p.done > 0 && p.done < p.total) {
    std::snprintf(buf, sizeof buf, ", ETA %.0f s", elapsed * double(p.total - p.done) / double(p.done));
    line += buf;
  }
  std::fprintf(stderr, "\r%s%*s", line.c_str(), int(width_ > line.size() ? width_ - line.size() : 0), "");
  std::fflush(stderr);
  width_ = line.size();
}

void ProgressLine::finish() {
  if (!active_ || width_ == 0) return;
  std::fprintf(stderr, "\r%*s\r", int(width_), "");
  std::fflush(stderr);
  width_ = 0;
}

}  // namespace streamcvd::cli
