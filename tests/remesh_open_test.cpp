// End-to-end tests of the remesher on open and dirty inputs (core/remesh.h,
// streaming/remesh_pipeline.h): manifold output, holes kept or closed, the genus kept, exactly N
// vertices with the boundary strips, no folded triangle on a flat grid.
#include "streamcvd/core/remesh.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/remesh_pipeline.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

// --- open and dirty inputs -------------------------------------------------------------------------------

TEST(RemeshOpen, OpenAndDirtyInputsGiveManifoldOutput) {
  struct Case {
    std::string name;
    MeshBuffers mesh;
    std::vector<uint32_t> budgets;
  };
  std::vector<Case> cases;
  cases.push_back({"grid", make_grid(80, 80), {20, 300, 1000}});
  cases.push_back({"elephant-with-holes", read_mesh(test::data_path("cgal_elephant_with_holes.off")), {200, 500, 1000, 2000}});
  // 150 non-manifold edges, 87 duplicate faces, 25 unreferenced vertices in the input.
  cases.push_back({"bunny", read_mesh(test::data_path("bun_zipper_res2.ply")), {200, 500, 2000}});
  for (const Case& c : cases) {
    const TopologyStats in = compute_topology_stats(c.mesh.view());
    MeshStore store = MeshStore::build(c.mesh.view());
    for (uint32_t n : c.budgets) {
      SCOPED_TRACE(c.name + " N=" + std::to_string(n));
      PipelineOptions o;
      o.remesh.clustering = test::metric_i_one_thread();
      o.remesh.vertices = n;
      PipelineResult r = remesh_store(store, o);
      const TopologyStats& t = r.output_topology;
      std::printf("[ open     ] %-20s N=%-5u -> V=%u (strip vertices %llu) loops %llu -> %llu, holes closed %llu, chi %lld -> %lld, faces removed %llu\n",
                  c.name.c_str(), n, r.remesh.mesh.vertex_count(), (unsigned long long)r.remesh.dual.boundary_vertices_added,
                  (unsigned long long)in.boundary_loops, (unsigned long long)t.boundary_loops,
                  (unsigned long long)r.remesh.dual.holes_closed, (long long)in.euler_characteristic,
                  (long long)t.euler_characteristic, (unsigned long long)r.remesh.placement.defects_removed.faces_removed);
      EXPECT_EQ(r.remesh.placement.defect_vertices, 0u);
      EXPECT_EQ(t.nonmanifold_edges, 0u);
      EXPECT_EQ(t.nonmanifold_vertices, 0u);
      EXPECT_EQ(t.duplicate_faces, 0u);
      EXPECT_EQ(t.isolated_vertices, 0u);
      EXPECT_TRUE(t.consistently_oriented);
      EXPECT_EQ(r.remesh.clusters, n);
      // N vertices, strips included, but where the strips alone need half of N or more (said
      // in the budget note: the strips of the dual of N clusters, which the repair can leave
      // fewer) or the last-resort cleanup deleted some (the dirty bunny).
      EXPECT_EQ(int64_t(r.remesh.mesh.vertex_count()),
                int64_t(n) - r.remesh.dual.vertex_shortfall - int64_t(r.remesh.placement.defects_removed.vertices_removed));
      const bool strips_need_half = 2 * r.remesh.dual.boundary_vertices_added >= n ||
                                    r.remesh.budget.note.starts_with("the boundary strips need");
      if (!strips_need_half && r.remesh.placement.defects_removed.vertices_removed == 0) {
        EXPECT_EQ(r.remesh.mesh.vertex_count(), n);
      } else if (r.remesh.dual.vertex_shortfall != 0) {
        EXPECT_FALSE(r.remesh.budget.note.empty()) << "a missed N must be explained";
      }
      EXPECT_GT(r.remesh.dual.boundary_vertices_added, 0u);
      if (c.name != "bunny") {  // manifold inputs: every hole is either kept or closed by the dual
        EXPECT_EQ(r.remesh.placement.defects_removed.faces_removed, 0u);
        EXPECT_EQ(t.boundary_loops + r.remesh.dual.holes_closed, in.boundary_loops);
        EXPECT_EQ(t.components, 1u);
        // Same genus, g = (2 − χ − loops) / 2 for one orientable component with boundary; a
        // closed hole raises χ by one and removes one loop.
        EXPECT_EQ(2 - t.euler_characteristic - int64_t(t.boundary_loops),
                  2 - in.euler_characteristic - int64_t(in.boundary_loops))
            << "genus changed";
      }
    }
  }
  {
    // The elephant's holes at N = 2000: those narrower than two output edges close (each adds
    // a disc: χ + 1), the others keep their loop, the genus stays.
    MeshBuffers holes = read_mesh(test::data_path("cgal_elephant_with_holes.off"));
    const TopologyStats in = compute_topology_stats(holes.view());
    MeshStore store = MeshStore::build(holes.view());
    PipelineOptions o;
    o.remesh.clustering = test::metric_i_one_thread();
    o.remesh.vertices = 2000;
    PipelineResult r = remesh_store(store, o);
    EXPECT_EQ(r.output_topology.boundary_loops + r.remesh.dual.holes_closed, in.boundary_loops);
    EXPECT_GT(2 * r.output_topology.boundary_loops, in.boundary_loops) << "most holes are wider than two edges";
    EXPECT_EQ(r.output_topology.euler_characteristic, in.euler_characteristic + int64_t(r.remesh.dual.holes_closed));
  }
}

TEST(RemeshOpen, FlatGridOutputHasNoFoldedTriangles) {
  // Every output triangle of a flat +z grid must face +z. Known failure (see report): at a convex
  // boundary corner the §VI-D strip triangle (p_t, p_t+1, b) folds when the centroid of the corner
  // cluster b lies on or beyond the chord p_t p_t+1 (measured: 1-3 folded triangles per run).
  for (uint64_t seed : {1ull, 2ull}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    MeshBuffers grid = make_grid(80, 80);
    MeshStore store = MeshStore::build(grid.view());
    RemeshOptions o;
    o.clustering = test::metric_i_one_thread();
    o.vertices = 300;
    o.seed = seed;
    RemeshResult r = remesh(store.view(), o);
    const auto& P = r.mesh.positions;
    const auto& T = r.mesh.triangles;
    uint32_t folded = 0;
    for (size_t f = 0; f < T.size(); f += 3) {
      const float *a = &P[3 * size_t(T[f])], *b = &P[3 * size_t(T[f + 1])], *c = &P[3 * size_t(T[f + 2])];
      double z = (double(b[0]) - a[0]) * (double(c[1]) - a[1]) - (double(b[1]) - a[1]) * (double(c[0]) - a[0]);
      folded += z <= 0;
    }
    std::printf("[ open     ] grid 80x80 N=300 seed %llu: %u of %zu output triangles folded\n", (unsigned long long)seed,
                folded, T.size() / 3);
    EXPECT_EQ(folded, 0u);
  }
}

// Eight pieces with boundaries (grids of different sizes and shapes), a closed torus and a
// small sphere in one soup: every metric gives exactly N output vertices, strip vertices included, with each piece kept.
TEST(RemeshExactCount, ManyPiecesWithBoundariesGiveExactlyN) {
  MeshBuffers soup;
  for (int k = 0; k < 8; ++k)
    test::append_shifted(soup, make_grid(30 + 5 * k, 20 + 3 * k, 1.0f + 0.2f * float(k), 0.6f), 0, 1.2f * float(k));
  test::append_shifted(soup, make_torus(80, 40), 5, 0);
  test::append_shifted(soup, make_icosphere(3, 0.3f), 5, 4);
  MeshStore store = MeshStore::build(soup.view());
  for (Metric m : {Metric::I, Metric::IQ, Metric::A, Metric::AQ}) {
    for (uint32_t n : {600u, 2000u}) {
      SCOPED_TRACE(std::string(metric_name(m)) + " N=" + std::to_string(n));
      PipelineOptions o;
      o.remesh.clustering = test::metric_i_one_thread();
      o.remesh.vertices = n;
      o.remesh.clustering.metric = m;
      PipelineResult r = remesh_store(store, o);
      EXPECT_GT(r.remesh.dual.boundary_vertices_added, 0u);
      EXPECT_EQ(r.remesh.mesh.vertex_count(), n) << r.remesh.budget.note;
      EXPECT_EQ(r.remesh.dual.vertex_shortfall, 0);
      EXPECT_EQ(r.output_topology.components, 10u);
      EXPECT_TRUE(r.remesh.checks.components.ok()) << r.remesh.checks.components.problems.front();
      EXPECT_EQ(r.output_topology.nonmanifold_edges + r.output_topology.nonmanifold_vertices, 0u);
    }
  }
}

}  // namespace
}  // namespace streamcvd
