#include "streamcvd/streaming/schedule/work_space.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <map>
#include <new>

#include "streamcvd/core/mesh/anonymous_pages.h"
#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/output_file.h"
#include "streamcvd/streaming/store/page_advice.h"

namespace streamcvd {
namespace {

// Which mappings are file-backed (their bytes were counted in files_), by address.
std::mutex g_mapped_mutex;
std::map<const void*, bool> g_file_backed;

int create_work_file(const std::string& folder) {
  int fd = ::open(folder.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  for (int attempt = 0; fd < 0 && attempt < 16; ++attempt) {  // no O_TMPFILE: named, unlinked at once
    const std::string name = folder + "/.streamcvd-work." + std::to_string(::getpid()) + "." +
                             std::to_string(std::chrono::steady_clock::now().time_since_epoch().count());
    fd = ::open(name.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
    if (fd >= 0) ::unlink(name.c_str());
    else if (errno != EEXIST) break;
  }
  return fd;
}

}  // namespace

WorkSpace::WorkSpace(std::string folder, uint64_t ram_budget) : folder_(std::move(folder)), ram_budget_(ram_budget) {
  if (folder_.empty()) {
    const char* tmp = std::getenv("TMPDIR");
    folder_ = tmp && *tmp ? tmp : "/tmp";
  }
  ignore_file_size_signal();
}

void* WorkSpace::allocate(size_t bytes, const char* name, ArrayUse use) {
  bool in_ram = false;
  {
    std::lock_guard lock(mutex_);
    // A cold array in RAM would take the place of a hot one allocated later (at 105M faces
    // in 2 GiB the component ids held 211 MB of it while the labels went to a file): it may
    // use RAM only while it leaves half the budget to the hot ones.
    const uint64_t budget = use == ArrayUse::Hot ? ram_budget_ : ram_budget_ / 2;
    if (ram_.load() + bytes <= budget) {
      ram_ += bytes;
      in_ram = true;
    }
  }
  if (in_ram) {
    void* p = map_anonymous_pages(bytes);
    if (!p) {
      ram_ -= bytes;
      throw std::bad_alloc();
    }
    std::lock_guard lock(g_mapped_mutex);
    g_file_backed[p] = false;
    return p;
  }
  auto fail = [&](const char* what) -> void* {
    throw OutputError(error_at(folder_, std::string("cannot ") + what + " a work file for " + name + " (" +
                                            std::to_string(bytes) + " bytes): " + work_file_problem(errno)));
  };
  const int fd = create_work_file(folder_);
  if (fd < 0) return fail("create");
  // Reserve the blocks now: a full disk fails here, not with a SIGBUS when a page is written.
  int r = ::posix_fallocate(fd, 0, off_t(bytes));
  if (r == EOPNOTSUPP || r == EINVAL) r = ::ftruncate(fd, off_t(bytes)) == 0 ? 0 : errno;  // no fallocate here
  if (r != 0) {
    errno = r;
    ::close(fd);
    return fail("reserve");
  }
  void* p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
  ::close(fd);  // the mapping keeps the file
  if (p == MAP_FAILED) return fail("map");
  const uint64_t now = files_ += bytes;
  for (uint64_t peak = peak_files_.load(); now > peak && !peak_files_.compare_exchange_weak(peak, now);) {
  }
  {
    std::lock_guard lock(mutex_);
    file_regions_[p] = bytes;
  }
  std::lock_guard lock(g_mapped_mutex);
  g_file_backed[p] = true;
  return p;
}

void WorkSpace::release(void* data, size_t bytes) noexcept {
  bool file_backed = false;
  {
    std::lock_guard lock(g_mapped_mutex);
    auto it = g_file_backed.find(data);
    if (it != g_file_backed.end()) file_backed = it->second, g_file_backed.erase(it);
  }
  if (file_backed) {
    std::lock_guard lock(mutex_);
    file_regions_.erase(data);
  }
  ::munmap(data, bytes);
  if (file_backed) files_ -= bytes;
  else ram_ -= bytes;
}

std::vector<std::pair<const void*, size_t>> WorkSpace::file_regions(uint32_t V) const {
  std::vector<std::pair<const void*, size_t>> out;
  if (V == 0) return out;
  std::lock_guard lock(mutex_);
  for (const auto& [data, bytes] : file_regions_)
    if (bytes % V == 0 && bytes / V >= 1 && bytes / V <= 256) out.push_back({data, bytes});
  return out;
}

void WorkSpace::will_need(const void* data, size_t bytes) { advise_pages(data, bytes, MADV_WILLNEED, PageSpan::Covering); }

// Only whole pages inside the range: a neighbour's data on a shared page must stay.
void WorkSpace::dont_need(const void* data, size_t bytes) { advise_pages(data, bytes, MADV_PAGEOUT, PageSpan::Inside); }

}  // namespace streamcvd
