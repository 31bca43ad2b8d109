// std::vector whose resize() leaves new elements of trivial types uninitialised (default-init
// instead of value-init). For big arrays that a parallel pass fills completely: no serial memset
// first, and each page is faulted in by the thread that fills it.
#pragma once

#include <memory>
#include <new>
#include <utility>
#include <vector>

namespace streamcvd {

template <typename T>
struct DefaultInitAllocator : std::allocator<T> {
  template <typename U>
  struct rebind {
    using other = DefaultInitAllocator<U>;
  };
  DefaultInitAllocator() = default;
  template <typename U>
  DefaultInitAllocator(const DefaultInitAllocator<U>&) noexcept {}
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
