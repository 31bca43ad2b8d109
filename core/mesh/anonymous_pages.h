// Anonymous memory mapped page by page: the one way this project takes large blocks from the
// system (big arrays, spill blocks, bounce buffers, RAM work files).
#pragma once

#include <sys/mman.h>

#include <cstddef>

namespace streamcvd {

/// Blocks of at least this size are asked to be backed by transparent huge pages.
inline constexpr std::size_t kHugePageBytes = std::size_t(2) << 20;

/// Maps `bytes` of zeroed, page-aligned anonymous memory, or returns nullptr. From 2 MiB on, the
/// block is advised MADV_HUGEPAGE: a first touch then faults 2 MiB at once instead of 4 KiB
/// (where page faults are dear, as in a paravirtualised guest, they were a third of a store
/// build's CPU). O(1); thread-safe; memory: the pages touched (rounded up to huge pages).
inline void* map_anonymous_pages(std::size_t bytes) noexcept {
  void* p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
  if (p == MAP_FAILED) return nullptr;
  if (bytes >= kHugePageBytes) ::madvise(p, bytes, MADV_HUGEPAGE);  // advice only: no error to report
  return p;
}

/// Gives back a block of map_anonymous_pages (same size). O(1); thread-safe.
inline void unmap_anonymous_pages(void* p, std::size_t bytes) noexcept { ::munmap(p, bytes); }

}  // namespace streamcvd
