// Holes below the output resolution closing in the dual (core/dual/hole_closing.h): a slit is
// closed by a triangulation of its ring of clusters, the same faces in build_dual_mesh and in
// the labels-only strip topology; a loop around all of a thin piece is not a hole and keeps its
// strip.
#include "streamcvd/core/dual/hole_closing.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <set>
#include <vector>

#include "streamcvd/core/dual/dual_mesh.h"
#include "streamcvd/core/dual/dual_topology.h"
#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/store/store.h"

namespace streamcvd {
namespace {

constexpr int kCells = 40, kSide = kCells + 1, kBlock = 5;  // grid vertices per side, cluster block

// The unit grid of kCells² cells without the cells of row 19 from column 10 to 29: a slit 20
// cells long and one cell wide, between the clusters of block rows 3 and 4.
MeshBuffers slit_grid() {
  const MeshBuffers grid = make_grid(kSide, kSide);
  MeshBuffers slit = grid;
  slit.triangles.clear();
  for (int j = 0; j < kCells; ++j)
    for (int i = 0; i < kCells; ++i) {
      if (j == 19 && i >= 10 && i < 30) continue;
      const size_t f = 2 * size_t(j * kCells + i);
      slit.triangles.insert(slit.triangles.end(), grid.triangles.begin() + 3 * f, grid.triangles.begin() + 3 * f + 6);
    }
  return slit;
}

// Clusters of kBlock × kBlock vertices (vertex id j·kSide + i in the unrenumbered store).
std::vector<int32_t> block_labels(uint32_t vertices, int side, int blocks_per_row) {
  std::vector<int32_t> labels(vertices);
  for (uint32_t v = 0; v < vertices; ++v) labels[v] = int32_t((int(v) / side) / kBlock * blocks_per_row + (int(v) % side) / kBlock);
  return labels;
}

std::vector<double> centroids(const MeshView& m, const std::vector<int32_t>& labels, uint32_t K) {
  std::vector<double> z(3 * size_t(K), 0.0), count(K, 0.0);
  for (uint32_t v = 0; v < labels.size(); ++v) {
    for (int c = 0; c < 3; ++c) z[3 * size_t(labels[v]) + c] += m.positions[3 * size_t(v) + c];
    count[labels[v]] += 1;
  }
  for (uint32_t k = 0; k < K; ++k)
    for (int c = 0; c < 3; ++c) z[3 * size_t(k) + c] /= std::max(1.0, count[k]);
  return z;
}

MeshStore unrenumbered(const MeshBuffers& m) {
  return MeshStore::build(m.view(), StoreBuildOptions{.hilbert_order = false});
}

TEST(HoleClosing, LoopWidthIsTheExtentAcrossTheMainDirection) {
  // A 10 × 1 rectangle loop, tilted in space: width 1; a 3 × 3 square: 3.
  std::vector<float> P;
  std::vector<uint32_t> loop;
  const float corners[4][2] = {{0, 0}, {10, 0}, {10, 1}, {0, 1}};
  for (int k = 0; k < 4; ++k) {
    const float x = corners[k][0], y = corners[k][1];
    P.insert(P.end(), {0.6f * x, 0.8f * x, y});
    loop.push_back(uint32_t(k));
  }
  EXPECT_NEAR(dual::loop_width(P, loop), 1.0, 1e-5);
  EXPECT_FALSE(dual::diameter_below(P, loop, 10.0));
  EXPECT_TRUE(dual::diameter_below(P, loop, 10.1));
  for (float& x : P) x *= 0.3f;
  std::vector<float> square = {0, 0, 0, 3, 0, 0, 3, 3, 0, 0, 3, 0};
  EXPECT_NEAR(dual::loop_width(square, loop), 3.0, 1e-5);
}

TEST(HoleClosing, ASlitClosesByATriangulationOfItsRing) {
  const MeshBuffers input = slit_grid();
  const MeshStore store = unrenumbered(input);
  const MeshView m = store.view();
  ASSERT_EQ(compute_topology_stats(input.view()).boundary_loops, 2u);
  const int blocks = kSide / kBlock + 1;
  const uint32_t K = uint32_t(blocks * blocks);
  const std::vector<int32_t> labels = block_labels(m.vertex_count(), kSide, blocks);
  const std::vector<double> z = centroids(m, labels, K);
  const double cell = 1.0 / kCells, h = kBlock * cell;
  DualMeshOptions wide{.close_hole_diameter = 2 * h, .strip_spacing = h};
  DualMeshOptions slits = wide;
  slits.close_hole_width = 0.5 * h;

  // Without the width rule the slit (4 h long) keeps a strip; with it, it closes, adding no vertex.
  const DualMesh kept = build_dual_mesh(m, labels, K, z, wide);
  EXPECT_EQ(kept.holes_closed, 0u);
  EXPECT_EQ(compute_topology_stats(kept.mesh.view()).boundary_loops, 2u);
  const DualMesh closed = build_dual_mesh(m, labels, K, z, slits);
  EXPECT_EQ(closed.holes_closed, 1u);
  const TopologyStats t = compute_topology_stats(closed.mesh.view());
  EXPECT_EQ(t.boundary_loops, 1u);
  EXPECT_EQ(t.components, 1u);
  EXPECT_EQ(t.euler_characteristic, 1);
  EXPECT_EQ(t.nonmanifold_edges, 0u);
  EXPECT_EQ(t.nonmanifold_vertices, 0u);
  EXPECT_EQ(t.duplicate_faces, 0u);
  // (The outer strip has flat corner triangles on this exactly straight boundary, 28 either way:
  // the pipeline's flat-face pass takes them; the closing adds none.)
  EXPECT_EQ(t.degenerate_faces, compute_topology_stats(kept.mesh.view()).degenerate_faces);
  EXPECT_TRUE(t.consistently_oriented);
  EXPECT_LT(closed.boundary_vertices_added, kept.boundary_vertices_added);
  // The closing triangles join the clusters on either side of the slit: no strip corner there.
  uint32_t across = 0;
  for (size_t f = 0; f < closed.mesh.face_count(); ++f) {
    int below = 0, above = 0;
    for (int k = 0; k < 3; ++k) {
      const int32_t c = closed.cluster_of_output_vertex[closed.mesh.triangles[3 * f + k]];
      below += c >= 0 && c / blocks == 3 && c % blocks >= 2 && c % blocks <= 5;
      above += c >= 0 && c / blocks == 4 && c % blocks >= 2 && c % blocks <= 5;
    }
    across += below > 0 && above > 0 && below + above == 3;
  }
  EXPECT_GE(across, 6u);

  // The labels-only topology the repair checks has the same closing faces (ids = clusters here).
  std::vector<uint32_t> sizes(K, 0);
  for (int32_t c : labels) ++sizes[c];
  uint32_t strip_vertices = 0;
  const auto strip_faces =
      boundary_strip_faces(m, find_boundary_loops(m), labels, K, sizes, slits, strip_vertices);
  EXPECT_EQ(uint64_t(strip_vertices), closed.boundary_vertices_added);
  std::set<dual::Face> built;
  for (size_t f = 0; f < closed.mesh.face_count(); ++f) {
    const uint32_t* t3 = &closed.mesh.triangles[3 * f];
    built.insert(dual::rotate_smallest_first(t3[0], t3[1], t3[2]));
  }
  uint32_t cluster_faces = 0;
  for (const dual::Face& f : strip_faces) {
    if (f[0] >= K || f[1] >= K || f[2] >= K) continue;  // strip vertices are numbered differently
    ++cluster_faces;
    EXPECT_TRUE(built.count(f)) << f[0] << " " << f[1] << " " << f[2];
  }
  EXPECT_GE(cluster_faces, 8u);  // a ring of 10 clusters: 8 triangles
}

TEST(HoleClosing, AClusterMeetingASlitTwiceKeepsItOpenAndIsNamed) {
  // The slit's ring has distinct clusters: it closes and names none. Give one cluster above the
  // slit to the one below it: that cluster meets the slit on both sides, the ring cannot close
  // (the disc would pinch it), the slit keeps its strip, and the cluster is the one the repair
  // is told to split (core/dual/repair.cpp).
  const MeshStore store = unrenumbered(slit_grid());
  const MeshView m = store.view();
  const int blocks = kSide / kBlock + 1;
  const uint32_t K = uint32_t(blocks * blocks);
  std::vector<int32_t> labels = block_labels(m.vertex_count(), kSide, blocks);
  const double h = kBlock * (1.0 / kCells);
  const DualMeshOptions slits{.close_hole_diameter = 2 * h, .close_hole_width = 0.5 * h, .strip_spacing = h};
  auto open_clusters = [&](uint32_t& strip_vertices) {
    std::vector<uint32_t> sizes(K, 0);
    for (int32_t c : labels) ++sizes[c];
    std::vector<OpenHole> open;
    boundary_strip_faces(m, find_boundary_loops(m), labels, K, sizes, slits, strip_vertices, &open);
    dual::sort_unique(open);
    std::vector<int32_t> clusters;
    for (const OpenHole& h : open) clusters.push_back(h.cluster);
    return clusters;
  };
  uint32_t closed_strips = 0, open_strips = 0;
  EXPECT_TRUE(open_clusters(closed_strips).empty());
  const int32_t below = 3 * blocks + 3, above = 4 * blocks + 3;
  for (int32_t& c : labels)
    if (c == above) c = below;
  EXPECT_EQ(open_clusters(open_strips), std::vector<int32_t>{below});
  EXPECT_GT(open_strips, closed_strips);  // the slit's strip
}

TEST(HoleClosing, ADiagonalOfAHoleClosedBeforeIsBarred) {
  // The slit's ring of 10 clusters, triangulated once freely and once with one of its
  // diagonals taken by an earlier hole: two holes closed with the same diagonal would give
  // that dual edge four faces (dragon → 1000: two holes side by side, 8 repair rounds).
  const MeshStore store = unrenumbered(slit_grid());
  const MeshView m = store.view();
  const int blocks = kSide / kBlock + 1;
  const std::vector<int32_t> labels = block_labels(m.vertex_count(), kSide, blocks);
  const BoundaryLoops loops = find_boundary_loops(m);
  std::vector<uint32_t> inner;  // the slit's loop: the one off the grid's border
  for (size_t l = 0; l + 1 < loops.offsets.size() && inner.empty(); ++l) {
    std::span<const uint32_t> loop(loops.vertices.data() + loops.offsets[l], loops.offsets[l + 1] - loops.offsets[l]);
    const float* p = &m.positions[3 * size_t(loop[0])];
    if (p[0] > 0 && p[0] < 1 && p[1] > 0 && p[1] < 1) inner.assign(loop.begin(), loop.end());
  }
  ASSERT_FALSE(inner.empty());
  std::vector<uint32_t> changes;
  std::vector<int32_t> ring;
  for (uint32_t k = 0; k < inner.size(); ++k) {
    const int32_t a = labels[inner[k]], b = labels[inner[(k + 1) % inner.size()]];
    if (a != b) changes.push_back(k), ring.push_back(b);
  }
  ASSERT_EQ(ring.size(), 10u);
  auto diagonals = [&](const std::vector<std::array<uint32_t, 3>>& triangles) {
    std::set<uint64_t> out;
    for (const auto& t : triangles)
      for (int k = 0; k < 3; ++k) {
        const auto i = std::find(ring.begin(), ring.end(), int32_t(t[k])) - ring.begin();
        const auto j = std::find(ring.begin(), ring.end(), int32_t(t[(k + 1) % 3])) - ring.begin();
        const auto gap = std::abs(i - j);
        if (gap != 1 && gap != int(ring.size()) - 1) out.insert(dual::cluster_pair_key(t[k], t[(k + 1) % 3]));
      }
    return out;
  };
  const auto free = dual::triangulate_hole_ring(m, inner, changes, ring, labels);
  ASSERT_EQ(free.size(), 8u);
  const std::set<uint64_t> used = diagonals(free);
  ASSERT_EQ(used.size(), 7u);
  const std::vector<uint64_t> taken = {*used.begin()};
  const auto barred = dual::triangulate_hole_ring(m, inner, changes, ring, labels, taken);
  ASSERT_EQ(barred.size(), 8u) << "the ring has other triangulations";
  EXPECT_FALSE(diagonals(barred).count(taken[0]));
}

TEST(HoleClosing, ALoopAroundAllOfAThinPieceIsNoHole) {
  // A ribbon 40 cells long and 2 wide, clusters in two rows (the bottom vertex row; the two
  // others): each cluster meets the one loop in one stretch, so the ring is simple and narrower
  // than the closing width. But every cluster lies on it, and those across the ribbon are
  // neighbours: closing it would fold the ribbon onto itself. It keeps its strip.
  const MeshBuffers ribbon = make_grid(kSide, 3, 1.0f, 2.0f / kCells);
  const MeshStore store = unrenumbered(ribbon);
  const MeshView m = store.view();
  const int blocks = kSide / kBlock + 1;
  std::vector<int32_t> labels(m.vertex_count());
  for (uint32_t v = 0; v < labels.size(); ++v) labels[v] = int32_t((int(v) % kSide) / kBlock + (int(v) / kSide > 0 ? blocks : 0));
  const uint32_t K = uint32_t(2 * blocks);
  const std::vector<double> z = centroids(m, labels, K);
  const double h = kBlock * 1.0 / kCells;
  const DualMeshOptions o{.close_hole_diameter = 2 * h, .close_hole_width = h, .strip_spacing = h};
  const BoundaryLoops loops = find_boundary_loops(m);
  ASSERT_EQ(loops.offsets.size(), 2u);
  std::vector<uint32_t> changes;
  std::vector<int32_t> ring;
  for (uint32_t k = 0; k < loops.vertices.size(); ++k) {
    const int32_t a = labels[loops.vertices[k]], b = labels[loops.vertices[(k + 1) % loops.vertices.size()]];
    if (a != b) changes.push_back(k), ring.push_back(b);
  }
  std::vector<int32_t> distinct = ring;
  std::sort(distinct.begin(), distinct.end());
  ASSERT_EQ(std::unique(distinct.begin(), distinct.end()), distinct.end()) << "the ring should be simple";
  EXPECT_TRUE(dual::triangulate_hole_ring(m, loops.vertices, changes, ring, labels).empty());
  const DualMesh d = build_dual_mesh(m, labels, K, z, o);
  EXPECT_EQ(d.holes_closed, 0u);
  EXPECT_GT(d.boundary_vertices_added, 0u);
  const TopologyStats t = compute_topology_stats(d.mesh.view());
  EXPECT_EQ(t.boundary_loops, 1u);
  EXPECT_EQ(t.nonmanifold_edges + t.nonmanifold_vertices, 0u);
}

}  // namespace
}  // namespace streamcvd
