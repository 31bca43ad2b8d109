// Tests of the quality post-pass (core/dual/mesh_optimize.h): flips between coplanar triangles only,
// never a duplicate edge or a fold, fixed vertices stay, moved vertices land on the surface,
// and on remeshed closed shapes the topology (closed manifold, genus) is kept while Qav rises.
#include "streamcvd/core/dual/mesh_optimize.h"
#include "streamcvd/core/dual/placement.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/mesh/vertex_faces.h"
#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/remesh.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

MeshOptimizeReport optimize_free(MeshBuffers& m, const MeshOptimizeOptions& o = {}) {
  std::vector<uint8_t> movable(m.vertex_count(), 1);
  return optimize_mesh_quality(m.positions, m.triangles, movable, nullptr, {}, o);
}

// Two triangles sharing the long diagonal of a rhombus: flipping to the short one makes both
// triangles better. Bent by `lift` out of the plane at the far corners.
MeshBuffers rhombus(float lift) {
  MeshBuffers m;
  m.positions = {-2, 0, 0, 2, 0, 0, 0, 1, lift, 0, -1, lift};
  m.triangles = {0, 1, 2, 1, 0, 3};  // shared edge 0-1 (the long diagonal)
  return m;
}

TEST(MeshOptimize, FlipsTheLongDiagonalOfAFlatRhombus) {
  MeshBuffers m = rhombus(0);
  MeshOptimizeOptions o;
  o.relax_iterations = 0;
  const MeshOptimizeReport r = optimize_free(m, o);
  EXPECT_EQ(r.flips, 1u);
  EXPECT_GT(r.q_avg_after, r.q_avg_before);
  EXPECT_NEAR(r.q_avg_after, average_triangle_quality(m.positions, m.triangles), 1e-9);
  // The diagonal is now 2-3, both faces keep the +z orientation.
  const TopologyStats t = compute_topology_stats(m.view());
  EXPECT_TRUE(t.consistently_oriented);
  EXPECT_EQ(t.boundary_edges, 4u);
  for (size_t f = 0; f < 2; ++f) {
    const uint32_t* tri = &m.triangles[3 * f];
    const float* a = &m.positions[3 * tri[0]];
    const float* b = &m.positions[3 * tri[1]];
    const float* c = &m.positions[3 * tri[2]];
    const float nz = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
    EXPECT_GT(nz, 0) << "face " << f << " turned over";
  }
}

// Two flat rhombi side by side (disjoint): only the one with a vertex flagged near is flipped.
TEST(MeshOptimize, FlipsNearFlaggedVerticesOnly) {
  MeshBuffers m = rhombus(0);
  const MeshBuffers far = rhombus(0);
  for (size_t i = 0; i < far.positions.size(); ++i) m.positions.push_back(far.positions[i] + (i % 3 == 0 ? 10.0f : 0.0f));
  for (uint32_t v : far.triangles) m.triangles.push_back(v + 4);
  std::vector<uint8_t> near(m.vertex_count(), 0);
  near[0] = 1;  // an end of the first rhombus's long diagonal 0-1
  const std::vector<uint32_t> before = m.triangles;
  EXPECT_EQ(flip_edges_near(m.positions, m.triangles, near), 1u);
  EXPECT_NE(std::vector<uint32_t>(m.triangles.begin(), m.triangles.begin() + 6),
            std::vector<uint32_t>(before.begin(), before.begin() + 6));
  EXPECT_EQ(std::vector<uint32_t>(m.triangles.begin() + 6, m.triangles.end()),
            std::vector<uint32_t>(before.begin() + 6, before.end()));  // the far one is left
  std::fill(near.begin(), near.end(), 1);
  EXPECT_EQ(flip_edges_near(m.positions, m.triangles, near), 1u);  // now the far one
  EXPECT_THROW(flip_edges_near(m.positions, m.triangles, std::vector<uint8_t>(3, 1)), InputError);
  m.triangles[0] = m.vertex_count();  // out of range
  EXPECT_THROW(flip_edges_near(m.positions, m.triangles, near), InputError);
}

TEST(MeshOptimize, NoFlipAcrossABend) {
  // Lifting the far corners by 0.5 bends the pair by ~53°: far above the 10° limit.
  MeshBuffers m = rhombus(0.5f);
  const std::vector<uint32_t> before = m.triangles;
  MeshOptimizeOptions o;
  o.relax_iterations = 0;
  EXPECT_EQ(optimize_free(m, o).flips, 0u);
  EXPECT_EQ(m.triangles, before);
  o.flip_max_dihedral_deg = 60;  // allowed when the limit is raised
  EXPECT_EQ(optimize_free(m, o).flips, 1u);
}

TEST(MeshOptimize, NeverCreatesAnExistingEdge) {
  // In a tetrahedron every flip would duplicate the opposite edge: even with no bend limit
  // none may happen, and the surface stays a closed manifold.
  MeshBuffers m;
  m.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  m.triangles = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  MeshOptimizeOptions o;
  o.flip_max_dihedral_deg = 180;
  const MeshOptimizeReport r = optimize_free(m, o);
  EXPECT_EQ(r.flips, 0u);
  EXPECT_EQ(r.moves, 0u);  // closed, but every edge bends by more than the feature angle
  const TopologyStats t = compute_topology_stats(m.view());
  EXPECT_TRUE(t.closed_manifold);
  EXPECT_EQ(t.duplicate_faces, 0u);
}

TEST(MeshOptimize, RejectsMismatchedArrays) {
  MeshBuffers m = rhombus(0);
  std::vector<uint8_t> too_short(2, 1);
  EXPECT_THROW(optimize_mesh_quality(m.positions, m.triangles, too_short, nullptr, {}), InputError);
  std::vector<uint8_t> movable(m.vertex_count(), 1);
  m.triangles[5] = 9;
  EXPECT_THROW(optimize_mesh_quality(m.positions, m.triangles, movable, nullptr, {}), InputError);
}

TEST(MeshOptimize, TwoFansThroughOneVertexStay) {
  // Two flat hexagonal fans, in the planes z = 0 and x = 0, sharing their off-centre vertex 0
  // (a non-manifold vertex left by a failed repair): both fans would pull it to the origin,
  // but it is not moved, and the fans are not merged by a flip.
  MeshBuffers m;
  m.positions = {0, 0.2f, 0};
  for (int fan = 0; fan < 2; ++fan)
    for (int k = 0; k < 6; ++k) {
      const float a = float(k) * 3.14159265f / 3;
      if (fan == 0) m.positions.insert(m.positions.end(), {std::cos(a), std::sin(a), 0});
      else m.positions.insert(m.positions.end(), {0, std::cos(a), std::sin(a)});
    }
  for (uint32_t fan = 0; fan < 2; ++fan)
    for (uint32_t k = 0; k < 6; ++k) m.triangles.insert(m.triangles.end(), {0, 1 + 6 * fan + k, 1 + 6 * fan + (k + 1) % 6});
  std::vector<uint8_t> movable(m.vertex_count(), 1);
  const std::vector<float> before = m.positions;
  optimize_mesh_quality(m.positions, m.triangles, movable, nullptr, {});
  for (int k = 0; k < 3; ++k) EXPECT_EQ(m.positions[k], before[k]);
  const TopologyStats t = compute_topology_stats(m.view());
  EXPECT_EQ(t.duplicate_faces, 0u);
  EXPECT_EQ(t.nonmanifold_edges, 0u);
  EXPECT_EQ(t.faces, 12u);
}

// A flat grid with its interior vertices jittered: planar, so every flip and move is allowed.
MeshBuffers jittered_grid() {
  MeshBuffers m = make_grid(12, 12);
  uint32_t seed = 12345;
  auto rnd = [&] {
    seed = seed * 1664525u + 1013904223u;
    return float(seed >> 8) / float(1u << 24) - 0.5f;
  };
  for (int y = 1; y < 11; ++y)
    for (int x = 1; x < 11; ++x) {
      m.positions[3 * size_t(y * 12 + x)] += 0.05f * rnd();
      m.positions[3 * size_t(y * 12 + x) + 1] += 0.05f * rnd();
    }
  return m;
}

TEST(MeshOptimize, FlatGridImprovesAndKeepsItsBoundaryAndFixedVertices) {
  MeshBuffers m = jittered_grid();
  const MeshBuffers before = m;
  std::vector<uint8_t> movable(m.vertex_count(), 1);
  movable[5 * 12 + 5] = 0;  // an interior vertex the caller pins
  const MeshOptimizeReport r = optimize_mesh_quality(m.positions, m.triangles, movable, nullptr, {});
  std::printf("[ grid     ] Qav %.4f -> %.4f, %llu flips, %llu moves\n", r.q_avg_before, r.q_avg_after,
              (unsigned long long)r.flips, (unsigned long long)r.moves);
  EXPECT_GT(r.q_avg_after, r.q_avg_before + 0.01);
  EXPECT_GT(r.moves, 0u);
  EXPECT_EQ(m.face_count(), before.face_count());
  for (uint32_t v = 0; v < m.vertex_count(); ++v) {
    const int x = int(v % 12), y = int(v / 12);
    const bool fixed = x == 0 || y == 0 || x == 11 || y == 11 || v == 5 * 12 + 5;
    EXPECT_FLOAT_EQ(m.positions[3 * size_t(v) + 2], 0.0f);  // tangent plane of a plane
    if (fixed) {
      for (int k = 0; k < 3; ++k) EXPECT_EQ(m.positions[3 * size_t(v) + k], before.positions[3 * size_t(v) + k]) << v;
    }
  }
  const TopologyStats t0 = compute_topology_stats(before.view()), t1 = compute_topology_stats(m.view());
  EXPECT_EQ(t1.boundary_edges, t0.boundary_edges);
  EXPECT_EQ(t1.euler_characteristic, t0.euler_characteristic);
  EXPECT_TRUE(t1.consistently_oriented);
  EXPECT_EQ(t1.nonmanifold_edges + t1.nonmanifold_vertices + t1.duplicate_faces + t1.degenerate_faces, 0u);
  // Deterministic.
  MeshBuffers again = before;
  optimize_mesh_quality(again.positions, again.triangles, movable, nullptr, {});
  EXPECT_EQ(again.positions, m.positions);
  EXPECT_EQ(again.triangles, m.triangles);
}

// The colour classes the Gauss-Seidel passes run in parallel: every active vertex in exactly one
// class, in the given order within it, and no two vertices of a class on one face.
TEST(MeshOptimize, ColourClassesPutNoTwoVerticesOfAFaceTogether) {
  const MeshBuffers m = make_icosphere(3);
  std::vector<uint32_t> offsets, faces, order, begin;
  build_vertex_faces(m.triangles, m.vertex_count(), offsets, faces);
  for (uint32_t v = m.vertex_count(); v-- > 0;) order.push_back(v);  // any order the caller likes
  std::vector<uint8_t> active(m.vertex_count(), 1);
  for (uint32_t v = 0; v < m.vertex_count(); v += 7) active[v] = 0;
  const std::vector<uint32_t> classes = colour_classes(m.triangles, offsets, faces, order, active, begin);
  ASSERT_EQ(begin.size(), kSerialColour + 2);
  std::vector<int> class_of(m.vertex_count(), -1);
  uint32_t used = 0;
  for (uint32_t k = 0; k <= kSerialColour; ++k) {
    used += begin[k + 1] > begin[k];
    for (uint32_t i = begin[k]; i < begin[k + 1]; ++i) {
      EXPECT_EQ(class_of[classes[i]], -1) << "vertex in two classes";
      class_of[classes[i]] = int(k);
      if (i > begin[k]) {
        EXPECT_GT(classes[i - 1], classes[i]) << "not in the order given";
      }
    }
  }
  for (uint32_t v = 0; v < m.vertex_count(); ++v) EXPECT_EQ(class_of[v] >= 0, active[v] != 0) << v;
  EXPECT_EQ(begin[kSerialColour + 1] - begin[kSerialColour], 0u);  // valence 5-6: no vertex alone
  EXPECT_GE(used, 3u);   // a triangle needs three
  EXPECT_LE(used, 8u);   // greedy on valence <= 6
  for (uint32_t f = 0; f < m.face_count(); ++f)
    for (int a = 0; a < 3; ++a)
      for (int b = a + 1; b < 3; ++b) {
        const uint32_t u = m.triangles[3 * f + a], w = m.triangles[3 * f + b];
        if (class_of[u] >= 0 && class_of[w] >= 0) {
          EXPECT_NE(class_of[u], class_of[w]) << "face " << f;
        }
      }
}

// The relaxation runs its colour classes in parallel: the same result for any thread count.
TEST(MeshOptimize, SameResultForAnyThreadCount) {
  MeshBuffers input = make_icosphere(5);  // 10,242 vertices: several tasks per class
  uint32_t seed = 7;
  for (float& x : input.positions) {
    seed = seed * 1664525u + 1013904223u;
    x += 0.002f * (float(seed >> 8) / float(1u << 24) - 0.5f);
  }
  std::vector<float> first_positions;
  std::vector<uint32_t> first_triangles;
  for (int threads : {1, 2, 4}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
    MeshBuffers m = input;
    const MeshOptimizeReport r = optimize_free(m);
    EXPECT_GT(r.moves, 1000u);
    if (first_positions.empty()) {
      first_positions = m.positions, first_triangles = m.triangles;
      EXPECT_NE(first_positions, input.positions);
    } else {
      EXPECT_EQ(m.positions, first_positions) << threads << " threads";
      EXPECT_EQ(m.triangles, first_triangles) << threads << " threads";
    }
  }
}

TEST(MeshOptimize, MovedVerticesLandOnTheSurface) {
  // Surface: a fine sphere. Mesh to optimize: a coarse sphere with its vertices moved along the
  // surface (rotated a little, per vertex), so its triangles are uneven.
  MeshStore fine = MeshStore::build(make_icosphere(5).view());
  const MeshView surface = fine.view();
  MeshBuffers m = make_icosphere(2);
  for (uint32_t v = 0; v < m.vertex_count(); ++v) {
    float* p = &m.positions[3 * size_t(v)];
    const float a = 0.08f * std::sin(7.0f * float(v));
    const float x = p[0] * std::cos(a) - p[1] * std::sin(a), y = p[0] * std::sin(a) + p[1] * std::cos(a);
    p[0] = x, p[1] = y;
  }
  // Start faces: any face of the fine sphere's vertex nearest to each vertex.
  std::vector<int32_t> labels(surface.vertex_count());
  std::vector<int32_t> cluster_of_output(m.vertex_count());
  for (uint32_t v = 0; v < m.vertex_count(); ++v) cluster_of_output[v] = int32_t(v);
  for (uint32_t u = 0; u < labels.size(); ++u) {
    const float* q = &surface.positions[3 * size_t(u)];
    double best = 1e30;
    for (uint32_t v = 0; v < m.vertex_count(); ++v) {
      const float* p = &m.positions[3 * size_t(v)];
      const double d = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]);
      if (d < best) best = d, labels[u] = int32_t(v);
    }
  }
  std::vector<uint32_t> anchors = cluster_anchor_faces(surface, labels, cluster_of_output, m.positions);
  for (uint32_t a : anchors) ASSERT_NE(a, UINT32_MAX);
  std::vector<uint8_t> movable(m.vertex_count(), 1);
  MeshOptimizeOptions o;
  o.feature_angle_deg = 60;  // a level-2 icosphere bends ~15° per edge
  const MeshOptimizeReport r = optimize_mesh_quality(m.positions, m.triangles, movable, &surface, anchors, o);
  std::printf("[ sphere   ] Qav %.4f -> %.4f, %llu flips, %llu moves\n", r.q_avg_before, r.q_avg_after,
              (unsigned long long)r.flips, (unsigned long long)r.moves);
  EXPECT_GT(r.moves, 0u);
  EXPECT_GT(r.q_avg_after, r.q_avg_before);
  for (uint32_t v = 0; v < m.vertex_count(); ++v) {
    const float* p = &m.positions[3 * size_t(v)];
    const double radius = std::sqrt(double(p[0]) * p[0] + double(p[1]) * p[1] + double(p[2]) * p[2]);
    EXPECT_GT(radius, 0.999);  // the fine sphere's faces lie within ~3e-4 inside the unit sphere
    EXPECT_LT(radius, 1.0 + 1e-5);
  }
  EXPECT_TRUE(compute_topology_stats(m.view()).closed_manifold);
}

// Closed inputs through remesh(): the pass keeps the output closed, manifold, oriented, with
// the input's genus and N vertices, and raises Qav.
void check_closed(const std::string& name, const MeshBuffers& input, int64_t genus, uint32_t n, Metric metric) {
  SCOPED_TRACE(name + " N=" + std::to_string(n) + " " + metric_name(metric));
  MeshStore store = MeshStore::build(input.view());
  RemeshOptions o;
  o.vertices = n;
  o.clustering.metric = metric;
  o.clustering.loops.threads = 1;
  o.optimize_quality = false;
  const RemeshResult off = remesh(store.view(), o);
  o.optimize_quality = true;
  const RemeshResult on = remesh(store.view(), o);
  const QualityStats q_off = compute_quality(off.mesh.view()), q_on = compute_quality(on.mesh.view());
  std::printf("[ closed   ] %-9s N=%-5u %-2s Qav %.4f -> %.4f (%llu flips, %llu moves)\n", name.c_str(), n,
              metric_name(metric), q_off.q_avg, q_on.q_avg, (unsigned long long)on.quality.flips(),
              (unsigned long long)on.quality.interior.moves);
  EXPECT_GT(q_on.q_avg, q_off.q_avg);
  EXPECT_GT(on.quality.interior.moves, 0u);
  const TopologyStats t = compute_topology_stats(on.mesh.view());
  EXPECT_TRUE(t.closed_manifold);
  EXPECT_TRUE(t.consistently_oriented);
  EXPECT_EQ(t.genus, genus);
  EXPECT_EQ(t.components, 1u);
  EXPECT_EQ(t.nonmanifold_edges + t.nonmanifold_vertices + t.duplicate_faces + t.degenerate_faces + t.isolated_vertices, 0u);
  EXPECT_EQ(on.mesh.vertex_count(), n);
  EXPECT_EQ(on.mesh.face_count(), off.mesh.face_count());
  EXPECT_FALSE(on.checks.topology_changed);
}

TEST(MeshOptimize, ClosedShapesKeepTopologyAndGainQuality) {
  const MeshBuffers fertility = read_mesh(test::data_path("fertility.off.zst"));
  for (Metric m : {Metric::I, Metric::IQ}) {
    check_closed("sphere", make_icosphere(5), 0, 1000, m);
    check_closed("torus", make_torus(160, 64), 1, 1500, m);
    check_closed("fertility", fertility, 4, 2000, m);
  }
}

}  // namespace
}  // namespace streamcvd
