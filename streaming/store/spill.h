// Scratch storage of the external-memory passes (DESIGN.md §2, §3): anonymous scratch files and
// buckets of fixed-size records that stay in RAM up to a budget and spill to disk beyond it.
// With a budget that holds everything nothing touches the disk, so an in-RAM build and an
// out-of-core build run the same code; the budget changes where bytes live, never their order.
#pragma once

#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <deque>
#include <atomic>
#include <exception>
#include <set>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "streamcvd/core/mesh/default_init_vector.h"

namespace streamcvd {

/// An anonymous file in `folder` (O_TMPFILE, or created and unlinked at once): it has no name,
/// so nothing is left on disk whatever ends the process (exception, signal, SIGKILL, crash).
/// Appends of whole 4 KiB-aligned blocks bypass the page cache (O_DIRECT where the file system
/// allows it); reads are positional and drop what they read from the page cache.
class ScratchFile {
 public:
  static constexpr size_t kAlign = 4096;
  /// Throws OutputError "<folder>: cannot create a work file: <reason>".
  explicit ScratchFile(const std::string& folder);
  ~ScratchFile();
  ScratchFile(const ScratchFile&) = delete;
  ScratchFile& operator=(const ScratchFile&) = delete;

  /// Appends n bytes (n a multiple of kAlign, data kAlign-aligned). One writing thread at a
  /// time. Throws OutputError naming the folder on a write error (disk full, file size limit).
  void append(const void* data, size_t n);
  /// Writes n bytes at `offset` (aligned as for append()). Thread-safe for distinct ranges.
  void write_at(uint64_t offset, const void* data, size_t n);
  /// Copies n bytes at `offset` (< size()) into dst. Thread-safe (pread). Throws InputError on
  /// a read error.
  void read(uint64_t offset, void* dst, size_t n) const;
  uint64_t size() const { return size_.load(); }
  const std::string& folder() const { return folder_; }

 private:
  std::string folder_;
  int fd_ = -1;       // appends (O_DIRECT when possible)
  int read_fd_ = -1;  // positional reads, buffered
  bool direct_ = false;
  std::atomic<uint64_t> size_{0};
};

/// Page-aligned memory blocks of one size, mapped directly (never from malloc's heap); up to
/// kKeepFree returned blocks are kept for reuse, the others unmapped. Thread-safe.
class BlockPool {
 public:
  explicit BlockPool(size_t block_bytes) : block_bytes_(block_bytes) {}
  ~BlockPool();
  BlockPool(const BlockPool&) = delete;
  BlockPool& operator=(const BlockPool&) = delete;
  std::byte* get();
  void put(std::byte* block);
  size_t block_bytes() const { return block_bytes_; }
  /// Blocks handed out and not returned.
  size_t in_use() const;

 private:
  size_t block_bytes_;
  static constexpr size_t kKeepFree = 16;
  mutable std::mutex mutex_;
  std::vector<std::byte*> free_;
  size_t in_use_ = 0;
};

/// `bucket_count` buckets of `record_bytes`-byte records. Appends fill one open block per
/// bucket; a full block stays resident while all resident blocks fit in `resident_budget` bytes,
/// else one background thread writes it to a scratch file in `folder` and recycles it. A bucket
/// is read back whole, in append order (take()). Memory: at most resident_budget plus one open
/// block per bucket plus a few blocks in flight. Appends from one thread; take() may run on
/// another thread than the appends to other buckets.
class SpillBuckets {
 public:
  static constexpr size_t kDefaultBlock = kLargeBlockBytes;
  /// block_bytes: a multiple of 4 KiB holding at least one record (smaller blocks for many
  /// buckets under a small budget).
  SpillBuckets(std::string folder, uint32_t bucket_count, uint32_t record_bytes, uint64_t resident_budget,
               size_t block_bytes = kDefaultBlock);
  /// A block size for `buckets` buckets under `budget` bytes: a quarter of the budget's share
  /// per bucket, a power of two within [64 KiB, 1 MiB].
  static size_t block_size_for(uint32_t buckets, uint64_t budget);
  ~SpillBuckets();
  SpillBuckets(const SpillBuckets&) = delete;
  SpillBuckets& operator=(const SpillBuckets&) = delete;

  /// Appends one record (record_bytes bytes) to `bucket`.
  void append(uint32_t bucket, const void* record) {
    Open& o = open_[bucket];
    if (o.end - o.cursor < ptrdiff_t(record_bytes_)) [[unlikely]] next_block(bucket);
    std::memcpy(o.cursor, record, record_bytes_);
    o.cursor += record_bytes_;
  }
  /// Appends n consecutive records.
  void append(uint32_t bucket, const void* records, size_t n);

  /// Records appended to `bucket` so far.
  uint64_t records(uint32_t bucket) const;
  /// All records of `bucket`, in append order, into `out` (resized to records × record_bytes
  /// bytes); the bucket is then empty and its memory released. Waits for the bucket's blocks
  /// in flight. Rethrows a write error of the background thread (OutputError).
  void take(uint32_t bucket, DefaultInitVector<std::byte>& out);
  /// Visits the records of `bucket` in append order, one block at a time (visit(bytes) with a
  /// whole number of records), releasing each block after its visit: a bucket larger than RAM
  /// streams through. The bucket is then empty.
  void drain(uint32_t bucket, const std::function<void(std::span<const std::byte>)>& visit);

  uint32_t bucket_count() const { return uint32_t(open_.size()); }
  uint32_t record_bytes() const { return record_bytes_; }
  /// Bytes written to the scratch file so far (0 when everything stayed resident).
  uint64_t bytes_spilled() const;
  /// Largest resident + open + in-flight block bytes seen.
  uint64_t peak_bytes() const { return peak_bytes_; }

 private:
  struct Block {
    std::byte* data = nullptr;  // resident (or in flight) block, else nullptr
    uint64_t offset = 0;        // in the scratch file when spilled
    uint32_t records = 0;
  };
  struct Open {
    std::byte* begin = nullptr;
    std::byte* cursor = nullptr;
    std::byte* end = nullptr;
  };
  struct Write {
    std::byte* data;
    uint64_t offset;
  };
  void next_block(uint32_t bucket);  // closes the open block of `bucket`, opens a new one
  void close_block(uint32_t bucket);
  void writer_loop();
  void note_peak();

  std::string folder_;
  uint32_t record_bytes_;
  uint32_t records_per_block_;
  size_t block_bytes_;
  uint64_t resident_budget_;
  BlockPool pool_;
  std::vector<Open> open_;
  std::vector<std::vector<Block>> blocks_;  // closed blocks per bucket, in append order
  std::vector<uint64_t> closed_records_;
  uint64_t resident_bytes_ = 0;             // closed blocks kept resident
  uint64_t peak_bytes_ = 0;
  // Scratch file and its writer thread (created at the first spill).
  std::unique_ptr<ScratchFile> file_;
  uint64_t next_offset_ = 0;                // file offset of the next spilled block
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Write> queue_;
  std::set<uint64_t> pending_;              // offsets of blocks queued or being written
  bool written_below(uint64_t end) const { return pending_.empty() || *pending_.begin() >= end; }
  bool closing_ = false;
  std::exception_ptr error_;
  static constexpr int kWriters = 2;       // two requests in flight: the disk is faster at QD2
  std::vector<std::thread> writers_;
};

}  // namespace streamcvd
