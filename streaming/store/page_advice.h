// Page advice on mapped files (the store's arrays, the job's work files): the one place that
// rounds a byte range to pages and calls madvise.
#pragma once

#include <cstddef>

namespace streamcvd {

/// Which pages of a byte range an advice applies to.
enum class PageSpan {
  Covering,  ///< every page the range touches (reading ahead: a shared edge page is wanted too)
  Inside,    ///< only pages wholly inside it (releasing: a neighbour's data on an edge page stays)
};

/// madvise(`advice`) over [data, data + bytes), rounded to pages by `span`. MADV_WILLNEED goes
/// in pieces of kWillNeedPiece bytes: Linux reads at most max(read-ahead window, device I/O
/// size) per call (force_page_cache_ra), so one call over a 55 MB chunk read its first 8 MB
/// and left the rest to page faults. O(bytes / piece) system calls; thread-safe; errors
/// ignored (advice only).
void advise_pages(const void* data, size_t bytes, int advice, PageSpan span);

/// Bytes per MADV_WILLNEED call: the kernel's default read-ahead window, the smallest cap seen.
inline constexpr size_t kWillNeedPiece = size_t(128) << 10;

}  // namespace streamcvd
