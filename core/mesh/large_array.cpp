#include "streamcvd/core/mesh/large_array.h"

#include <new>

#include "streamcvd/core/mesh/anonymous_pages.h"

namespace streamcvd {
namespace {

// mmap'ed anonymous pages: zero without a memset, page-aligned, unmapped at release (malloc would
// keep freed blocks of this size resident in its arenas).
class RamStorage final : public ArrayStorage {
 public:
  void* allocate(size_t bytes, const char*, ArrayUse) override {
    void* p = map_anonymous_pages(bytes);
    if (!p) throw std::bad_alloc();
    return p;
  }
  void release(void* data, size_t bytes) noexcept override { unmap_anonymous_pages(data, bytes); }
};

}  // namespace

ArrayStorage& ram_storage() {
  static RamStorage storage;
  return storage;
}

}  // namespace streamcvd
