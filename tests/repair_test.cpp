// Tests of core/repair.h: the incremental repair loop finds the same defects as the global
// finder on the built dual, and leaves a defect-free dual with connected clusters.
#include "core/repair.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "core/clustering.h"
#include "core/dual_mesh.h"
#include "core/item_data.h"
#include "core/remesh.h"
#include "core/shapes.h"
#include "streaming/mesh_io.h"
#include "streaming/store.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

size_t global_defects(const MeshView& view, const std::vector<int32_t>& labels, uint32_t K, const BoundaryLoops& loops) {
  std::vector<double> z(3 * size_t(K), 0.0);
  DualMesh dual = build_dual_mesh(view, labels, K, z, {}, &loops);
  return find_manifold_defects(dual.mesh.view()).size();
}

// Labels of a random clustering: region growing from random seeds (many small, twisted
// clusters, so the dual has defects), without any minimisation.
std::vector<int32_t> rough_clustering(const MeshView& view, const ItemData& items, uint32_t K, uint64_t seed) {
  ComponentBudget budget = plan_component_budget(view, items, K, SmallComponents::Keep, ram_storage());
  return test::to_vector(initial_sampling(view, items, budget, seed, ram_storage()));
}

// Returns how many of the starts had a defect.
int check_rounds(const MeshBuffers& soup, uint32_t K) {
  MeshStore store = MeshStore::build(soup.view());
  MeshView view = store.view();
  ItemData items = compute_item_data(view);
  BoundaryLoops loops = find_boundary_loops(view);
  std::vector<uint8_t> adjustable(K, 1);
  int defective_starts = 0;
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    std::vector<int32_t> start = rough_clustering(view, items, K, seed);
    // The defect count after r rounds, from the incremental tracker and from a full rebuild.
    for (uint32_t rounds = 0; rounds <= 4; ++rounds) {
      std::vector<int32_t> labels = start;
      DefectRepairOptions options;
      options.max_rounds = rounds;
      options.relax = false;
      ClusteringReport report;
      DefectRepairResult r = repair_dual_defects(view, items, labels, K, adjustable, loops, options, report, ram_storage());
      EXPECT_EQ(r.defect_vertices, global_defects(view, labels, K, loops)) << "K " << K << " seed " << seed << " rounds " << rounds;
      EXPECT_LE(r.rounds, rounds);
    }
    std::vector<int32_t> labels = start;
    ClusteringReport report;
    DefectRepairResult r = repair_dual_defects(view, items, labels, K, adjustable, loops, {}, report, ram_storage());
    EXPECT_EQ(r.defect_vertices, global_defects(view, labels, K, loops));
    if (r.defect_vertices == 0) {
      EXPECT_TRUE(clusters_connected(view, labels, K));
    }
    defective_starts += global_defects(view, start, K, loops) > 0;
  }
  return defective_starts;
}

TEST(RepairLoop, IncrementalChecksMatchTheGlobalFinderOnATorus) {
  // Clusters as wide as the tube wrap it: the duals of these rough clusterings have defects.
  int defective = 0;
  for (uint32_t K : {8u, 12u, 20u, 40u}) defective += check_rounds(make_torus(60, 120), K);
  EXPECT_GT(defective, 0) << "no start had a defect: nothing incremental was checked";
}

TEST(RepairLoop, IncrementalChecksMatchTheGlobalFinderOnAGridWithStrips) {
  for (uint32_t K : {6u, 30u}) check_rounds(make_grid(60, 60), K);
}

TEST(RepairLoop, CleanClusteringNeedsNoRound) {
  MeshBuffers soup = make_icosphere(4);
  MeshStore store = MeshStore::build(soup.view());
  MeshView view = store.view();
  ItemData items = compute_item_data(view);
  const uint32_t K = 200;
  std::vector<int32_t> labels = rough_clustering(view, items, K, 7);
  minimize_clustering(view, items, labels, K);
  BoundaryLoops loops = find_boundary_loops(view);
  std::vector<uint8_t> adjustable(K, 1);
  std::vector<int32_t> before = labels;
  ClusteringReport report;
  DefectRepairResult r = repair_dual_defects(view, items, labels, K, adjustable, loops, {}, report, ram_storage());
  ASSERT_EQ(global_defects(view, before, K, loops), 0u);
  EXPECT_EQ(r.rounds, 0u);
  EXPECT_EQ(r.defect_vertices, 0u);
  EXPECT_EQ(labels, before);
}

TEST(RepairDragon, SlowSeedsConvergeWithinTheRoundBudget) {
  // Dragon, N = 20000, metric I: seed 1 needs 13 repair rounds (seeds 1-18 need 6-13 with the
  // chunk-wise sampling and the K-sized repair). With the former cap of 12 the last-resort
  // cleanup deleted faces and vertices (holes, fewer than N).
  const auto path = test::shared_data_path("stanford_dragon_vrip.ply");
  if (!path) GTEST_SKIP() << "../shared/data absent";
  MeshStore store = MeshStore::build(read_mesh(*path).view());
  for (uint64_t seed : {1}) {
    RemeshOptions o;
    o.vertices = 20000;
    o.seed = seed;
    const RemeshResult r = remesh(store.view(), o);
    EXPECT_GT(r.repair_rounds_used, 12u) << "seed " << seed;
    EXPECT_LE(r.repair_rounds_used, o.repair_rounds) << "seed " << seed;
    EXPECT_EQ(r.defect_faces_removed, 0u) << "seed " << seed;
    EXPECT_EQ(r.defect_vertices, 0u) << "seed " << seed;
    EXPECT_EQ(r.mesh.vertex_count() - r.boundary_vertices_added, 20000u) << "seed " << seed;
  }
}

}  // namespace
}  // namespace streamcvd
