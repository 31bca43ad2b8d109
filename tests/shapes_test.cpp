// Tests for core/measure/shapes.h (suite Shapes): the procedural surfaces are closed, oriented outward,
// of the stated genus and size, and enclose the analytic volume.
#include "streamcvd/core/measure/shapes.h"

#include <gtest/gtest.h>

#include <cmath>

#include "streamcvd/core/measure/mesh_stats.h"

namespace streamcvd {
namespace {

// Signed volume by the divergence theorem: positive for outward-oriented closed meshes.
double signed_volume(const MeshBuffers& m) {
  double v = 0;
  for (size_t f = 0; f < m.triangles.size(); f += 3) {
    const float* a = &m.positions[3 * size_t(m.triangles[f])];
    const float* b = &m.positions[3 * size_t(m.triangles[f + 1])];
    const float* c = &m.positions[3 * size_t(m.triangles[f + 2])];
    v += (double(a[0]) * (double(b[1]) * c[2] - double(b[2]) * c[1]) - double(a[1]) * (double(b[0]) * c[2] - double(b[2]) * c[0]) +
          double(a[2]) * (double(b[0]) * c[1] - double(b[1]) * c[0])) / 6;
  }
  return v;
}

void expect_closed_sphere_like(const MeshBuffers& m, double volume, double tolerance) {
  const TopologyStats t = compute_topology_stats(m.view());
  EXPECT_TRUE(t.closed_manifold);
  EXPECT_TRUE(t.consistently_oriented);
  EXPECT_EQ(t.genus, 0);
  EXPECT_EQ(t.degenerate_faces, 0u);
  EXPECT_EQ(t.isolated_vertices, 0u);
  EXPECT_NEAR(signed_volume(m), volume, tolerance * volume);
}

TEST(Shapes, EllipsoidIsAClosedOutwardScaledIcosphere) {
  const MeshBuffers m = make_ellipsoid(4, 3.0f, 1.0f, 0.5f);
  EXPECT_EQ(m.vertex_count(), 10u * 256 + 2);
  expect_closed_sphere_like(m, 4.0 / 3 * M_PI * 3 * 1 * 0.5, 0.01);
  // A mirror (negative axis) keeps the orientation outward.
  expect_closed_sphere_like(make_ellipsoid(3, -2.0f, 1.0f, 1.0f), 4.0 / 3 * M_PI * 2, 0.02);
}

TEST(Shapes, CapsuleIsAClosedOutwardCylinderWithCaps) {
  for (int segments : {3, 8, 64}) {
    SCOPED_TRACE(segments);
    const MeshBuffers m = make_capsule(segments, 0.5f, 3.0f);
    // V = rows·segments + 2 poles; every vertex at distance r from the axis segment.
    EXPECT_EQ((m.vertex_count() - 2) % uint32_t(segments), 0u);
    for (uint32_t v = 0; v < m.vertex_count(); ++v) {
      const float* p = &m.positions[3 * size_t(v)];
      const double dz = std::abs(p[2]) > 1.5 ? std::abs(p[2]) - 1.5 : 0.0;
      EXPECT_NEAR(std::sqrt(double(p[0]) * p[0] + double(p[1]) * p[1] + dz * dz), 0.5, 1e-5);
    }
    const double volume = M_PI * 0.25 * 3.0 + 4.0 / 3 * M_PI * 0.125;
    const TopologyStats t = compute_topology_stats(m.view());
    EXPECT_TRUE(t.closed_manifold);
    EXPECT_TRUE(t.consistently_oriented);
    EXPECT_EQ(t.genus, 0);
    EXPECT_GT(signed_volume(m), 0.0);
    if (segments == 64) {
      EXPECT_NEAR(signed_volume(m), volume, 0.01 * volume);
    }
  }
}

}  // namespace
}  // namespace streamcvd
