// Shared state of the store builder's passes (streaming/store/store_build.h), internal to
// store_build.cpp (sink, plan, chunks), store_build_order.cpp (pass 2) and
// store_build_ranges.cpp (passes 3 and 4).
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/default_init_vector.h"
#include "streamcvd/streaming/store/hilbert.h"
#include "streamcvd/streaming/store/spill.h"
#include "streamcvd/streaming/store/store_build.h"
#include "streamcvd/core/mesh/timer.h"

namespace streamcvd {

namespace store_build {

/// Bytes the build itself needs besides what it plans (buffers of the reader and the output
/// streams, thread stacks, the program): subtracted from the limit before planning.
inline constexpr uint64_t kFixedOverhead = uint64_t(24) << 20;
/// Smallest working set a pass is given (a bucket being sorted, a vertex range).
inline constexpr uint64_t kMinWork = uint64_t(8) << 20;
/// Working bytes per vertex of a pass-4 range: owned and foreign faces, the local CSR and flags
/// (two sets: one being written while the next is built), the next range's input read ahead.
inline constexpr uint64_t kRangeBytesPerVertex = 320;

/// Positions of every stride-th input vertex, at most kCapacity of them: when full, every other
/// sample is dropped and the stride doubles. Deterministic; the key ranges of pass 2 come from
/// the sample's keys (only the bucket balance depends on it, never the result).
struct PositionSample {
  static constexpr size_t kCapacity = size_t(1) << 17;
  uint64_t stride = 1;
  std::vector<float> xyz;
  void add(uint64_t first_id, std::span<const float> block);
};

/// A vertex record of pass 2: Hilbert key, input id, position (attributes follow in the record).
/// The key travels with the record: computing it costs more than carrying it through the disk.
struct VertexRecord {
  uint64_t key;
  uint32_t id;
  float xyz[3];
};
static_assert(sizeof(VertexRecord) == 24);

/// A face sent to a later vertex range that holds one of its corners (pass 4).
struct ForeignFace {
  uint32_t face;
  uint32_t corner[3];
};
static_assert(sizeof(ForeignFace) == 16);

/// Chunk boundaries as owned-face counts stream by, vertex after vertex (the rule of the
/// chunk table: C = round(F / target) chunks, cut at the vertex whose first owned face is nearest
/// to k·F/C; a vertex's owned faces are never split).
class ChunkCutter {
 public:
  ChunkCutter(uint64_t vertices, uint64_t faces, uint64_t target);
  /// Vertex e (in order, from 0 to V) whose first owned face is `first_face` (faces owned by
  /// vertices < e) and that of e − 1; appends to `cuts` the chunk boundaries this decides
  /// (each ≤ e, ascending).
  void visit(uint64_t e, uint64_t first_face, uint64_t previous_first_face, std::vector<uint64_t>& cuts);

 private:
  uint64_t vertices_, faces_, chunks_;
  uint64_t k_ = 1, begin_ = 0;
};

}  // namespace store_build

struct StoreBuilder::State {
  State(StoreOutputs& o, const StoreBuildOptions& opt, std::function<void(const BuildProgress&)> p);

  // The passes (one function each).
  void plan_order(uint64_t n_in, const float* box_lo, const float* box_hi, std::span<const float> sample_xyz,
                  uint64_t sample_stride);            // pass 2: grid, key buckets
  void distribute(std::span<const std::byte> vertex_records, uint64_t first_id);  // pass 2
  void distribute_batched(std::span<const std::byte> vertex_records, bool flush);
  uint64_t vertex_key(uint64_t id, const float* p) const;
  void order_vertices();                             // pass 2
  void begin_faces();                                // pass 3
  void add_faces(std::span<const uint32_t> corners);  // pass 3, one block in file order (batched)
  void flush_faces();                                // pass 3: the batch so far
  void remap_faces(std::span<const uint32_t> corners);  // pass 3: remap and bucket a batch
  void finish_faces();                               // pass 3
  void build_ranges();                               // pass 4
  void finish_result();

  void report(const char* stage, uint64_t done, uint64_t total, const char* unit) const {
    if (progress) progress({stage, done, total, unit});
    if (trace) note_memory(stage);
  }
  /// STREAMCVD_BUILD_TRACE=1: per-stage peaks of the resident anonymous memory on stderr.
  bool trace = false;
  void note_memory(const char* stage) const;
  /// Bytes still free for a new structure when `held` bytes are in use (huge when unlimited).
  uint64_t free_after(uint64_t held) const { return held >= usable ? 0 : usable - held; }
  /// Throws InputError when `need` bytes of working memory do not fit under the limit.
  void require(uint64_t need, const char* what) const;

  StoreOutputs& outputs;
  StoreBuildOptions options;
  std::function<void(const BuildProgress&)> progress;
  uint64_t usable = ~uint64_t(0);  ///< limit − fixed overhead: what the passes plan with
  std::string work_dir;
  MeshHeaderInfo header;
  uint32_t attribute_count = 0;
  bool merge_corners = false;      ///< STL: identical corners become one vertex (pass 2)
  std::chrono::steady_clock::time_point started;

  // Pass 1: vertices in file order, bounding box, key sample; faces spilled raw when they come
  // before the vertex order is known.
  std::unique_ptr<SpillBuckets> vertex_records;  ///< xyz + attributes per vertex
  uint64_t input_vertices = 0;
  float lo[3], hi[3];
  store_build::PositionSample sample;
  std::vector<float> record_scratch;  ///< interleaved xyz + attributes of one block
  std::unique_ptr<SpillBuckets> raw_faces;
  uint64_t input_faces = 0;
  ReadStats read;

  // Pass 2: the vertex order. With bounds in the header the vertices are distributed to the key
  // buckets as they are read; otherwise from the pass-1 spill once all are known.
  bool ordered = false;
  HilbertGrid grid;
  std::unique_ptr<SpillBuckets> key_records;
  std::vector<uint64_t> key_splits;
  uint32_t order_record_bytes = 0;
  size_t distribute_batch_bytes = 0;
  uint64_t distributed = 0;  ///< vertices handed to distribute()
  double distribute_seconds = 0;
  DefaultInitVector<std::byte> order_batch, order_staging;
  DefaultInitVector<uint64_t> order_scratch_keys;
  DefaultInitVector<uint32_t> order_scratch_buckets, order_scratch_start;
  DefaultInitVector<uint32_t> new_of_old;  ///< input vertex → store vertex
  uint32_t vertex_count = 0;               ///< store vertices

  // Bounding box of every kBoxBlock store vertices (pass 2), from which pass 4 gets the chunks'
  // boxes without reading the positions back (only the few vertices of partial blocks).
  static constexpr uint32_t kBoxBlock = 4096;
  std::vector<float> block_boxes;          ///< 6 per block: lo xyz, hi xyz (empty: ±inf)

  // Pass 3: faces by owner range.
  uint32_t range_width = 1, range_count = 0;
  std::unique_ptr<SpillBuckets> owned_faces;
  /// Faces per remap_faces() call (3 MiB of corners): two counting-sort parts and 64 remap tasks.
  static constexpr size_t kFaceBatch = size_t(1) << 18;
  DefaultInitVector<uint32_t> face_batch;  ///< corners of the reader's blocks not yet remapped
  DefaultInitVector<uint32_t> remapped, face_range, face_staging, face_range_start;  ///< scratch of remap_faces
  uint64_t face_count = 0;

  StoreBuildResult result;
};

}  // namespace streamcvd
