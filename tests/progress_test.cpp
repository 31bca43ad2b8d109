// The stage reporter (core/mesh/progress.h): chunks counted once all their vertices were visited,
// passes and rounds, stages without visits reporting their time only, visits forwarded to the
// view's own hooks, and the remesh reporting each of its stages in order, started and finished.
#include "streamcvd/core/mesh/progress.h"

#include <gtest/gtest.h>

#include <chrono>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "streamcvd/core/remesh.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

struct CountingHooks final : RangeResidency {
  int entered = 0, left = 0;
  void enter(const char*, VertexRange, uint8_t) override { ++entered; }
  void leave(const char*, VertexRange) override { ++left; }
};

// Visits [0, V) in ranges of `step` vertices through `mesh`'s hooks.
void visit_all(const MeshView& mesh, uint32_t step) {
  for (uint32_t v = 0; v < mesh.vertex_count(); v += step) {
    const RangeVisit visit(mesh, "test", {v, std::min(mesh.vertex_count(), v + step)}, kReadsNeighbours);
  }
}

TEST(StageReporter, CountsChunksPassesAndRounds) {
  const MeshStore store = MeshStore::build(make_torus(60, 40).view(), {.faces_per_chunk = 1000});
  MeshView mesh = store.view();
  const uint64_t C = mesh.chunks.size();
  ASSERT_GT(C, 2u);
  CountingHooks hooks;
  mesh.residency = &hooks;
  std::vector<StageProgress> seen;
  StageReporter reporter([&](const StageProgress& p) { seen.push_back(p); }, mesh);
  EXPECT_EQ(reporter.view().residency, &reporter);

  reporter.begin("first");  // one pass in small ranges
  visit_all(reporter.view(), 100);
  reporter.begin("second");  // two passes
  visit_all(reporter.view(), 700);
  visit_all(reporter.view(), 700);
  reporter.begin("idle");  // no visit: its time only
  reporter.begin("loops");
  reporter.round(1, "loop");
  visit_all(reporter.view(), 300);
  reporter.round(2, "loop");
  reporter.finish();

  // Every visit reached the view's own hooks.
  EXPECT_EQ(hooks.entered, hooks.left);
  EXPECT_GT(hooks.entered, 0);
  std::vector<StageProgress> finished;
  for (const StageProgress& p : seen)
    if (p.finished) finished.push_back(p);
  ASSERT_EQ(finished.size(), 4u);
  EXPECT_STREQ(finished[0].stage, "first");
  EXPECT_EQ(finished[0].done, C);
  EXPECT_EQ(finished[0].total, C);
  EXPECT_STREQ(finished[0].unit, "chunks");
  EXPECT_EQ(finished[0].round, 0u);
  EXPECT_DOUBLE_EQ(finished[0].fraction, 1.0);
  EXPECT_STREQ(finished[1].stage, "second");
  EXPECT_EQ(finished[1].done, C);
  EXPECT_EQ(finished[1].round, 2u);
  EXPECT_STREQ(finished[1].round_unit, "pass");
  EXPECT_STREQ(finished[2].stage, "idle");
  EXPECT_EQ(finished[2].total, 0u);
  EXPECT_STREQ(finished[2].unit, "");
  EXPECT_STREQ(finished[3].stage, "loops");
  EXPECT_EQ(finished[3].round, 2u);
  EXPECT_STREQ(finished[3].round_unit, "loop");
  EXPECT_EQ(finished[3].total, 0u);  // the last round's chunks restarted with it
  // Each stage starts with a report of its own (its elapsed time counts from there), and the
  // chunk count of a pass only grows.
  EXPECT_STREQ(seen.front().stage, "first");
  EXPECT_FALSE(seen.front().finished);
  uint64_t last = 0;
  for (const StageProgress& p : seen)
    if (std::string(p.stage) == "first" && p.total > 0) {
      EXPECT_GE(p.done, last);
      last = p.done;
    }
}

TEST(StageReporter, RemeshReportsEveryStageInOrder) {
  const MeshStore store = MeshStore::build(make_torus(60, 40).view(), {.faces_per_chunk = 1000});
  RemeshOptions options;
  options.clustering = test::metric_i_one_thread();
  options.vertices = 200;
  std::vector<std::string> started, finished;
  uint32_t loops = 0;
  options.progress = [&](const StageProgress& p) {
    std::vector<std::string>& list = p.finished ? finished : started;
    if (list.empty() || list.back() != p.stage) list.push_back(p.stage);
    if (p.finished && std::string(p.stage) == "clustering") loops = p.round;
  };
  const RemeshResult r = remesh(store.view(), options);
  const std::vector<std::string> stages = {"items",     "sampling", "clustering", "repair",
                                           "dual",      "placement", "optimize",  "checks"};
  EXPECT_EQ(finished, stages);
  EXPECT_EQ(started, stages);
  EXPECT_EQ(loops, r.clustering.unconstrained_loops + r.clustering.constrained_loops);
}

// A callback may throw to cancel the job (the Python binding's Ctrl-C). Inside a range visit it
// runs in RangeVisit's destructor, where an exception would terminate: the reporter keeps it and
// throws it from the next round or stage instead, once.
TEST(StageReporter, AnExceptionOfTheCallbackInsideAVisitWaitsForTheNextRound) {
  const MeshStore store = MeshStore::build(make_torus(60, 40).view(), {.faces_per_chunk = 1000});
  bool armed = false;
  int thrown = 0;
  StageReporter reporter(
      [&](const StageProgress& p) {
        if (armed && !p.finished) ++thrown, throw std::runtime_error("cancelled");
      },
      store.view());
  reporter.begin("loops");
  reporter.round(1, "loop");
  armed = true;
  std::this_thread::sleep_for(std::chrono::milliseconds(120));  // past the reporter's rate limit
  EXPECT_NO_THROW(visit_all(reporter.view(), 300));
  EXPECT_EQ(thrown, 1);  // one report was due, and the next ones wait for the kept exception
  armed = false;
  EXPECT_THROW(reporter.round(2, "loop"), std::runtime_error);
  EXPECT_NO_THROW(reporter.round(3, "loop"));  // thrown once
  EXPECT_NO_THROW(reporter.finish());
}

TEST(StageReporter, ARemeshWhoseCallbackThrowsStopsWithThatException) {
  const MeshStore store = MeshStore::build(make_torus(60, 40).view(), {.faces_per_chunk = 1000});
  for (const char* cancel_at : {"sampling", "clustering", "dual"}) {
    RemeshOptions options;
    options.clustering = test::metric_i_one_thread();
    options.vertices = 200;
    std::vector<std::string> seen;
    options.progress = [&](const StageProgress& p) {
      if (seen.empty() || seen.back() != p.stage) seen.push_back(p.stage);
      // The clustering is cancelled in its second loop (from a round or a visit), the others at their start.
      const bool clustering = std::string(p.stage) == "clustering";
      if (std::string(p.stage) == cancel_at && (!clustering || p.round >= 2)) throw std::runtime_error(cancel_at);
    };
    EXPECT_THROW(remesh(store.view(), options), std::runtime_error) << cancel_at;
    ASSERT_FALSE(seen.empty());
    EXPECT_EQ(seen.back(), cancel_at);  // no stage ran after the one cancelled
  }
}

}  // namespace
}  // namespace streamcvd
