#include "streamcvd/streaming/store/store_writer.h"

#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/output_file.h"
#include "streamcvd/streaming/store/spill.h"

namespace streamcvd {

StoreDirectoryWriter::StoreDirectoryWriter(std::string directory, bool background)
    : directory_(std::move(directory)), created_(directory_), background_(background) {
  // Step 1. The removal is durable before any array is replaced, so that after a crash an old
  // header never describes new arrays.
  const std::string header_path = directory_ + "/header.bin";
  if (::unlink(header_path.c_str()) != 0 && errno != ENOENT)
    throw OutputError(error_at(header_path, std::string("cannot remove old header: ") + std::strerror(errno)));
  sync_directory(directory_);
  if (background_) thread_ = std::thread([this] { worker(); });
}

StoreDirectoryWriter::~StoreDirectoryWriter() {
  if (thread_.joinable()) {
    {
      std::lock_guard lock(mutex_);
      closing_ = true;
      queue_.clear();
    }
    ready_.notify_all();
    thread_.join();
  }
  // done_ goes out of scope: uncommitted temporaries are removed.
}

void StoreDirectoryWriter::run(const Job& job) {
  auto out = std::make_unique<AtomicOutputFile>(directory_ + "/" + job.name);
  out->write_direct(job.bytes.data(), job.bytes.size());
  out->sync();
  std::lock_guard lock(mutex_);
  done_.push_back(std::move(out));
}

void StoreDirectoryWriter::worker() {
  for (;;) {
    Job job;
    {
      std::unique_lock lock(mutex_);
      ready_.wait(lock, [&] { return closing_ || !queue_.empty(); });
      if (queue_.empty()) return;  // closing and drained
      job = std::move(queue_.front());
      queue_.pop_front();
      if (error_) continue;  // a file failed: the store will not be committed
    }
    try {
      run(job);
    } catch (...) {
      std::lock_guard lock(mutex_);
      if (!error_) error_ = std::current_exception();
    }
  }
}

void StoreDirectoryWriter::add(const std::string& name, std::span<const std::byte> bytes) {
  Job job{name, bytes};
  if (!background_) {
    pending_.push_back(std::move(job));
    return;
  }
  {
    std::lock_guard lock(mutex_);
    queue_.push_back(std::move(job));
  }
  ready_.notify_one();
}

StoreArrayStream& StoreDirectoryWriter::stream(const std::string& name, uint32_t blocks_in_flight) {
  streams_.push_back(std::make_unique<StoreArrayStream>(directory_ + "/" + name, false, blocks_in_flight));
  return *streams_.back();
}

void StoreDirectoryWriter::finish(const std::string& name, std::span<const std::byte> header) {
  if (background_) {
    {
      std::lock_guard lock(mutex_);
      closing_ = true;
    }
    ready_.notify_all();
    thread_.join();
    if (error_) std::rethrow_exception(error_);
  } else {
    // Two files at a time (one per core): the bounce copies overlap the other file's I/O.
    tbb::parallel_for(size_t(0), pending_.size(), [&](size_t i) { run(pending_[i]); });
  }
  for (auto& s : streams_) s->finish();
  for (auto& out : done_) out->commit(/*sync_folder=*/false);  // step 3
  for (auto& s : streams_) s->file().commit(/*sync_folder=*/false);
  sync_directory(directory_);
  AtomicOutputFile out(directory_ + "/" + name);  // step 4
  out.write(header.data(), header.size());
  out.commit();
  created_.keep();
}

}  // namespace streamcvd

namespace streamcvd {

void MemoryArrayOutput::append(const void* data, size_t n) {
  if (n == 0) return;  // an empty span may carry a null pointer, which memcpy must not see
  const size_t old = data_.size();
  if (old + n > data_.capacity()) data_.reserve(std::max(old + n, 2 * data_.capacity()));
  data_.resize(old + n);  // no zero fill (DefaultInitVector)
  std::memcpy(data_.data() + old, data, n);
}

namespace {
constexpr size_t kStreamBlock = StoreArrayStream::kBlockBytes;  // large enough for full-speed direct I/O

// A scratch array is a work file: when the folder is full, its error says what to do, as the
// other work files' do (work_file_problem). The file's error carries strerror() only.
std::string as_work_file_error(const std::string& message) {
  for (int err : {ENOSPC, EDQUOT, EFBIG}) {
    const std::string reason = std::strerror(err);
    const size_t at = message.find(reason);
    if (at != std::string::npos) return message.substr(0, at) + work_file_problem(err) + message.substr(at + reason.size());
  }
  return message;
}
}  // namespace

StoreArrayStream::StoreArrayStream(const std::string& path, bool scratch, uint32_t blocks_in_flight)
    : file_(std::make_unique<AtomicOutputFile>(path)),
      pool_(std::make_unique<BlockPool>(kStreamBlock)),
      scratch_(scratch),
      in_flight_(std::max<uint32_t>(blocks_in_flight, 1)) {
  thread_ = std::thread([this] { run(); });
}

StoreArrayStream::~StoreArrayStream() {
  {
    std::lock_guard lock(mutex_);
    closing_ = true;
  }
  changed_.notify_all();
  if (thread_.joinable()) thread_.join();
  if (pool_) {
    for (auto& [block, n] : queue_) pool_->put(block);
    if (block_) pool_->put(block_);
  }
}

void StoreArrayStream::run() {
  for (;;) {
    std::pair<std::byte*, size_t> job;
    {
      std::unique_lock lock(mutex_);
      changed_.wait(lock, [&] { return closing_ || !queue_.empty(); });
      if (queue_.empty()) return;
      job = queue_.front();
    }
    try {
      if (!error_) file_->write_direct(job.first, job.second);
    } catch (const OutputError& e) {
      std::lock_guard lock(mutex_);
      error_ = scratch_ ? std::make_exception_ptr(OutputError(as_work_file_error(e.what()))) : std::current_exception();
    } catch (...) {
      std::lock_guard lock(mutex_);
      error_ = std::current_exception();
    }
    pool_->put(job.first);
    {
      std::lock_guard lock(mutex_);
      queue_.pop_front();
    }
    changed_.notify_all();
  }
}

void StoreArrayStream::submit() {
  std::unique_lock lock(mutex_);
  if (error_) std::rethrow_exception(error_);
  queue_.emplace_back(block_, used_);
  block_ = nullptr;
  used_ = 0;
  changed_.notify_all();
  changed_.wait(lock, [&] { return queue_.size() < in_flight_ || error_; });
  if (error_) std::rethrow_exception(error_);
}

void StoreArrayStream::append(const void* data, size_t n) {
  const std::byte* p = static_cast<const std::byte*>(data);
  bytes_ += n;
  while (n > 0) {
    if (!block_) block_ = pool_->get();
    const size_t take = std::min(n, kStreamBlock - used_);
    std::memcpy(block_ + used_, p, take);
    used_ += take;
    p += take;
    n -= take;
    if (used_ == kStreamBlock) submit();
  }
}

void StoreArrayStream::read_back(uint64_t offset, void* dst, size_t n) {
  finish();
  file_->read_back(offset, dst, n);
}

void StoreArrayStream::finish() {
  if (finished_) return;
  finished_ = true;
  if (block_ && used_ > 0) submit();  // the tail: write_direct pads and truncates it
  {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return queue_.empty(); });
    closing_ = true;
  }
  changed_.notify_all();
  thread_.join();
  if (error_) std::rethrow_exception(error_);
  pool_.reset();  // the stream is complete: its blocks go back to the system
  if (scratch_) file_->flush();  // mapped next: every byte must be in the file, durable or not
  else file_->sync();
}

}  // namespace streamcvd
