#include "streamcvd/core/mesh/progress.h"

#include <algorithm>
#include <utility>

namespace streamcvd {

namespace {
constexpr uint32_t kBlockVertices = 1u << 16;  // the unit of a view without chunks
constexpr auto kReportInterval = std::chrono::milliseconds(100);
}  // namespace

StageReporter::StageReporter(ProgressCallback callback, const MeshView& mesh)
    : callback_(std::move(callback)), inner_(mesh.residency), view_(mesh) {
  view_.residency = this;
  // Chunk ends copied once: leave() then never touches a (possibly mapped) chunk table.
  if (!mesh.chunks.empty()) {
    chunk_end_.reserve(mesh.chunks.size());
    for (const Chunk& c : mesh.chunks) chunk_end_.push_back(c.vertex_end);
  } else {
    for (uint32_t v = 0; v < mesh.vertex_count(); v += kBlockVertices)
      chunk_end_.push_back(std::min(mesh.vertex_count(), v + kBlockVertices));
  }
  visited_.assign(chunk_end_.size(), 0);
}

StageReporter::~StageReporter() = default;

void StageReporter::rethrow_pending_locked() {
  if (!pending_) return;
  std::exception_ptr e = std::exchange(pending_, nullptr);
  std::rethrow_exception(e);
}

void StageReporter::begin(const char* stage) {
  std::lock_guard lock(mutex_);
  rethrow_pending_locked();
  if (stage_) report_locked(true);
  stage_ = stage;
  round_ = 0;
  completions_ = visits_ = vertices_ = 0;
  std::fill(visited_.begin(), visited_.end(), 0);
  report_locked(false);  // the stage's start: its elapsed time counts from here
}

void StageReporter::round(uint32_t r, const char* unit) {
  std::lock_guard lock(mutex_);
  rethrow_pending_locked();
  round_ = r;
  round_unit_ = unit;
  completions_ = vertices_ = 0;  // visits_ stays: the stage does read chunks
  std::fill(visited_.begin(), visited_.end(), 0);
  if (std::chrono::steady_clock::now() - last_report_ >= kReportInterval) report_locked(false);
}

void StageReporter::finish() {
  std::lock_guard lock(mutex_);
  if (stage_) report_locked(true);
  stage_ = nullptr;
}

void StageReporter::enter(const char* stage, VertexRange range, uint8_t arrays) {
  if (inner_) inner_->enter(stage, range, arrays);
}

void StageReporter::scattered_reads(bool begin) {
  if (inner_) inner_->scattered_reads(begin);
}

void StageReporter::leave(const char* stage, VertexRange range) {
  if (inner_) inner_->leave(stage, range);
  if (range.end <= range.begin || chunk_end_.empty()) return;
  std::lock_guard lock(mutex_);
  ++visits_;
  vertices_ += range.end - range.begin;
  // The chunks the range overlaps (usually one or two): each counts its share of the range.
  auto c = size_t(std::upper_bound(chunk_end_.begin(), chunk_end_.end(), range.begin) - chunk_end_.begin());
  for (; c < chunk_end_.size(); ++c) {
    const uint32_t lo = c == 0 ? 0 : chunk_end_[c - 1], hi = chunk_end_[c];
    if (lo >= range.end) break;
    const uint64_t size = hi - lo;
    if (size == 0) continue;
    const uint64_t before = visited_[c] / size;
    visited_[c] += std::min(hi, range.end) - std::max(lo, range.begin);
    completions_ += visited_[c] / size - before;
  }
  // leave() runs in RangeVisit's destructor: a callback's exception (a cancelled job) waits for
  // the next begin() or round(), which throw it.
  if (stage_ && !pending_ && std::chrono::steady_clock::now() - last_report_ >= kReportInterval) {
    try {
      report_locked(false);
    } catch (...) {
      pending_ = std::current_exception();
    }
  }
}

void StageReporter::report_locked(bool finished) {
  last_report_ = std::chrono::steady_clock::now();
  if (!callback_) return;
  StageProgress p;
  p.stage = stage_;
  p.finished = finished;
  p.round = round_;
  p.round_unit = round_ ? round_unit_ : "pass";
  const uint64_t chunks = chunk_end_.size();
  // A stage that reads no chunk (e.g. on the output mesh) reports its time only, and a finished
  // one with rounds its last round (its chunk count restarted with it).
  if (visits_ == 0 || chunks == 0 || (finished && round_)) {
    callback_(p);
    return;
  }
  p.unit = view_.chunks.empty() ? "blocks" : "chunks";
  p.total = chunks;
  p.done = completions_;
  uint64_t pass = 1;
  if (completions_ > chunks) {  // through every chunk and visiting them again: the next pass
    pass = (completions_ - 1) / chunks + 1;
    p.done = completions_ - (pass - 1) * chunks;
    if (!round_) p.round = uint32_t(pass);
  }
  // The vertices give the part of the pass done between chunk ends (a few big chunks).
  const uint64_t V = chunk_end_.back(), before = (pass - 1) * V;
  if (V > 0) p.fraction = std::min(1.0, double(vertices_ > before ? vertices_ - before : 0) / double(V));
  callback_(p);
}

}  // namespace streamcvd
