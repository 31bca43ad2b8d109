// Tests of core/mesh/subdivide.h (linear 1→4 subdivision, §VI-F) and of the pipeline's use of it
// when N approaches the input vertex count.
#include "streamcvd/core/mesh/subdivide.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/remesh_pipeline.h"
#include "streamcvd/streaming/store/store.h"
#include "streamcvd/streaming/store/subdivision_stream.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

uint64_t distinct_edges(const TriangleSoupView& m) {
  std::set<std::pair<uint32_t, uint32_t>> e;
  for (uint64_t f = 0; f < m.face_count(); ++f)
    for (int k = 0; k < 3; ++k) e.insert(std::minmax(m.triangles[3 * f + k], m.triangles[3 * f + (k + 1) % 3]));
  return e.size();
}

double total_area(const TriangleSoupView& m) {
  double a = 0;
  for (uint64_t f = 0; f < m.face_count(); ++f) {
    const float* p = &m.positions[3 * size_t(m.triangles[3 * f])];
    const float* q = &m.positions[3 * size_t(m.triangles[3 * f + 1])];
    const float* r = &m.positions[3 * size_t(m.triangles[3 * f + 2])];
    double u[3], v[3];
    for (int k = 0; k < 3; ++k) {
      u[k] = double(q[k]) - p[k];
      v[k] = double(r[k]) - p[k];
    }
    double c[3] = {u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    a += 0.5 * std::sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]);
  }
  return a;
}

void expect_subdivision_counts(const MeshBuffers& in, const std::string& what) {
  SCOPED_TRACE(what);
  MeshBuffers out = subdivide_linear(in.view());
  const uint64_t E = distinct_edges(in.view());
  EXPECT_EQ(out.vertex_count(), in.vertex_count() + E);
  EXPECT_EQ(out.face_count(), 4 * in.face_count());
  // The original vertices come first, unchanged.
  for (size_t i = 0; i < in.positions.size(); ++i) ASSERT_EQ(out.positions[i], in.positions[i]);
  TopologyStats a = compute_topology_stats(in.view()), b = compute_topology_stats(out.view());
  EXPECT_EQ(b.euler_characteristic, a.euler_characteristic);
  EXPECT_EQ(b.components, a.components);
  EXPECT_EQ(b.boundary_loops, a.boundary_loops);
  EXPECT_EQ(b.closed_manifold, a.closed_manifold);
  EXPECT_EQ(b.genus, a.genus);
  EXPECT_EQ(b.consistently_oriented, a.consistently_oriented);
  EXPECT_TRUE(b.consistently_oriented);
  EXPECT_EQ(b.nonmanifold_edges, 0u);
  EXPECT_EQ(b.degenerate_faces, 0u);
  EXPECT_EQ(b.duplicate_faces, 0u);
  EXPECT_EQ(b.edges, 2 * E + 3 * in.face_count());
  EXPECT_NEAR(total_area(out.view()), total_area(in.view()), 1e-5 * total_area(in.view()));
  // Every new vertex is the midpoint of one input edge.
  std::set<std::array<float, 3>> midpoints;
  for (uint64_t f = 0; f < in.face_count(); ++f)
    for (int k = 0; k < 3; ++k) {
      const float* p = &in.positions[3 * size_t(in.triangles[3 * f + k])];
      const float* q = &in.positions[3 * size_t(in.triangles[3 * f + (k + 1) % 3])];
      midpoints.insert({0.5f * (p[0] + q[0]), 0.5f * (p[1] + q[1]), 0.5f * (p[2] + q[2])});
    }
  for (uint32_t v = in.vertex_count(); v < out.vertex_count(); ++v) {
    std::array<float, 3> p = {out.positions[3 * v], out.positions[3 * v + 1], out.positions[3 * v + 2]};
    EXPECT_TRUE(midpoints.count(p)) << "vertex " << v << " is not an edge midpoint";
  }
}

TEST(Subdivide, IcosphereCountsTopologyAndOrientation) {
  const MeshBuffers s = make_icosphere(2);  // V 162, E 480, F 320
  expect_subdivision_counts(s, "icosphere 2");
  MeshBuffers out = subdivide_linear(s.view());
  EXPECT_EQ(out.vertex_count(), 162u + 480u);
  EXPECT_EQ(out.face_count(), 1280u);
  TopologyStats t = compute_topology_stats(out.view());
  EXPECT_TRUE(t.closed_manifold);
  EXPECT_EQ(t.genus, 0);
  EXPECT_EQ(t.euler_characteristic, 2);
  // The corner triangles keep the input orientation: face 4f has the normal of input face f.
  for (uint64_t f = 0; f < s.face_count(); ++f) {
    auto normal = [](const MeshBuffers& m, uint64_t face) {
      const float* p = &m.positions[3 * size_t(m.triangles[3 * face])];
      const float* q = &m.positions[3 * size_t(m.triangles[3 * face + 1])];
      const float* r = &m.positions[3 * size_t(m.triangles[3 * face + 2])];
      double u[3], v[3];
      for (int k = 0; k < 3; ++k) {
        u[k] = double(q[k]) - p[k];
        v[k] = double(r[k]) - p[k];
      }
      return std::array<double, 3>{u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]};
    };
    auto n0 = normal(s, f);
    for (int c = 0; c < 4; ++c) {
      auto n1 = normal(out, 4 * f + c);
      EXPECT_GT(n0[0] * n1[0] + n0[1] * n1[1] + n0[2] * n1[2], 0.0) << "sub-face " << 4 * f + c << " flipped";
    }
  }
}

TEST(Subdivide, TorusGridAndTwoLevels) {
  expect_subdivision_counts(make_torus(10, 6), "torus");
  expect_subdivision_counts(make_grid(5, 4), "grid");
  MeshBuffers once = subdivide_linear(make_icosphere(1).view());
  expect_subdivision_counts(once, "icosphere 1, second level");
  MeshBuffers twice = subdivide_linear(once.view());
  EXPECT_EQ(twice.vertex_count(), uint32_t(10 * 16 * 4 + 2));  // 10·4^l + 2 with l = 3
}

TEST(Subdivide, DegenerateFacesCopiedAndUnreferencedVerticesKept) {
  MeshBuffers m;
  m.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 9, 9, 9};  // vertex 3 unreferenced
  m.triangles = {0, 1, 2, 0, 1, 1};                      // second face degenerate
  MeshBuffers out = subdivide_linear(m.view());
  // Edges of the degenerate face (0-1, 1-1) still get midpoints: 0-1 is shared, 1-1 is new.
  EXPECT_EQ(out.face_count(), 5u);
  EXPECT_EQ(out.triangles[12], 0u);
  EXPECT_EQ(out.triangles[13], 1u);
  EXPECT_EQ(out.triangles[14], 1u);
  EXPECT_EQ(out.positions[9], 9.0f);
  for (uint32_t i : out.triangles) EXPECT_LT(i, out.vertex_count());
  EXPECT_TRUE(subdivide_linear(MeshBuffers{}.view()).triangles.empty());
}

TEST(Subdivide, LevelsForABudget) {
  EXPECT_GE(subdivision_levels(1000, 500, -1), 1);
  EXPECT_EQ(subdivision_levels(1000, 500, -1), 2);      // 1000 → 4000 → 16000 ≥ 10·500
  EXPECT_EQ(subdivision_levels(100000, 1000, -1), 0);   // already 100 vertices per cluster
  EXPECT_EQ(subdivision_levels(10000, 1000, -1), 0);    // exactly 10 per cluster
  EXPECT_EQ(subdivision_levels(9999, 1000, -1), 1);
  EXPECT_EQ(subdivision_levels(1000, 500, 0), 0);       // requested level used as is
  EXPECT_EQ(subdivision_levels(100000, 10, 3), 3);
  EXPECT_EQ(subdivision_levels(4, 1000000000, -1), 6);  // capped
  EXPECT_EQ(subdivision_levels(1000, 0, -1), 0);
  EXPECT_EQ(subdivision_levels(1000, 500, -1, 1.0), 0);
  EXPECT_EQ(subdivision_levels(1000, 500, -1, 3.0), 1);
}

TEST(Subdivide, PipelineReachesNAboveHalfTheInputVertices) {
  // 642 input vertices, N = 600: the pipeline subdivides and still returns exactly N vertices.
  MeshBuffers sphere = make_icosphere(3);
  MeshStore store = MeshStore::build(sphere.view());
  PipelineOptions o;
  o.remesh.clustering = test::metric_i_one_thread();
  o.remesh.vertices = 600;
  PipelineResult r = remesh_store(store, o);
  EXPECT_GE(r.subdivision_levels, 1);
  EXPECT_GE(r.remeshed_vertices, 6000u);
  EXPECT_EQ(r.remesh.clusters, 600u);
  EXPECT_EQ(r.remesh.mesh.vertex_count(), 600u);
  EXPECT_EQ(r.remesh.placement.defect_vertices, 0u);
  EXPECT_TRUE(r.output_topology.closed_manifold);
  EXPECT_TRUE(r.output_topology.consistently_oriented);
  EXPECT_EQ(r.output_topology.genus, 0);
  // Without subdivision the same budget still works but each cluster holds ~1 vertex.
  o.subdivide = 0;
  PipelineResult flat = remesh_store(store, o);
  EXPECT_EQ(flat.subdivision_levels, 0);
  EXPECT_EQ(flat.remeshed_vertices, 642u);
  EXPECT_EQ(flat.remesh.clusters, 600u);
}

}  // namespace
}  // namespace streamcvd
