// How a job takes fresh memory: populated blocks, malloc's freed memory kept
// (core/mesh/anonymous_pages.h).
#include "streamcvd/core/mesh/anonymous_pages.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>
#include <mutex>

namespace streamcvd {

std::atomic<bool> detail::populate_fresh_blocks{false};

namespace {

std::mutex g_scope_mutex;
int g_scope_depth = 0;

}  // namespace

void keep_freed_heap_memory(std::size_t bytes) noexcept {
#if defined(__GLIBC__)
  if (bytes == 0) {
    ::mallopt(M_MMAP_THRESHOLD, 128 << 10);
    ::mallopt(M_TRIM_THRESHOLD, 128 << 10);
    ::malloc_trim(0);
    return;
  }
  // The largest mmap threshold glibc takes. Both must be set: a trim threshold alone stops the
  // mmap threshold from adapting (every block above 128 KiB mapped afresh: 258k faults on
  // dragon x9 -> 300k), an mmap threshold alone leaves the heap trimmed above 128 KiB free.
  ::mallopt(M_MMAP_THRESHOLD, 32 << 20);
  ::mallopt(M_TRIM_THRESHOLD, int(std::min<std::size_t>(bytes, std::size_t(1) << 30)));
#else
  (void)bytes;
#endif
}

InCoreMemory::InCoreMemory(std::uint64_t memory_limit) {
  std::lock_guard lock(g_scope_mutex);
  if (g_scope_depth++ > 0) return;
  const std::uint64_t share = memory_limit == 0 ? ~std::uint64_t(0) : memory_limit / 16;
  keep_freed_heap_memory(std::size_t(std::min<std::uint64_t>(share, std::uint64_t(256) << 20)));
  detail::populate_fresh_blocks.store(true, std::memory_order_relaxed);
}

InCoreMemory::~InCoreMemory() {
  std::lock_guard lock(g_scope_mutex);
  if (--g_scope_depth > 0) return;
  detail::populate_fresh_blocks.store(false, std::memory_order_relaxed);
  keep_freed_heap_memory(0);
}

}  // namespace streamcvd
