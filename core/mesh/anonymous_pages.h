// Anonymous memory mapped page by page: the one way this project takes large blocks from the
// system (big arrays, spill blocks, bounce buffers, RAM work files); and how a job that fits in
// RAM takes fresh pages (populated at once, malloc's freed memory kept).
#pragma once

#include <sys/mman.h>

#include <atomic>
#include <cstddef>
#include <cstdint>

namespace streamcvd {

/// The size of the blocks streamed through the spill buckets and the store writer: 2 MiB, a
/// huge page's size, so a kernel that backs memory with huge pages by itself can back them.
inline constexpr std::size_t kLargeBlockBytes = std::size_t(2) << 20;

namespace detail {
/// Set while an InCoreMemory scope lives.
extern std::atomic<bool> populate_fresh_blocks;
}  // namespace detail

/// Maps `bytes` of zeroed, page-aligned anonymous memory, or returns nullptr. No huge-page
/// advice: with the common `defrag=madvise` setting, MADV_HUGEPAGE makes each first touch of a
/// 2 MiB region compact memory synchronously when no free huge page is at hand, which page
/// cache makes the usual case (and a memory cgroup, always). Measured on this 2-core guest (a
/// fresh page is dear here, 1.5-3.5 us): dragon -> 20k took 0.68-1.62 s with the advice (system
/// time up to 1.06 s) and 0.70-0.75 s without; the 105M-face ingest inside 2 GiB 18-24 s against
/// 13 s; dragon x9 ingest 1.06-3.59 s against 1.10-1.25 s. Where the kernel
/// hands out huge pages by itself (`enabled=always`) they still come, without the stalls.
/// Inside an InCoreMemory scope, blocks of 1 MiB or more are populated by the mmap call itself.
/// O(1) (O(bytes) when populated); thread-safe; memory: the pages touched (all, when populated).
inline void* map_anonymous_pages(std::size_t bytes) noexcept {
  const bool populate =
      bytes >= (std::size_t(1) << 20) && detail::populate_fresh_blocks.load(std::memory_order_relaxed);
  void* p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | (populate ? MAP_POPULATE : 0),
                   -1, 0);
  return p == MAP_FAILED ? nullptr : p;
}

/// Gives back a block of map_anonymous_pages (same size). O(1); thread-safe.
inline void unmap_anonymous_pages(void* p, std::size_t bytes) noexcept { ::munmap(p, bytes); }

/// Lets malloc keep up to `bytes` of freed memory for the next allocations instead of returning
/// it at once (glibc: allocations below 32 MiB come from its heap, trimmed only above `bytes`
/// free; elsewhere nothing). A fresh page costs a fault and zeroing, 1.5-14 us in the
/// paravirtualised guests measured: dragon x9 -> 300k made 120-160k faults (0.9-1.4 s of
/// system time) with malloc's defaults, 97k (0.6-0.8 s) with 256 MiB kept, for 5 MB more peak
/// RSS. 0 gives glibc's default thresholds back (not their adaptation) and trims the heap.
/// Process-wide; thread-safe.
void keep_freed_heap_memory(std::size_t bytes) noexcept;

/// While one lives, the process takes memory as a job that fits in RAM should: blocks of
/// map_anonymous_pages of 1 MiB or more come populated (one mmap call maps all their pages,
/// which a job in core touches anyway: 5.6 us a page in this guest against 10.6 us for a fault
/// each; alternated runs: dragon -> 20k 1.16 -> 0.86 s, dragon x9 -> 300k 4.62 -> 4.28 s, its
/// ingest 3.15 -> 2.52 s, for +3, +6 and +25 MB of peak RSS), and malloc keeps freed memory for the next allocations (keep_freed_heap_memory): a
/// sixteenth of the job's `memory_limit` (0 = none), at most 256 MiB.
/// Out of core neither is wanted (pages not needed yet, kept memory taking the page cache's
/// room): no scope. Nested scopes: the outermost one sets and resets. Process-wide.
class InCoreMemory {
 public:
  explicit InCoreMemory(std::uint64_t memory_limit);
  ~InCoreMemory();
  InCoreMemory(const InCoreMemory&) = delete;
  InCoreMemory& operator=(const InCoreMemory&) = delete;
};

}  // namespace streamcvd
