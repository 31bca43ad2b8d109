#include "streamcvd/streaming/store/page_advice.h"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cstdint>

namespace streamcvd {

void advise_pages(const void* data, size_t bytes, int advice, PageSpan span) {
  static const uintptr_t page = uintptr_t(::sysconf(_SC_PAGESIZE));
  const uintptr_t begin = uintptr_t(data), end = begin + bytes;
  const uintptr_t lo = span == PageSpan::Covering ? begin & ~(page - 1) : (begin + page - 1) & ~(page - 1);
  const uintptr_t hi = span == PageSpan::Covering ? (end + page - 1) & ~(page - 1) : end & ~(page - 1);
  if (hi <= lo) return;
  const uintptr_t step = advice == MADV_WILLNEED ? kWillNeedPiece : hi - lo;
  for (uintptr_t p = lo; p < hi; p += step) ::madvise(reinterpret_cast<void*>(p), std::min(step, hi - p), advice);
}

}  // namespace streamcvd
