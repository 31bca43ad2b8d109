// Progress of a long job, stage by stage (DESIGN.md §3, batch behaviour): what a stage reports,
// and the reporter the remesh stages go through. A display (tools/job_options.h ProgressLine)
// turns the reports into one line per stage. Reports come per chunk or per loop at most, never
// per vertex, and are rate-limited here, so a job with a display costs nothing measurable more
// and one without pays nothing at all (no reporter is installed).
#pragma once

#include <chrono>
#include <cstdint>
#include <exception>
#include <functional>
#include <mutex>
#include <vector>

#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

/// One report of a stage: `done` of `total` (0 = unknown) in `unit` ("bytes" are printed as
/// sizes, "chunks", "faces", "levels"..., "" = a plain count). `round` is the `round_unit`
/// ("pass", "loop") of a stage that repeats (0 = none). `fraction` is the part of the stage (or
/// of its round) done when it is finer than done / total (−1: done / total). `finished` ends the
/// stage: its line is kept.
struct StageProgress {
  const char* stage = "";
  uint64_t done = 0, total = 0;
  const char* unit = "";
  uint32_t round = 0;
  const char* round_unit = "pass";
  double fraction = -1;
  bool finished = false;
};

/// Receives the reports; may be called from any thread, never from two at once by one reporter.
/// It may throw to cancel the job (the Python binding does on Ctrl-C): the exception ends the
/// job, which unwinds without leaving files behind. A report made inside a range visit passes
/// its exception on at the stage's next round or stage (StageReporter), so cancelling takes
/// up to one clustering loop.
using ProgressCallback = std::function<void(const StageProgress&)>;

/// Reports the stages of one job: begin(stage) ... finish(). Installed as the RangeResidency of
/// the job's mesh view (view()), it forwards every visit to the view's own hooks (the chunk
/// scheduler, if any) and counts the chunks the current stage has been through: a chunk counts
/// once all its vertices were visited, a stage that visits them again starts a new pass.
/// Thread-safe; reports at most 10 times a second between begin() and finish().
class StageReporter final : public RangeResidency {
 public:
  /// Reports to `callback` about `mesh` (whose chunks are the unit; without chunks, blocks of
  /// 65536 vertices). `mesh` is copied, its arrays must outlive the reporter.
  StageReporter(ProgressCallback callback, const MeshView& mesh);
  ~StageReporter() override;
  StageReporter(const StageReporter&) = delete;
  StageReporter& operator=(const StageReporter&) = delete;

  /// `mesh` with this reporter as its residency hooks: the view the stages must use.
  const MeshView& view() const { return view_; }

  /// Ends the current stage (if any) and starts `stage` (a string literal).
  void begin(const char* stage);
  /// Round `r` (1, 2, ...) of the current stage, e.g. loop r of the clustering (`unit` "loop"):
  /// its chunk count restarts.
  void round(uint32_t r, const char* unit);
  /// Ends the current stage: one last report with finished = true.
  void finish();

  void enter(const char* stage, VertexRange range, uint8_t arrays) override;
  void leave(const char* stage, VertexRange range) override;
  void scattered_reads(bool begin) override;

 private:
  void report_locked(bool finished);  // with mutex_ held
  void rethrow_pending_locked();      // with mutex_ held: the callback's exception kept by leave()

  ProgressCallback callback_;
  RangeResidency* inner_;
  MeshView view_;
  std::vector<uint32_t> chunk_end_;      // exclusive end vertex of each chunk, ascending
  std::vector<uint64_t> visited_;        // per chunk: vertices visited in this stage or round
  uint64_t completions_ = 0;             // chunk passes completed in this stage or round
  uint64_t visits_ = 0;                  // ranges left in this stage
  uint64_t vertices_ = 0;                // vertices of those ranges, in this stage or round
  const char* stage_ = nullptr;
  uint32_t round_ = 0;
  const char* round_unit_ = "pass";
  std::chrono::steady_clock::time_point last_report_{};
  std::mutex mutex_;
  std::exception_ptr pending_;  // thrown by the callback inside leave(), rethrown by begin()/round()
};

}  // namespace streamcvd
