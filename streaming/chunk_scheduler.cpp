#include "streaming/chunk_scheduler.h"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cstring>

namespace streamcvd {

namespace {

// madvise over the whole pages of [data, data + bytes) (a neighbour's data may share the edge pages).
void advise_pages(const void* data, size_t bytes, int advice) {
  static const uintptr_t page = uintptr_t(::sysconf(_SC_PAGESIZE));
  const uintptr_t lo = (uintptr_t(data) + page - 1) & ~(page - 1), hi = (uintptr_t(data) + bytes) & ~(page - 1);
  if (hi > lo) ::madvise(reinterpret_cast<void*>(lo), hi - lo, advice);
}

}  // namespace

ChunkScheduler::ChunkScheduler(const MeshStore& store, const WorkSpace* work, uint64_t resident_budget)
    : store_(store), view_(store.view()), work_(work), budget_(resident_budget),
      resident_(view_.chunks.size(), 0), busy_(view_.chunks.size(), 0), left_stamp_(view_.chunks.size(), 0),
      queued_size_(view_.chunks.size(), 0) {}

std::pair<uint32_t, uint32_t> ChunkScheduler::chunks_of(VertexRange range) const {
  const auto& chunks = view_.chunks;
  auto starts_after = [](uint32_t v, const Chunk& c) { return v < c.vertex_begin; };
  const uint32_t first =
      uint32_t(std::upper_bound(chunks.begin(), chunks.end(), range.begin, starts_after) - chunks.begin()) - 1;
  uint32_t last = first;
  while (last < chunks.size() && chunks[last].vertex_begin < range.end) ++last;
  return {first, std::max(last, first + 1)};
}

uint64_t ChunkScheduler::chunk_bytes(uint32_t c) const {
  const Chunk& k = view_.chunks[c];
  const uint64_t n = k.vertex_end - k.vertex_begin;
  uint64_t bytes = n * (12 + 1 + 16) + 12 * (k.face_end - k.face_begin) +
                   4 * (view_.vertex_vertex_offsets[k.vertex_end] - view_.vertex_vertex_offsets[k.vertex_begin]) +
                   4 * (view_.vertex_face_offsets[k.vertex_end] - view_.vertex_face_offsets[k.vertex_begin]);
  if (work_)
    for (const auto& [data, size] : work_->file_regions(view_.vertex_count())) bytes += n * (size / view_.vertex_count());
  return bytes;
}

void ChunkScheduler::advise_work_arrays(uint32_t c, bool will_need) const {
  if (!work_) return;
  const Chunk& k = view_.chunks[c];
  for (const auto& [data, size] : work_->file_regions(view_.vertex_count())) {
    const size_t stride = size / view_.vertex_count();
    advise_pages(static_cast<const std::byte*>(data) + stride * k.vertex_begin, stride * (k.vertex_end - k.vertex_begin),
                 will_need ? MADV_WILLNEED : MADV_COLD);
  }
}

StageVisits& ChunkScheduler::stage_of(const char* stage) {
  for (auto& [name, visits] : stages_)
    if (name == stage || std::strcmp(name, stage) == 0) return visits;
  stages_.push_back({stage, StageVisits{stage}});
  return stages_.back().second;
}

void ChunkScheduler::enter(const char* stage, VertexRange range) {
  if (range.end <= range.begin || view_.chunks.empty()) return;
  const auto [first, last] = chunks_of(range);
  std::vector<uint32_t> fetch;
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
      if (!resident_[c]) resident_[c] = 1, fetch.push_back(c);
    }
    visits.chunks_fetched += fetch.size();
  }
  for (uint32_t c : fetch) {
    store_.validate_chunk(c);
    store_.advise(c, MeshStore::Advice::WillNeed);
    advise_work_arrays(c, true);
  }
}

void ChunkScheduler::leave(const char* stage, VertexRange range) {
  (void)stage;
  if (range.end <= range.begin || view_.chunks.empty()) return;
  const auto [first, last] = chunks_of(range);
  std::vector<uint32_t> release;
  {
    std::lock_guard lock(mutex_);
    for (uint32_t c = first; c < last; ++c) {
      if (--busy_[c] != 0 || !resident_[c]) continue;
      left_stamp_[c] = ++stamp_;
      left_.push_back({c, stamp_});
      queued_size_[c] = chunk_bytes(c);
      queued_bytes_ += queued_size_[c];
    }
    while (queued_bytes_ > budget_ && !left_.empty()) {
      const auto [c, stamp] = left_.front();
      left_.pop_front();
      if (left_stamp_[c] != stamp) continue;  // entered (and maybe left) again since: stale
      queued_bytes_ -= queued_size_[c];
      left_stamp_[c] = 0;
      resident_[c] = 0;
      release.push_back(c);
      ++released_;
    }
  }
  for (uint32_t c : release) {
    store_.advise(c, MeshStore::Advice::Cold);
    advise_work_arrays(c, false);
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
