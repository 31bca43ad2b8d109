// A MeshSink that runs another sink on a thread of its own: the reader parses the next block
// while the previous one is consumed (for the store builder: remapped and bucketed), so reading
// and building use two cores. Blocks are copied into a small ring of buffers; the consumer sees
// them in order, exactly as if it were called directly.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

#include "streamcvd/streaming/io/mesh_reader.h"

namespace streamcvd {

class PipelinedSink final : public MeshSink {
 public:
  /// Forwards to `target` on a consumer thread, with at most `depth` blocks waiting.
  explicit PipelinedSink(MeshSink& target, uint32_t depth = 4);
  /// Stops the consumer (what is queued is dropped). Never throws.
  ~PipelinedSink() override;

  void begin(const MeshHeaderInfo& header) override;
  void vertices(std::span<const float> xyz, std::span<const float> attributes) override;
  void triangles(std::span<const uint32_t> corners) override;
  /// Waits for every queued block, then runs target.end() on the calling thread. Rethrows the
  /// consumer's first exception (also from the calls above, at the next call after it failed).
  void end(const ReadStats& stats) override;

 private:
  struct Block {
    bool is_vertices = false;
    std::vector<float> xyz, attributes;
    std::vector<uint32_t> corners;
  };
  Block& next_free();  // waits for room in the ring
  void push(Block& b);
  void run();
  void rethrow();

  MeshSink& target_;
  uint32_t depth_;
  std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Block*> queue_;
  std::vector<Block> ring_;
  std::vector<Block*> free_;
  bool closing_ = false;
  bool abandon_ = false;  // closing without consuming what is queued
  std::exception_ptr error_;
  std::thread thread_;
};

}  // namespace streamcvd
