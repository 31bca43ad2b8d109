// Arrays sized by the input (V or F entries) that the remeshing stages create: labels, item
// data, component ids, scratch. Where they live is the job's choice (DESIGN.md §3): RAM by
// default; the out-of-core pipeline supplies an ArrayStorage that maps anonymous work files
// (streaming/schedule/work_space.h), so the same stage code runs in core and out of core and its memory
// is reclaimable page cache, touched chunk by chunk.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <type_traits>
#include <utility>

namespace streamcvd {

/// How an array is used, for a storage that keeps some arrays in RAM and the rest in files.
enum class ArrayUse : uint8_t {
  Hot,   ///< read again and again (labels, item data): RAM while the budget lasts
  Cold,  ///< written once and read at the end (component ids for the checks): a file if any
};

/// Where LargeArrays get their memory. Implementations are thread-safe.
class ArrayStorage {
 public:
  virtual ~ArrayStorage() = default;
  /// `bytes` of page-aligned memory reading as zero; `name` labels it in reports. Throws
  /// std::bad_alloc (RAM) or OutputError (a work file that cannot be created).
  virtual void* allocate(size_t bytes, const char* name, ArrayUse use) = 0;
  /// Returns memory from allocate() (same size). Never throws.
  virtual void release(void* data, size_t bytes) noexcept = 0;
  /// The range will be used soon / not for a while (madvise on work files; RAM ignores it).
  virtual void will_need(const void* data, size_t bytes) { (void)data, (void)bytes; }
  virtual void dont_need(const void* data, size_t bytes) { (void)data, (void)bytes; }
};

/// Anonymous RAM pages (mmap): page-aligned and zero without a memset, returned at release.
ArrayStorage& ram_storage();

/// A fixed-size array of trivially copyable T from an ArrayStorage: zero-initialised, move-only,
/// released with its owner. Indexing and spans like std::vector, without resizing.
template <typename T>
class LargeArray {
  static_assert(std::is_trivially_copyable_v<T>, "LargeArray holds plain data");

 public:
  LargeArray() = default;
  explicit LargeArray(size_t n, ArrayStorage& storage = ram_storage(), const char* name = "",
                      ArrayUse use = ArrayUse::Hot)
      : storage_(&storage), size_(n) {
    if (n > 0) data_ = static_cast<T*>(storage.allocate(n * sizeof(T), name, use));
  }
  /// n copies of `value` (a parallel-free fill: use for small arrays or one-off setup).
  LargeArray(size_t n, T value, ArrayStorage& storage = ram_storage(), const char* name = "")
      : LargeArray(n, storage, name) {
    fill(value);
  }
  ~LargeArray() { reset(); }
  LargeArray(LargeArray&& o) noexcept { swap(o); }
  LargeArray& operator=(LargeArray&& o) noexcept {
    if (this != &o) {
      reset();
      swap(o);
    }
    return *this;
  }
  LargeArray(const LargeArray&) = delete;
  LargeArray& operator=(const LargeArray&) = delete;

  void swap(LargeArray& o) noexcept {
    std::swap(storage_, o.storage_);
    std::swap(data_, o.data_);
    std::swap(size_, o.size_);
  }
  void reset() noexcept {
    if (data_) storage_->release(data_, size_ * sizeof(T));
    data_ = nullptr;
    size_ = 0;
  }
  /// A copy in the same storage (explicit: these arrays are large).
  LargeArray clone() const {
    LargeArray out(size_, *storage_);
    if (size_ > 0) std::memcpy(out.data_, data_, size_ * sizeof(T));
    return out;
  }
  void fill(T value) {
    for (size_t i = 0; i < size_; ++i) data_[i] = value;
  }

  T* data() { return data_; }
  const T* data() const { return data_; }
  size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  T& operator[](size_t i) { return data_[i]; }
  const T& operator[](size_t i) const { return data_[i]; }
  T* begin() { return data_; }
  T* end() { return data_ + size_; }
  const T* begin() const { return data_; }
  const T* end() const { return data_ + size_; }
  std::span<T> span() { return {data_, size_}; }
  std::span<const T> span() const { return {data_, size_}; }
  operator std::span<T>() { return span(); }
  operator std::span<const T>() const { return span(); }
  ArrayStorage& storage() const { return *storage_; }

 private:
  ArrayStorage* storage_ = &ram_storage();
  T* data_ = nullptr;
  size_t size_ = 0;
};

/// A LargeArray holding a copy of `values`.
template <typename T>
LargeArray<std::remove_const_t<T>> large_array_of(std::span<T> values, ArrayStorage& storage = ram_storage()) {
  LargeArray<std::remove_const_t<T>> out(values.size(), storage);
  if (!values.empty()) std::memcpy(out.data(), values.data(), values.size_bytes());
  return out;
}

}  // namespace streamcvd
