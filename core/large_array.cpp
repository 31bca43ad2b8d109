#include "core/large_array.h"

#include <sys/mman.h>

#include <new>

namespace streamcvd {
namespace {

// mmap'ed anonymous pages: zero without a memset, page-aligned, unmapped at release (malloc would
// keep freed blocks of this size resident in its arenas).
class RamStorage final : public ArrayStorage {
 public:
  void* allocate(size_t bytes, const char*) override {
    void* p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    return p;
  }
  void release(void* data, size_t bytes) noexcept override { ::munmap(data, bytes); }
};

}  // namespace

ArrayStorage& ram_storage() {
  static RamStorage storage;
  return storage;
}

}  // namespace streamcvd
