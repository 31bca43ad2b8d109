#include "streamcvd/streaming/schedule/chunk_scheduler.h"

#include <sys/mman.h>

#include <algorithm>
#include <cstring>

#include "streamcvd/streaming/store/page_advice.h"

namespace streamcvd {

namespace {

constexpr uint8_t kWorkArrays = 0x80;  // resident_ bit: the chunk's per-vertex work-array slices

}  // namespace

ChunkScheduler::ChunkScheduler(const MeshStore& store, const WorkSpace* work, uint64_t resident_budget)
    : store_(store), view_(store.view()), work_(work), budget_(resident_budget),
      resident_(view_.chunks.size(), 0), busy_(view_.chunks.size(), 0), left_stamp_(view_.chunks.size(), 0),
      queued_size_(view_.chunks.size(), 0), left_stage_(view_.chunks.size(), "") {}

std::pair<uint32_t, uint32_t> ChunkScheduler::chunks_of(VertexRange range) const {
  const auto& chunks = view_.chunks;
  auto starts_after = [](uint32_t v, const Chunk& c) { return v < c.vertex_begin; };
  const uint32_t first =
      uint32_t(std::upper_bound(chunks.begin(), chunks.end(), range.begin, starts_after) - chunks.begin()) - 1;
  uint32_t last = first;
  while (last < chunks.size() && chunks[last].vertex_begin < range.end) ++last;
  return {first, std::max(last, first + 1)};
}

uint64_t ChunkScheduler::chunk_bytes(uint32_t c, uint8_t arrays) const {
  const Chunk& k = view_.chunks[c];
  const uint64_t n = k.vertex_end - k.vertex_begin;
  uint64_t bytes = 0;
  if (arrays & kReadsPositions) bytes += 12 * n;
  if (arrays & kReadsTriangles) bytes += 12 * (k.face_end - k.face_begin);
  if (arrays & kReadsNeighbours)
    bytes += 8 * n + 4 * (view_.vertex_vertex_offsets[k.vertex_end] - view_.vertex_vertex_offsets[k.vertex_begin]);
  if (arrays & kReadsVertexFaces)
    bytes += 8 * n + 4 * (view_.vertex_face_offsets[k.vertex_end] - view_.vertex_face_offsets[k.vertex_begin]);
  if (arrays & kReadsFlags) bytes += n;
  if (work_ && (arrays & kWorkArrays))
    for (const auto& [data, size] : work_->file_regions(view_.vertex_count())) bytes += n * (size / view_.vertex_count());
  return bytes;
}

void ChunkScheduler::advise_work_arrays(uint32_t c, bool will_need) const {
  if (!work_) return;
  const Chunk& k = view_.chunks[c];
  for (const auto& [data, size] : work_->file_regions(view_.vertex_count())) {
    const size_t stride = size / view_.vertex_count();
    // Releasing leaves the edge pages a neighbouring chunk's slice shares.
    advise_pages(static_cast<const std::byte*>(data) + stride * k.vertex_begin, stride * (k.vertex_end - k.vertex_begin),
                 will_need ? MADV_WILLNEED : MADV_COLD, will_need ? PageSpan::Covering : PageSpan::Inside);
  }
}

StageVisits& ChunkScheduler::stage_of(const char* stage) {
  for (auto& [name, visits] : stages_)
    if (name == stage || std::strcmp(name, stage) == 0) return visits;
  stages_.push_back({stage, StageVisits{stage}});
  return stages_.back().second;
}

void ChunkScheduler::enter(const char* stage, VertexRange range, uint8_t arrays) {
  if (range.end <= range.begin || view_.chunks.empty()) return;
  const auto [first, last] = chunks_of(range);
  std::vector<std::pair<uint32_t, uint8_t>> fetch;  // (chunk, arrays to read ahead)
  {
    std::lock_guard lock(mutex_);
    StageVisits& visits = stage_of(stage);
    ++visits.visits;
    visits.vertices += range.size();
    for (uint32_t c = first; c < last; ++c) {
      if (busy_[c]++ == 0 && left_stamp_[c] != 0) {  // queued: no longer a release candidate
        queued_bytes_ -= queued_size_[c];
        left_stamp_[c] = 0;
      }
      // Scattered reads: the kernel no longer reads around a fault, so a visit that reads
      // arrays reads them ahead even when they were advised before (they may have been evicted).
      const bool refetch = scattered_depth_ > 0 && arrays != 0;
      const uint8_t wanted = uint8_t((arrays & kReadsAllArrays) | kWorkArrays);
      const uint8_t missing = uint8_t(wanted & (refetch ? 0xff : ~resident_[c]));
      if (missing) {
        if (resident_[c] == 0) ++visits.chunks_fetched;
        else if ((missing & ~resident_[c]) == 0) ++visits.chunks_refetched;
        resident_[c] |= missing;
        visits.bytes_read_ahead += chunk_bytes(c, missing);
        fetch.push_back({c, missing});
      }
    }
  }
  for (const auto& [c, missing] : fetch) {
    store_.validate_chunk(c);
    if (missing & kReadsAllArrays) store_.advise(c, MeshStore::Advice::WillNeed, missing & kReadsAllArrays);
    if (missing & kWorkArrays) advise_work_arrays(c, true);
  }
}

void ChunkScheduler::leave(const char* stage, VertexRange range) {
  if (range.end <= range.begin || view_.chunks.empty()) return;
  const auto [first, last] = chunks_of(range);
  std::vector<std::pair<uint32_t, uint8_t>> release;  // (chunk, arrays read ahead)
  {
    std::lock_guard lock(mutex_);
    for (uint32_t c = first; c < last; ++c) {
      if (--busy_[c] != 0 || !resident_[c]) continue;
      left_stamp_[c] = ++stamp_;
      left_stage_[c] = stage;
      left_.push_back({c, stamp_});
      queued_size_[c] = chunk_bytes(c, resident_[c]);
      queued_bytes_ += queued_size_[c];
    }
    while (queued_bytes_ > budget_ && !left_.empty()) {
      const auto [c, stamp] = left_.front();
      if (left_stamp_[c] != stamp) {  // entered (and maybe left) again since: stale
        left_.pop_front();
        continue;
      }
      // Only what earlier stages left goes: a stage's own rounds revisit its chunks cyclically,
      // and releasing them ahead of the kernel's reclaim only made it read them again.
      if (left_stage_[c] == stage || std::strcmp(left_stage_[c], stage) == 0) break;
      left_.pop_front();
      queued_bytes_ -= queued_size_[c];
      left_stamp_[c] = 0;
      release.push_back({c, resident_[c]});
      resident_[c] = 0;
      ++released_;
    }
  }
  for (const auto& [c, arrays] : release) {
    if (arrays & kReadsAllArrays) store_.advise(c, MeshStore::Advice::Cold, arrays & kReadsAllArrays);
    if (arrays & kWorkArrays) advise_work_arrays(c, false);
  }
}

void ChunkScheduler::scattered_reads(bool begin) {
  // Called from ScatteredReads' destructor, maybe while an exception unwinds: advice only, so
  // a failure (no memory for the list of work files) is dropped rather than thrown.
  try {
    std::lock_guard lock(mutex_);
    if (begin ? scattered_depth_++ != 0 : --scattered_depth_ != 0) return;
    // A fault reads ahead max(read_ahead_kb) of the file around it: 8 MB on the test machine's
    // disk. In the clustering's late rounds, with the cache smaller than the working set, that
    // read 190 GB at 105M faces inside 2 GiB for a few MB of touched pages.
    store_.advise(MeshStore::kAllChunks, begin ? MeshStore::Advice::Random : MeshStore::Advice::Normal);
    if (work_)
      for (const auto& [data, size] : work_->file_regions(view_.vertex_count()))
        advise_pages(data, size, begin ? MADV_RANDOM : MADV_NORMAL, PageSpan::Covering);
  } catch (...) {
  }
}

SchedulerReport ChunkScheduler::report() const {
  std::lock_guard lock(mutex_);
  SchedulerReport r;
  r.resident_budget_bytes = budget_;
  r.chunks = view_.chunks.size();
  r.chunks_released = released_;
  for (const auto& [name, visits] : stages_) r.stages.push_back(visits);
  return r;
}

}  // namespace streamcvd
