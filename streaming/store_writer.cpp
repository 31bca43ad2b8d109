#include "streaming/store_writer.h"

#include <tbb/parallel_for.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>

#include "core/errors.h"
#include "streaming/output_file.h"

namespace streamcvd {

StoreDirectoryWriter::StoreDirectoryWriter(std::string directory, bool background)
    : directory_(std::move(directory)), background_(background) {
  std::error_code ec;
  std::filesystem::create_directories(directory_, ec);
  if (ec || !std::filesystem::is_directory(directory_))
    throw OutputError(
        error_at(directory_, "cannot create store directory" + (ec ? ": " + ec.message() : std::string())));
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
  for (auto& out : done_) out->commit(/*sync_folder=*/false);  // step 3
  sync_directory(directory_);
  AtomicOutputFile out(directory_ + "/" + name);  // step 4
  out.write(header.data(), header.size());
  out.commit();
}

}  // namespace streamcvd
