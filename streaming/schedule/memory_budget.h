// Memory limits and measurements for `--memory` (DESIGN.md §3, §7): what a job may use, and what
// it did use. A limit decides how much a stage keeps resident (bucket sizes of the store build,
// resident chunks of the remesher); it never changes the order of the work, so outputs do not
// depend on it.
#pragma once

#include <cstdint>
#include <string>

namespace streamcvd {

/// Parses "2G", "512M", "1.5GiB", "64m", "1000000" (bytes; K/M/G/T are binary multiples, an
/// optional trailing "B"/"iB"). Throws InputError naming `text` when it is not a size.
uint64_t parse_memory_size(const std::string& text);

/// "2.0 GiB", "512 MiB", "4 KiB", "17 B": the form used in reports and errors.
std::string format_memory_size(uint64_t bytes);

/// Memory limit of this process's cgroup (v1 or v2, the smallest along its ancestry), or 0
/// when there is none. Reads /proc/self/cgroup and /sys/fs/cgroup; O(depth) small file reads.
uint64_t cgroup_memory_limit();

/// MemAvailable of /proc/meminfo in bytes (0 if unknown).
uint64_t available_memory();

/// The default limit when `--memory` is not given: 3/4 of the cgroup limit when there is one
/// (page cache and anonymous memory both count there), else 1/2 of MemAvailable; never below
/// 64 MiB.
uint64_t default_memory_limit();

/// Where a measured peak comes from.
enum class PeakSource { Cgroup, Rss };

struct MemoryPeak {
  uint64_t bytes = 0;
  PeakSource source = PeakSource::Rss;
};

/// Peak memory of this job so far: the cgroup's peak (memory.peak / max_usage_in_bytes) when the
/// process runs in a cgroup with a limit (as under `memlimit`), else the peak RSS (VmHWM).
MemoryPeak measure_peak_memory();

/// Current resident anonymous memory of this process (RssAnon of /proc/self/status), bytes. The
/// figure a test of memory bounds can assert on without a cgroup.
uint64_t resident_anonymous_bytes();

/// Peak RSS of this process (VmHWM), bytes.
uint64_t peak_rss_bytes();

/// Bytes this process made the storage layer read and write (read_bytes / write_bytes of
/// /proc/self/io: disk traffic, page cache hits excluded); zeros where unavailable.
struct IoCounters {
  uint64_t read_bytes = 0, write_bytes = 0;
};
IoCounters read_io_counters();

}  // namespace streamcvd
