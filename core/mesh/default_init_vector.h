// std::vector whose resize() leaves new elements of trivial types uninitialised (default-init
// instead of value-init). For big arrays that a parallel pass fills completely: no serial memset
// first, and each page is faulted in by the thread that fills it. Big arrays are page-aligned.
#pragma once

#include <cstddef>
#include <memory>
#include <new>
#include <utility>
#include <vector>

#include "streamcvd/core/mesh/anonymous_pages.h"

namespace streamcvd {

inline constexpr std::size_t kPageAlignFrom = std::size_t(1) << 20;

template <typename T>
struct DefaultInitAllocator : std::allocator<T> {
  template <typename U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  DefaultInitAllocator() = default;
  template <typename U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}
  /// Arrays of 1 MiB or more are mapped pages of their own: page-aligned, so direct I/O writes
  /// them in place, and unmapped when freed (malloc's memalign would carve them from its heap,
  /// which keeps freed memory resident and raises the peak RSS).
  T* allocate(std::size_t n) {
    if (n * sizeof(T) < kPageAlignFrom) return std::allocator<T>::allocate(n);
    if (n > std::size_t(-1) / sizeof(T)) throw std::bad_array_new_length();
    void* p = map_anonymous_pages(n * sizeof(T));
    if (!p) throw std::bad_alloc();
    return static_cast<T*>(p);
  }
  void deallocate(T* p, std::size_t n) noexcept {
    if (n * sizeof(T) < kPageAlignFrom) return std::allocator<T>::deallocate(p, n);
    unmap_anonymous_pages(p, n * sizeof(T));
  }
  /// construct(p) default-initialises (no zeroing); with arguments it constructs as usual.
  template <typename U, typename... Args>
  void construct(U* p, Args&&... args) {
    if constexpr (sizeof...(Args) == 0)
      ::new (static_cast<void*>(p)) U;
    else
      ::new (static_cast<void*>(p)) U(std::forward<Args>(args)...);
  }
};

/// resize(n) leaves new elements uninitialised; resize(n, value), assign and push_back as usual.
template <typename T>
using DefaultInitVector = std::vector<T, DefaultInitAllocator<T>>;

}  // namespace streamcvd
