// Tests of the vertex budget when the boundary strips need a large share of N (core/remesh.cpp):
// the cluster count C is searched so that C clusters plus their strip vertices make N, and the
// N-cluster output (with a note) comes back when that would leave the interior below N/2 or the
// repair cannot make C clusters valid; and the repair leaves the count exact after its last round.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <string>

#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/remesh.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/remesh_pipeline.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

TEST(StripBudget, ElephantWithHolesGetsExactlyNWhenTheInteriorKeepsHalf) {
  // 2,798 vertices, 106 holes. At N = 1000 the strips of 1000 clusters need 734 vertices
  // (over N/2): about 500 larger clusters need fewer than 500, so N is met. At N = 700 too.
  // At N = 200 the interior would fall below N/2: the output is the N clusters with their
  // strips, and says so. Between, N = 500 and 600 are on the edge: whether the search for C
  // finds the clusters whose strips fit depends on which holes close, and at 2 threads it
  // does in about half the runs (measured, whichever repair); at 700 it always does.
  const MeshBuffers holes = read_mesh(test::data_path("cgal_elephant_with_holes.off"));
  const TopologyStats in = compute_topology_stats(holes.view());
  MeshStore store = MeshStore::build(holes.view());
  for (uint32_t n : {1000u, 700u, 200u}) {
    SCOPED_TRACE(n);
    PipelineOptions o;
    o.remesh.clustering = test::metric_i_one_thread();
    o.remesh.vertices = n;
    const PipelineResult r = remesh_store(store, o);
    const RemeshResult& m = r.remesh;
    std::printf("[ budget   ] elephant with holes -> N=%u: %u vertices, %llu strip vertices, %llu loops kept, %llu closed\n", n,
                m.mesh.vertex_count(), (unsigned long long)m.dual.boundary_vertices_added,
                (unsigned long long)r.output_topology.boundary_loops, (unsigned long long)m.dual.holes_closed);
    EXPECT_TRUE(m.checks.components.ok()) << m.checks.components.problems.front();
    EXPECT_EQ(r.output_topology.nonmanifold_edges + r.output_topology.nonmanifold_vertices, 0u);
    EXPECT_EQ(m.placement.defects_removed.faces_removed, 0u);
    EXPECT_EQ(r.output_topology.boundary_loops + m.dual.holes_closed, in.boundary_loops);
    if (n >= 700) {
      EXPECT_EQ(m.mesh.vertex_count(), n) << m.budget.note;
      EXPECT_EQ(m.dual.vertex_shortfall, 0);
      EXPECT_TRUE(m.budget.note.empty()) << m.budget.note;
      EXPECT_LT(2 * m.dual.boundary_vertices_added, n);
    } else {
      EXPECT_GT(m.mesh.vertex_count(), n);
      EXPECT_NE(m.budget.note.find("boundary strips need"), std::string::npos) << m.budget.note;
      // The N clusters and their strips (fewer than the note's: the repair closed holes).
      EXPECT_EQ(m.mesh.vertex_count(), n + m.dual.boundary_vertices_added);
    }
  }
}

TEST(StripBudget, TheLastDefectRoundLeavesTheCountExact) {
  // Cuts of clusters at the boundary add strip vertices: a round sets the count again after
  // them, so no round follows the last defect round only to set the count. Before, 4 of these
  // 10 runs had one (N = 600 seeds 1 and 2, N = 1000 seeds 1 and 3).
  const MeshBuffers holes = read_mesh(test::data_path("cgal_elephant_with_holes.off"));
  MeshStore store = MeshStore::build(holes.view());
  uint32_t with_defects = 0;
  for (uint32_t n : {600u, 1000u})
    for (uint64_t seed = 1; seed <= 5; ++seed) {
      SCOPED_TRACE("N " + std::to_string(n) + ", seed " + std::to_string(seed));
      PipelineOptions o;
      o.remesh.clustering = test::metric_i_one_thread();
      o.remesh.vertices = n;
      o.remesh.seed = seed;
      const RemeshResult m = remesh_store(store, o).remesh;
      ASSERT_FALSE(m.repair.defects_per_round.empty());
      with_defects += m.repair.defects_per_round[0] > 0;
      EXPECT_EQ(m.repair.count_rounds, 0u);
      EXPECT_EQ(m.repair.defects_per_round.back(), 0u);
      EXPECT_EQ(m.mesh.vertex_count(), n);
    }
  EXPECT_GE(with_defects, 8u) << "the runs repair defects, so their rounds cut clusters at the boundary";
}

}  // namespace
}  // namespace streamcvd
