#include "streamcvd/streaming/store/spill.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstring>

#include "streamcvd/core/mesh/anonymous_pages.h"
#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/output_file.h"

namespace streamcvd {

// ---- ScratchFile ------------------------------------------------------------------------------

ScratchFile::ScratchFile(const std::string& folder) : folder_(folder.empty() ? "." : folder) {
  ignore_file_size_signal();
  fd_ = ::open(folder_.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  if (fd_ < 0) {
    // No O_TMPFILE here: a named file, unlinked at once (the descriptor keeps it alive).
    for (int attempt = 0; attempt < 16 && fd_ < 0; ++attempt) {
      const std::string name = folder_ + "/.streamcvd-work." + std::to_string(::getpid()) + "." +
                               std::to_string(std::chrono::steady_clock::now().time_since_epoch().count()) + "." +
                               std::to_string(attempt);
      fd_ = ::open(name.c_str(), O_RDWR | O_CREAT | O_EXCL | O_CLOEXEC, 0600);
      if (fd_ >= 0) ::unlink(name.c_str());
      else if (errno != EEXIST) break;
    }
  }
  if (fd_ < 0) throw OutputError(error_at(folder_, "cannot create a work file: " + work_file_problem(errno)));
  // Reads go through a second open file without O_DIRECT (any alignment); /proc names the
  // anonymous file. dup() would share the O_DIRECT flag.
  read_fd_ = ::open(("/proc/self/fd/" + std::to_string(fd_)).c_str(), O_RDONLY | O_CLOEXEC);
  const bool own_read_file = read_fd_ >= 0;
  if (!own_read_file) read_fd_ = ::dup(fd_);
  // Direct writes where the file system allows them (and the reads have their own descriptor):
  // spilled blocks are read back once, much later, so the page cache has no use for them.
  const int flags = ::fcntl(fd_, F_GETFL);
  direct_ = own_read_file && flags >= 0 && ::fcntl(fd_, F_SETFL, flags | O_DIRECT) == 0;
}

ScratchFile::~ScratchFile() {
  if (read_fd_ >= 0) ::close(read_fd_);
  if (fd_ >= 0) ::close(fd_);
}

void ScratchFile::write_at(uint64_t offset, const void* data, size_t n) {
  const char* p = static_cast<const char*>(data);
  for (size_t done = 0; done < n;) {
    const ssize_t w = ::pwrite(fd_, p + done, n - done, off_t(offset + done));
    if (w < 0 && errno == EINTR) continue;
    if (w < 0 && errno == EINVAL && direct_ && done == 0) {  // refused after all: buffered from now on
      const int flags = ::fcntl(fd_, F_GETFL);
      if (flags >= 0 && ::fcntl(fd_, F_SETFL, flags & ~O_DIRECT) == 0) continue;
    }
    if (w <= 0)
      throw OutputError(error_at(folder_, "cannot write a work file (at byte " + std::to_string(offset + done) +
                                              "): " + (w < 0 ? work_file_problem(errno) : "no progress")));
    done += size_t(w);
  }
  uint64_t end = offset + n, seen = size_.load(std::memory_order_relaxed);
  while (end > seen && !size_.compare_exchange_weak(seen, end)) {
  }
}

void ScratchFile::append(const void* data, size_t n) {
  const char* p = static_cast<const char*>(data);
  size_t done = 0;
  while (done < n) {
    const ssize_t w = ::pwrite(fd_, p + done, n - done, off_t(size_.load() + done));
    if (w < 0 && errno == EINTR) continue;
    if (w < 0 && errno == EINVAL && direct_ && done == 0) {  // refused after all: buffered from now on
      const int flags = ::fcntl(fd_, F_GETFL);
      direct_ = false;
      if (flags >= 0 && ::fcntl(fd_, F_SETFL, flags & ~O_DIRECT) == 0) continue;
    }
    if (w <= 0)
      throw OutputError(error_at(folder_, "cannot write a work file (" + std::to_string(size_.load() + done) +
                                              " bytes written): " + (w < 0 ? work_file_problem(errno) : "no progress")));
    done += size_t(w);
  }
  size_ += n;
}

void ScratchFile::read(uint64_t offset, void* dst, size_t n) const {
  char* p = static_cast<char*>(dst);
  for (size_t done = 0; done < n;) {
    const ssize_t r = ::pread(read_fd_, p + done, n - done, off_t(offset + done));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0)
      throw InputError(error_at(folder_, "cannot read back a work file: " +
                                             std::string(r < 0 ? std::strerror(errno) : "short read")));
    done += size_t(r);
  }
  // Read once: do not let the page cache keep it (it would count against a memory cgroup).
  ::posix_fadvise(read_fd_, off_t(offset), off_t(n), POSIX_FADV_DONTNEED);
}

// ---- BlockPool --------------------------------------------------------------------------------

BlockPool::~BlockPool() {
  for (std::byte* b : free_) unmap_anonymous_pages(b, block_bytes_);
}

std::byte* BlockPool::get() {
  std::lock_guard lock(mutex_);
  ++in_use_;
  if (!free_.empty()) {
    std::byte* b = free_.back();
    free_.pop_back();
    return b;
  }
  void* m = map_anonymous_pages(block_bytes_);
  if (!m) {
    --in_use_;
    throw std::bad_alloc();
  }
  return static_cast<std::byte*>(m);
}

void BlockPool::put(std::byte* block) {
  // A few free blocks stay resident for reuse (giving their pages back would fault them in
  // again at every reuse); beyond kKeepFree they go back to the system.
  std::lock_guard lock(mutex_);
  --in_use_;
  if (free_.size() < kKeepFree) free_.push_back(block);
  else unmap_anonymous_pages(block, block_bytes_);
}

size_t BlockPool::in_use() const {
  std::lock_guard lock(mutex_);
  return in_use_;
}

// ---- SpillBuckets -----------------------------------------------------------------------------

size_t SpillBuckets::block_size_for(uint32_t buckets, uint64_t budget) {
  size_t block = kDefaultBlock;
  while (block > (size_t(64) << 10) && uint64_t(block) * 4 * std::max<uint32_t>(buckets, 1) > budget) block /= 2;
  return block;
}

SpillBuckets::SpillBuckets(std::string folder, uint32_t bucket_count, uint32_t record_bytes,
                           uint64_t resident_budget, size_t block_bytes)
    : folder_(std::move(folder)),
      record_bytes_(record_bytes),
      records_per_block_(uint32_t(block_bytes / record_bytes)),
      block_bytes_(block_bytes),
      resident_budget_(resident_budget),
      pool_(block_bytes),
      open_(bucket_count),
      blocks_(bucket_count),
      closed_records_(bucket_count, 0) {}

SpillBuckets::~SpillBuckets() {
  {
    std::lock_guard lock(mutex_);
    closing_ = true;
  }
  changed_.notify_all();
  for (std::thread& t : writers_) t.join();
  for (Open& o : open_)
    if (o.begin) pool_.put(o.begin);
  for (auto& list : blocks_)
    for (Block& b : list)
      if (b.data) pool_.put(b.data);
}

void SpillBuckets::append(uint32_t bucket, const void* records, size_t n) {
  const std::byte* p = static_cast<const std::byte*>(records);
  while (n > 0) {
    Open& o = open_[bucket];
    if (o.end - o.cursor < ptrdiff_t(record_bytes_)) next_block(bucket);
    const size_t room = size_t(o.end - o.cursor) / record_bytes_, take = std::min(room, n);
    std::memcpy(o.cursor, p, take * record_bytes_);
    o.cursor += take * record_bytes_;
    p += take * record_bytes_;
    n -= take;
  }
}

uint64_t SpillBuckets::records(uint32_t bucket) const {
  const Open& o = open_[bucket];
  return closed_records_[bucket] + uint64_t(o.cursor - o.begin) / record_bytes_;
}

uint64_t SpillBuckets::bytes_spilled() const {
  std::lock_guard lock(mutex_);
  return next_offset_;
}

void SpillBuckets::note_peak() {
  const uint64_t now = uint64_t(pool_.in_use()) * block_bytes_;
  peak_bytes_ = std::max(peak_bytes_, now);
}

void SpillBuckets::close_block(uint32_t bucket) {
  Open& o = open_[bucket];
  if (!o.begin) return;
  const uint32_t n = uint32_t((o.cursor - o.begin) / record_bytes_);
  std::lock_guard lock(mutex_);
  if (error_) std::rethrow_exception(error_);
  Block b{o.begin, 0, n};
  closed_records_[bucket] += n;
  if (resident_bytes_ + block_bytes_ <= resident_budget_) {
    resident_bytes_ += block_bytes_;
  } else {
    // Spill: the writer thread owns the block until written, then recycles it.
    if (writers_.empty()) {
      file_ = std::make_unique<ScratchFile>(folder_);
      for (int i = 0; i < kWriters; ++i) writers_.emplace_back([this] { writer_loop(); });
    }
    b.offset = next_offset_;
    next_offset_ += block_bytes_;
    queue_.push_back({o.begin, b.offset});
    pending_.insert(b.offset);
    b.data = nullptr;
    changed_.notify_all();
  }
  blocks_[bucket].push_back(b);
  o = Open{};
}

void SpillBuckets::next_block(uint32_t bucket) {
  close_block(bucket);
  // Bound the blocks in flight: the appending thread waits when the writer falls behind.
  {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return queue_.size() < 16 || error_; });
    if (error_) std::rethrow_exception(error_);
  }
  Open& o = open_[bucket];
  o.begin = o.cursor = pool_.get();
  o.end = o.begin + size_t(records_per_block_) * record_bytes_;
  note_peak();
}

void SpillBuckets::writer_loop() {
  for (;;) {
    Write w;
    {
      std::unique_lock lock(mutex_);
      changed_.wait(lock, [&] { return closing_ || !queue_.empty(); });
      if (queue_.empty()) return;
      w = queue_.front();
      queue_.pop_front();
    }
    try {
      file_->write_at(w.offset, w.data, block_bytes_);
    } catch (...) {
      std::lock_guard lock(mutex_);
      if (!error_) error_ = std::current_exception();
    }
    pool_.put(w.data);
    {
      std::lock_guard lock(mutex_);
      pending_.erase(w.offset);
    }
    changed_.notify_all();
  }
}

void SpillBuckets::take(uint32_t bucket, DefaultInitVector<std::byte>& out) {
  Open& o = open_[bucket];
  std::vector<Block> list;
  uint64_t last_offset_end = 0;
  {
    std::lock_guard lock(mutex_);
    list.swap(blocks_[bucket]);
    for (const Block& b : list)
      if (!b.data) last_offset_end = b.offset + block_bytes_;
  }
  uint64_t total = 0;
  for (const Block& b : list) total += b.records;
  const size_t open_bytes = size_t(o.cursor - o.begin);
  out.resize(size_t(total) * record_bytes_ + open_bytes);
  if (last_offset_end > 0) {  // wait until the writer has put this bucket's blocks on disk
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return written_below(last_offset_end) || error_; });
    if (error_) std::rethrow_exception(error_);
  }
  std::byte* at = out.data();
  uint64_t released = 0;
  for (const Block& b : list) {
    const size_t bytes = size_t(b.records) * record_bytes_;
    if (b.data) {
      std::memcpy(at, b.data, bytes);
      pool_.put(b.data);
      released += block_bytes_;
    } else {
      file_->read(b.offset, at, bytes);
    }
    at += bytes;
  }
  if (o.begin) {
    std::memcpy(at, o.begin, open_bytes);
    pool_.put(o.begin);
    o = Open{};
  }
  std::lock_guard lock(mutex_);
  resident_bytes_ -= released;
  closed_records_[bucket] = 0;
}

}  // namespace streamcvd

namespace streamcvd {

void SpillBuckets::drain(uint32_t bucket, const std::function<void(std::span<const std::byte>)>& visit) {
  Open& o = open_[bucket];
  std::vector<Block> list;
  {
    std::lock_guard lock(mutex_);
    list.swap(blocks_[bucket]);
  }
  DefaultInitVector<std::byte> staging;
  for (const Block& b : list) {
    const size_t bytes = size_t(b.records) * record_bytes_;
    if (b.data) {
      visit({b.data, bytes});
      pool_.put(b.data);
      std::lock_guard lock(mutex_);
      resident_bytes_ -= block_bytes_;
      continue;
    }
    {
      std::unique_lock lock(mutex_);
      changed_.wait(lock, [&] { return written_below(b.offset + block_bytes_) || error_; });
      if (error_) std::rethrow_exception(error_);
    }
    staging.resize(bytes);
    file_->read(b.offset, staging.data(), bytes);
    visit({staging.data(), bytes});
  }
  if (o.begin) {
    visit({o.begin, size_t(o.cursor - o.begin)});
    pool_.put(o.begin);
    o = Open{};
  }
  std::lock_guard lock(mutex_);
  closed_records_[bucket] = 0;
}

}  // namespace streamcvd
