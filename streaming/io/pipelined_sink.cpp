#include "streamcvd/streaming/io/pipelined_sink.h"

namespace streamcvd {

PipelinedSink::PipelinedSink(MeshSink& target, uint32_t depth)
    : target_(target), depth_(std::max<uint32_t>(depth, 1)), ring_(depth_ + 1) {
  for (Block& b : ring_) free_.push_back(&b);
  thread_ = std::thread([this] { run(); });
}

PipelinedSink::~PipelinedSink() {
  {
    std::lock_guard lock(mutex_);
    closing_ = abandon_ = true;  // the block in the consumer's hands finishes, the rest is dropped
  }
  changed_.notify_all();
  if (thread_.joinable()) thread_.join();
}

void PipelinedSink::rethrow() {
  if (error_) std::rethrow_exception(error_);
}

void PipelinedSink::begin(const MeshHeaderInfo& header) { target_.begin(header); }

PipelinedSink::Block& PipelinedSink::next_free() {
  std::unique_lock lock(mutex_);
  changed_.wait(lock, [&] { return !free_.empty() || error_; });
  rethrow();
  Block* b = free_.back();
  free_.pop_back();
  return *b;
}

void PipelinedSink::push(Block& b) {
  {
    std::lock_guard lock(mutex_);
    queue_.push_back(&b);
  }
  changed_.notify_all();
}

void PipelinedSink::vertices(std::span<const float> xyz, std::span<const float> attributes) {
  Block& b = next_free();
  b.is_vertices = true;
  b.xyz.assign(xyz.begin(), xyz.end());
  b.attributes.assign(attributes.begin(), attributes.end());
  push(b);
}

void PipelinedSink::triangles(std::span<const uint32_t> corners) {
  Block& b = next_free();
  b.is_vertices = false;
  b.corners.assign(corners.begin(), corners.end());
  push(b);
}

void PipelinedSink::run() {
  for (;;) {
    Block* b = nullptr;
    {
      std::unique_lock lock(mutex_);
      changed_.wait(lock, [&] { return closing_ || !queue_.empty(); });
      if (queue_.empty() || abandon_) return;
      b = queue_.front();
    }
    try {
      if (!error_) {
        if (b->is_vertices) target_.vertices(b->xyz, b->attributes);
        else target_.triangles(b->corners);
      }
    } catch (...) {
      std::lock_guard lock(mutex_);
      error_ = std::current_exception();
    }
    {
      std::lock_guard lock(mutex_);
      queue_.pop_front();
      free_.push_back(b);
    }
    changed_.notify_all();
  }
}

void PipelinedSink::end(const ReadStats& stats) {
  {
    std::unique_lock lock(mutex_);
    changed_.wait(lock, [&] { return queue_.empty(); });
    closing_ = true;
  }
  changed_.notify_all();
  thread_.join();
  rethrow();
  target_.end(stats);
}

}  // namespace streamcvd
