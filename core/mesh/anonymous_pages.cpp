// How much of malloc's freed memory the process keeps (core/mesh/anonymous_pages.h).
#include "streamcvd/core/mesh/anonymous_pages.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <algorithm>

namespace streamcvd {

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

}  // namespace streamcvd
