// The chunk scheduler of an out-of-core job (DESIGN.md §3, §4): the RangeResidency hooks the
// stages call around each vertex range they visit (core/mesh/mesh_view.h), turned into page advice on
// the store's mapped arrays and the job's per-vertex work files. Entering a range validates its
// chunks on first use (MeshStore::validate_chunk) and reads their pages ahead (MADV_WILLNEED);
// leaving it queues them; once the queued chunks exceed the resident budget, the least recently
// left by an earlier stage are released (MADV_COLD: the kernel reclaims them first, their
// contents stay valid); a stage's own chunks are not, its rounds come back to them. Only
// the arrays a visit says it reads are read ahead (reading a chunk's every array for a stage
// that needs two of them cost the 105M-face run 70 GB of reads inside 2 GiB). Inside a
// scattered-reads bracket (the clustering loops, the repair rounds, the projection walks) the
// mapped files are advised MADV_RANDOM, so a fault outside a visit reads its page and not the
// device's read-ahead window around it, and dense visits are read ahead every time. The order
// of the work never depends on it; only residency does. Counts visits per stage.
#pragma once

#include <cstdint>
#include <deque>
#include <mutex>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/mesh_view.h"
#include "streamcvd/streaming/store/store.h"
#include "streamcvd/streaming/schedule/work_space.h"

namespace streamcvd {

/// Visits of one stage (a stage is the name it passes to RangeVisit).
struct StageVisits {
  std::string stage;
  uint64_t visits = 0;           ///< ranges entered
  uint64_t vertices = 0;         ///< vertices of those ranges (a vertex visited twice counts twice)
  uint64_t chunks_fetched = 0;   ///< chunks read ahead because they were not resident
  uint64_t chunks_refetched = 0; ///< resident chunks read ahead again inside scattered_reads
  uint64_t bytes_read_ahead = 0; ///< bytes of those chunks' arrays advised MADV_WILLNEED
};

struct SchedulerReport {
  uint64_t resident_budget_bytes = 0;
  uint64_t chunks = 0;
  uint64_t chunks_released = 0;  ///< releases of chunks past the budget
  std::vector<StageVisits> stages;  ///< in the order the stages first entered a range
};

class ChunkScheduler final : public RangeResidency {
 public:
  /// Schedules the chunks of `store` (which must outlive it) and the per-vertex arrays of
  /// `work` (may be null; arrays of V·s bytes in work files), holding about `resident_budget`
  /// bytes of left chunks before releasing. O(chunks) memory.
  ChunkScheduler(const MeshStore& store, const WorkSpace* work, uint64_t resident_budget);

  void enter(const char* stage, VertexRange range, uint8_t arrays) override;
  void leave(const char* stage, VertexRange range) override;
  /// Inside the bracket the store's arrays and the work files are advised MADV_RANDOM (a fault
  /// reads its page only) and every visit that reads arrays reads its chunks ahead again.
  void scattered_reads(bool begin) override;

  SchedulerReport report() const;

 private:
  std::pair<uint32_t, uint32_t> chunks_of(VertexRange range) const;
  uint64_t chunk_bytes(uint32_t c, uint8_t arrays) const;
  void advise_work_arrays(uint32_t c, bool will_need) const;
  StageVisits& stage_of(const char* stage);

  const MeshStore& store_;
  const MeshView view_;
  const WorkSpace* work_;
  const uint64_t budget_;
  mutable std::mutex mutex_;
  std::vector<uint8_t> resident_;       // per chunk: MeshArray bits read ahead (kWorkArrays: its
                                        // work-array slices) and not released since
  std::vector<uint32_t> busy_;          // per chunk: ranges entered and not yet left
  std::deque<std::pair<uint32_t, uint64_t>> left_;  // (chunk, stamp) as left, least recent first
  std::vector<uint64_t> left_stamp_;    // per chunk: stamp of its valid entry in left_, 0 = none
  std::vector<uint64_t> queued_size_;   // per chunk: bytes it counts in queued_bytes_
  std::vector<const char*> left_stage_;  // per chunk: the stage that left it last
  uint64_t stamp_ = 0;
  uint64_t queued_bytes_ = 0;
  uint64_t released_ = 0;
  uint32_t scattered_depth_ = 0;        // open scattered_reads(true) brackets
  std::vector<std::pair<const char*, StageVisits>> stages_;
};

}  // namespace streamcvd
