// Tests for core/measure/qem_decimate.h (suite QemDecimate): the OpenMesh baseline of the benchmarks.
#include "streamcvd/core/measure/qem_decimate.h"

#include <gtest/gtest.h>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/core/measure/surface_distance.h"

namespace streamcvd {
namespace {

TEST(QemDecimate, SphereReachesTheTargetAndStaysAClosedManifold) {
  const MeshBuffers sphere = make_icosphere(4);  // 2562 vertices
  QemReport report;
  const MeshBuffers out = decimate_quadric(sphere.view(), 300, &report);
  EXPECT_EQ(out.vertex_count(), 300u);
  EXPECT_EQ(report.input_vertices, 2562u);
  EXPECT_EQ(report.collapses, 2562u - 300u);
  EXPECT_EQ(report.faces_skipped, 0u);
  const TopologyStats t = compute_topology_stats(out.view());
  EXPECT_TRUE(t.closed_manifold);
  EXPECT_TRUE(t.consistently_oriented);
  EXPECT_EQ(t.euler_characteristic, 2);
  EXPECT_EQ(t.isolated_vertices, 0u);
  // Close to the sphere: every vertex stays near radius 1.
  const DistanceReport d = surface_distance(sphere.view(), out.view(), 20000, 5);
  EXPECT_LT(d.hausdorff, 0.05);
  // Deterministic.
  const MeshBuffers again = decimate_quadric(sphere.view(), 300);
  EXPECT_EQ(again.positions, out.positions);
  EXPECT_EQ(again.triangles, out.triangles);
}

TEST(QemDecimate, TorusKeepsItsGenusWithOrWithoutTheFlipGuard) {
  const MeshBuffers torus = make_torus(60, 30);
  for (bool guard : {true, false}) {
    const MeshBuffers out = decimate_quadric(torus.view(), 400, nullptr, guard);
    EXPECT_EQ(out.vertex_count(), 400u) << guard;
    const TopologyStats t = compute_topology_stats(out.view());
    EXPECT_TRUE(t.closed_manifold) << guard;
    EXPECT_EQ(t.euler_characteristic, 0) << guard;
  }
}

TEST(QemDecimate, DefectsAreSkippedAndUnreferencedVerticesDropped) {
  MeshBuffers m = make_icosphere(2);  // 162 vertices, 320 faces
  const uint32_t v = m.vertex_count();
  m.positions.insert(m.positions.end(), {9, 9, 9, 8, 8, 8});  // two unreferenced vertices
  m.triangles.insert(m.triangles.end(), {0, 0, 1});           // repeated index
  m.triangles.insert(m.triangles.end(), {m.triangles[0], m.triangles[1], m.triangles[2]});  // duplicate
  QemReport report;
  const MeshBuffers out = decimate_quadric(m.view(), 100, &report);
  EXPECT_EQ(report.input_vertices, v);
  EXPECT_EQ(report.faces_skipped, 2u);
  EXPECT_EQ(out.vertex_count(), 100u);
  EXPECT_EQ(compute_topology_stats(out.view()).isolated_vertices, 0u);
  // A target above the vertex count changes nothing but the compaction.
  const MeshBuffers same = decimate_quadric(m.view(), 100000, &report);
  EXPECT_EQ(same.vertex_count(), v);
  EXPECT_EQ(same.face_count(), 320u);
  EXPECT_EQ(report.collapses, 0u);
}

TEST(QemDecimate, BadIndexThrows) {
  MeshBuffers m = make_icosphere(1);
  m.triangles[7] = 5000;
  EXPECT_THROW(decimate_quadric(m.view(), 10), InputError);
}

}  // namespace
}  // namespace streamcvd
