#include "streamcvd/streaming/schedule/memory_budget.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string_view>
#include <vector>

#include "streamcvd/core/mesh/errors.h"

namespace streamcvd {
namespace {

// First unsigned number of a small text file, or `fallback`. "max" (cgroup v2) reads as fallback.
uint64_t read_number(const std::string& path, uint64_t fallback) {
  std::ifstream in(path);
  std::string word;
  if (!(in >> word) || word.empty() || !std::isdigit(static_cast<unsigned char>(word[0]))) return fallback;
  return std::strtoull(word.c_str(), nullptr, 10);
}

// Value in kB of a "Key:   123 kB" line of a /proc file, as bytes (0 if missing).
uint64_t proc_field_kb(const char* file, std::string_view key) {
  std::ifstream in(file);
  std::string line;
  while (std::getline(in, line))
    if (line.compare(0, key.size(), key) == 0 && line.size() > key.size() && line[key.size()] == ':')
      return std::strtoull(line.c_str() + key.size() + 1, nullptr, 10) * 1024;
  return 0;
}

// "/a/b" → {"/a/b", "/a", ""}: a cgroup and its ancestors, innermost first.
std::vector<std::string> ancestry(std::string path) {
  std::vector<std::string> out;
  while (!path.empty() && path.back() == '/') path.pop_back();
  for (;;) {
    out.push_back(path);
    if (path.empty()) return out;
    path.resize(path.find_last_of('/'));
  }
}

// This process's cgroup folders with a memory controller, innermost first, and whether they are
// v1 (memory.limit_in_bytes) or v2 (memory.max).
struct CgroupDirs {
  std::vector<std::string> dirs;
  bool v1 = false;
};

CgroupDirs cgroup_dirs() {
  CgroupDirs out;
  std::ifstream in("/proc/self/cgroup");
  std::string line, v2_path;
  while (std::getline(in, line)) {
    // "hierarchy-id:controllers:path"
    const size_t a = line.find(':'), b = line.find(':', a + 1);
    if (a == std::string::npos || b == std::string::npos) continue;
    const std::string controllers = "," + line.substr(a + 1, b - a - 1) + ",", path = line.substr(b + 1);
    if (controllers.find(",memory,") != std::string::npos) {
      out.v1 = true;
      for (const std::string& p : ancestry(path)) out.dirs.push_back("/sys/fs/cgroup/memory" + p);
      return out;
    }
    if (line.compare(0, 3, "0::") == 0) v2_path = path;
  }
  if (v2_path.empty()) return out;
  for (const char* base : {"/sys/fs/cgroup/unified", "/sys/fs/cgroup"}) {
    if (!std::ifstream(std::string(base) + "/cgroup.controllers")) continue;
    for (const std::string& p : ancestry(v2_path)) out.dirs.push_back(base + p);
    break;
  }
  return out;
}

constexpr uint64_t kNoLimit = ~uint64_t(0);

}  // namespace

uint64_t parse_memory_size(const std::string& text) {
  auto fail = [&]() -> uint64_t {
    throw InputError("--memory: '" + text + "' is not a memory size (use e.g. 2G, 512M, 1.5G)");
  };
  size_t i = 0;
  while (i < text.size() && (std::isdigit(static_cast<unsigned char>(text[i])) || text[i] == '.')) ++i;
  if (i == 0) return fail();
  double value = 0;
  try {
    size_t used = 0;
    value = std::stod(text.substr(0, i), &used);
    if (used != i) return fail();
  } catch (...) {
    return fail();
  }
  std::string unit = text.substr(i);
  for (char& c : unit) c = char(std::toupper(static_cast<unsigned char>(c)));
  if (unit.size() >= 2 && unit.substr(unit.size() - 2) == "IB") unit.resize(unit.size() - 2);
  else if (!unit.empty() && unit.back() == 'B') unit.pop_back();
  double scale = 1;
  if (unit == "K") scale = 1024.0;
  else if (unit == "M") scale = 1024.0 * 1024;
  else if (unit == "G") scale = 1024.0 * 1024 * 1024;
  else if (unit == "T") scale = 1024.0 * 1024 * 1024 * 1024;
  else if (!unit.empty()) return fail();
  const double bytes = value * scale;
  if (!(bytes >= 1) || bytes > 1.8e19) return fail();
  return uint64_t(bytes);
}

std::string format_memory_size(uint64_t bytes) {
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB"};
  double v = double(bytes);
  int u = 0;
  while (v >= 1024 && u < 4) v /= 1024, ++u;
  char buf[32];
  if (u == 0) std::snprintf(buf, sizeof buf, "%llu B", (unsigned long long)bytes);
  else std::snprintf(buf, sizeof buf, v < 10 ? "%.1f %s" : "%.0f %s", v, units[u]);
  return buf;
}

uint64_t cgroup_memory_limit() {
  const CgroupDirs cg = cgroup_dirs();
  uint64_t limit = kNoLimit;
  for (const std::string& d : cg.dirs)
    limit = std::min(limit, read_number(d + (cg.v1 ? "/memory.limit_in_bytes" : "/memory.max"), kNoLimit));
  // v1 reports "no limit" as a huge page-rounded number.
  return limit >= (uint64_t(1) << 60) ? 0 : limit;
}

uint64_t available_memory() { return proc_field_kb("/proc/meminfo", "MemAvailable"); }

uint64_t default_memory_limit() {
  constexpr uint64_t kFloor = uint64_t(64) << 20;
  const uint64_t cgroup = cgroup_memory_limit();
  if (cgroup > 0) return std::max(kFloor, cgroup / 4 * 3);
  const uint64_t available = available_memory();
  return available > 0 ? std::max(kFloor, available / 2) : uint64_t(1) << 30;
}

MemoryPeak measure_peak_memory() {
  MemoryPeak peak{peak_rss_bytes(), PeakSource::Rss};
  if (cgroup_memory_limit() == 0) return peak;
  const CgroupDirs cg = cgroup_dirs();
  if (cg.dirs.empty()) return peak;
  const uint64_t bytes =
      read_number(cg.dirs.front() + (cg.v1 ? "/memory.max_usage_in_bytes" : "/memory.peak"), 0);
  if (bytes > 0) peak = {bytes, PeakSource::Cgroup};
  return peak;
}

uint64_t resident_anonymous_bytes() { return proc_field_kb("/proc/self/status", "RssAnon"); }

uint64_t peak_rss_bytes() { return proc_field_kb("/proc/self/status", "VmHWM"); }

IoCounters read_io_counters() {
  IoCounters io;
  std::ifstream in("/proc/self/io");
  std::string key;
  uint64_t value = 0;
  while (in >> key >> value) {
    if (key == "read_bytes:") io.read_bytes = value;
    if (key == "write_bytes:") io.write_bytes = value;
  }
  return io;
}

}  // namespace streamcvd
