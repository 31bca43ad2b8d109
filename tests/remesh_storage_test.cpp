// The memory limit changes where the per-vertex arrays live (RAM or mapped work files), never the
// order of the work: the same output whatever the storage (DESIGN.md §3; issue "out-of-core
// remesh", item 5). A CI-sized stand-in for the 105M-face run at --memory 2G vs unlimited.
#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <string>
#include <vector>

#include "streamcvd/core/remesh.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/store/store.h"
#include "streamcvd/streaming/schedule/work_space.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

RemeshOptions options_for(Metric metric, uint32_t threads, bool deterministic) {
  RemeshOptions o;
  o.vertices = 1500;
  o.seed = 11;
  o.clustering.metric = metric;
  o.clustering.loops.threads = threads;
  o.clustering.loops.deterministic = deterministic;
  o.clustering.loops.region_vertices = 256;  // many regions: visits cross chunk frontiers
  return o;
}

struct Output {
  std::vector<float> positions;
  std::vector<uint32_t> triangles;
  std::vector<int32_t> labels;
};

Output run_with(const MeshView& view, RemeshOptions o, ArrayStorage& storage) {
  const RemeshResult r = remesh(view, o, storage);
  return {r.mesh.positions, r.mesh.triangles, test::to_vector(r.cluster_of_vertex)};
}

TEST(RemeshStorage, WorkFilesGiveTheSameOutputAsRam) {
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
  const MeshBuffers elephant = read_mesh(test::data_path("cgal_elephant.off"));
  // Small chunks: many chunks, ranges and frontiers, as a large store has.
  const MeshStore store = MeshStore::build(elephant.view(), {.faces_per_chunk = 500});
  ASSERT_GT(store.view().chunks.size(), 4u);
  struct Case {
    Metric metric;
    uint32_t threads;
    bool deterministic;
  };
  for (const Case c : {Case{Metric::I, 1, false}, Case{Metric::IQ, 1, false},
                       Case{Metric::I, 2, true}, Case{Metric::IQ, 2, true}, Case{Metric::A, 2, true}}) {
    SCOPED_TRACE("metric " + std::to_string(int(c.metric)) + " threads " + std::to_string(c.threads));
    const RemeshOptions o = options_for(c.metric, c.threads, c.deterministic);
    const Output in_ram = run_with(store.view(), o, ram_storage());
    WorkSpace files("", 0);  // every array sized by the input in a mapped work file
    const Output in_files = run_with(store.view(), o, files);
    EXPECT_GT(files.peak_file_bytes(), 0u);
    ASSERT_GT(in_ram.triangles.size(), 0u);
    EXPECT_TRUE(in_ram.positions == in_files.positions);
    EXPECT_TRUE(in_ram.triangles == in_files.triangles);
    EXPECT_TRUE(in_ram.labels == in_files.labels);
    // A WorkSpace with a small RAM budget: some arrays in RAM, the rest in files.
    WorkSpace mixed("", 64 << 10);
    const Output in_mixed = run_with(store.view(), o, mixed);
    EXPECT_TRUE(in_ram.positions == in_mixed.positions);
    EXPECT_TRUE(in_ram.triangles == in_mixed.triangles);
  }
}

// Cold arrays (written once, read at the end) take RAM only while half the budget is left for
// the hot ones that come later: at 105M faces in 2 GiB the component ids took the labels' place.
TEST(RemeshStorage, ColdArraysLeaveHalfTheRamBudgetToHotOnes) {
  const uint64_t budget = 1 << 20;
  WorkSpace work(test::temp_dir("cold-arrays").string(), budget);
  const LargeArray<uint8_t> hot(600 << 10, work, "hot");
  EXPECT_EQ(work.ram_bytes(), uint64_t(600 << 10));
  const LargeArray<uint8_t> cold(100 << 10, work, "cold", ArrayUse::Cold);  // 700 KiB > budget / 2
  EXPECT_EQ(work.ram_bytes(), uint64_t(600 << 10));
  EXPECT_EQ(work.file_bytes(), uint64_t(100 << 10));
  const LargeArray<uint8_t> hot2(300 << 10, work, "hot too");  // 900 KiB <= budget
  EXPECT_EQ(work.ram_bytes(), uint64_t(900 << 10));
  WorkSpace roomy(test::temp_dir("cold-arrays-roomy").string(), budget);
  const LargeArray<uint8_t> small_cold(100 << 10, roomy, "cold", ArrayUse::Cold);
  EXPECT_EQ(roomy.ram_bytes(), uint64_t(100 << 10));
}

TEST(RemeshStorage, LabelsAreReturnedOnlyWhenAsked) {
  const MeshBuffers elephant = read_mesh(test::data_path("cgal_elephant.off"));
  const MeshStore store = MeshStore::build(elephant.view());
  RemeshOptions o = options_for(Metric::I, 1, false);
  WorkSpace files("", 0);
  const RemeshResult kept = remesh(store.view(), o, files);
  EXPECT_EQ(kept.cluster_of_vertex.size(), store.view().vertex_count());
  EXPECT_EQ(&kept.cluster_of_vertex.storage(), &ram_storage());  // outlives the work space
  o.keep_vertex_labels = false;
  const RemeshResult dropped = remesh(store.view(), o, files);
  EXPECT_TRUE(dropped.cluster_of_vertex.empty());
  EXPECT_TRUE(dropped.budget.component_of_vertex.empty());
  EXPECT_TRUE(dropped.mesh.triangles == kept.mesh.triangles);
}

}  // namespace
}  // namespace streamcvd
