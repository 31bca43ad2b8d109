// compute_topology_stats / compute_quality: hand-built meshes with exact counts, procedural
// shapes, and the MANIFEST figures of the bundled and shared test meshes.
#include "streamcvd/core/measure/mesh_stats.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <numeric>
#include <random>
#include <sstream>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

MeshBuffers soup(std::vector<float> positions, std::vector<uint32_t> triangles) {
  MeshBuffers m;
  m.positions = std::move(positions);
  m.triangles = std::move(triangles);
  return m;
}

TopologyStats topo(const MeshBuffers& m) { return compute_topology_stats(m.view()); }

// Regular tetrahedron, outward oriented.
MeshBuffers tetrahedron() {
  return soup({1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1}, {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3});
}

// nx × ny grid of unit cells with cells (i, j) in `holes` left out.
MeshBuffers grid_with_holes(int nx, int ny, const std::vector<std::pair<int, int>>& holes) {
  MeshBuffers g = make_grid(nx + 1, ny + 1, float(nx), float(ny));
  MeshBuffers m;
  m.positions = g.positions;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      if (std::find(holes.begin(), holes.end(), std::make_pair(i, j)) != holes.end()) continue;
      const size_t cell = size_t(j * nx + i) * 6;
      m.triangles.insert(m.triangles.end(), g.triangles.begin() + long(cell), g.triangles.begin() + long(cell + 6));
    }
  return m;
}

TEST(MeshStats, SingleTriangle) {
  const TopologyStats s = topo(soup({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2}));
  EXPECT_EQ(s.vertices, 3u);
  EXPECT_EQ(s.faces, 1u);
  EXPECT_EQ(s.edges, 3u);
  EXPECT_EQ(s.boundary_edges, 3u);
  EXPECT_EQ(s.boundary_loops, 1u);
  EXPECT_EQ(s.nonmanifold_edges, 0u);
  EXPECT_EQ(s.nonmanifold_vertices, 0u);
  EXPECT_EQ(s.components, 1u);
  EXPECT_EQ(s.euler_characteristic, 1);
  EXPECT_FALSE(s.closed_manifold);
  EXPECT_TRUE(s.consistently_oriented);
  EXPECT_EQ(s.genus, -1);
  EXPECT_EQ(s.bbox_max[0], 1.0f);
  EXPECT_EQ(s.bbox_min[2], 0.0f);
}

TEST(MeshStats, TwoTrianglesSharingAnEdge) {
  const TopologyStats s = topo(soup({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}, {0, 1, 2, 0, 2, 3}));
  EXPECT_EQ(s.edges, 5u);
  EXPECT_EQ(s.boundary_edges, 4u);
  EXPECT_EQ(s.boundary_loops, 1u);
  EXPECT_EQ(s.components, 1u);
  EXPECT_EQ(s.nonmanifold_vertices, 0u);
  EXPECT_EQ(s.euler_characteristic, 1);
  EXPECT_TRUE(s.consistently_oriented);
}

TEST(MeshStats, TetrahedronIsClosedGenusZero) {
  const TopologyStats s = topo(tetrahedron());
  EXPECT_EQ(s.edges, 6u);
  EXPECT_EQ(s.boundary_edges, 0u);
  EXPECT_EQ(s.boundary_loops, 0u);
  EXPECT_EQ(s.euler_characteristic, 2);
  EXPECT_TRUE(s.closed_manifold);
  EXPECT_TRUE(s.consistently_oriented);
  EXPECT_EQ(s.genus, 0);
  EXPECT_EQ(s.degenerate_faces, 0u);
}

TEST(MeshStats, FlippedFaceIsNotConsistentlyOriented) {
  MeshBuffers m = tetrahedron();
  std::swap(m.triangles[0], m.triangles[1]);
  const TopologyStats s = topo(m);
  EXPECT_FALSE(s.consistently_oriented);
  EXPECT_TRUE(s.closed_manifold);
  EXPECT_EQ(s.genus, 0);
}

TEST(MeshStats, OpenBowtieHasOneNonManifoldVertexAndOneLoop) {
  const TopologyStats s = topo(soup({0, 0, 0, 1, 0, 0, 1, 1, 0, -1, 0, 0, -1, -1, 0}, {0, 1, 2, 0, 3, 4}));
  EXPECT_EQ(s.nonmanifold_vertices, 1u);
  EXPECT_EQ(s.nonmanifold_edges, 0u);
  EXPECT_EQ(s.boundary_edges, 6u);
  EXPECT_EQ(s.boundary_loops, 1u);
  EXPECT_EQ(s.components, 1u);  // joined through the shared vertex
  EXPECT_FALSE(s.closed_manifold);
}

TEST(MeshStats, TwoTetrahedraTouchingAtAVertexAreNotManifold) {
  // Both fans around the shared vertex are closed cycles: only fan connectivity can tell.
  MeshBuffers a = tetrahedron(), m = tetrahedron();
  for (size_t i = 0; i < a.positions.size(); ++i) m.positions.push_back(a.positions[i] + (i % 3 == 0 ? 2.0f : 0.0f));
  for (uint32_t v : a.triangles) m.triangles.push_back(v == 0 ? 0 : v + 4);  // share vertex 0
  const TopologyStats s = topo(m);
  EXPECT_EQ(s.boundary_edges, 0u);
  EXPECT_EQ(s.nonmanifold_edges, 0u);
  EXPECT_EQ(s.nonmanifold_vertices, 1u);
  EXPECT_EQ(s.isolated_vertices, 1u);  // the second copy of vertex 0
  EXPECT_EQ(s.components, 1u);
  EXPECT_FALSE(s.closed_manifold);
  EXPECT_TRUE(s.consistently_oriented);
  EXPECT_EQ(s.genus, -1);
}

TEST(MeshStats, ThreeFacesOnOneEdge) {
  const TopologyStats s =
      topo(soup({0, 0, 0, 1, 0, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1}, {0, 1, 2, 1, 0, 3, 0, 1, 4}));
  EXPECT_EQ(s.nonmanifold_edges, 1u);
  EXPECT_EQ(s.nonmanifold_vertices, 2u);
  EXPECT_EQ(s.boundary_edges, 6u);
  EXPECT_EQ(s.edges, 7u);
  EXPECT_EQ(s.components, 1u);
}

TEST(MeshStats, DuplicateFacesIgnoreCornerOrder) {
  const TopologyStats s =
      topo(soup({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0}, {0, 1, 2, 2, 0, 1, 2, 1, 0, 1, 3, 2}));
  EXPECT_EQ(s.duplicate_faces, 2u);
  EXPECT_EQ(s.faces, 4u);
  EXPECT_EQ(s.nonmanifold_edges, 3u);  // 0–1 and 0–2 by three faces, 1–2 by all four
}

TEST(MeshStats, DuplicateFacesWithRepeatedIndices) {
  // Sets {0,1} twice, {2} once, and the proper face {0,1,2} (not a duplicate of {0,1}).
  const TopologyStats s = topo(soup({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 0, 1, 1, 0, 1, 2, 2, 2, 0, 1, 2}));
  EXPECT_EQ(s.duplicate_faces, 1u);
  EXPECT_EQ(s.degenerate_faces, 3u);
  EXPECT_EQ(s.edges, 3u);  // self-loops are not edges
}

TEST(MeshStats, UnreferencedVertex) {
  const TopologyStats s = topo(soup({0, 0, 0, 1, 0, 0, 0, 1, 0, 5, 5, 5}, {0, 1, 2}));
  EXPECT_EQ(s.isolated_vertices, 1u);
  EXPECT_EQ(s.components, 1u);
  EXPECT_EQ(s.euler_characteristic, 1);  // over referenced vertices only
  EXPECT_EQ(s.bbox_max[1], 5.0f);        // the box covers every stored vertex
}

TEST(MeshStats, DegenerateFaces) {
  // A repeated index, an exactly collinear face and a proper one.
  const TopologyStats s = topo(soup({0, 0, 0, 1, 0, 0, 2, 0, 0, 0, 1, 0}, {0, 0, 1, 0, 1, 2, 0, 1, 3}));
  EXPECT_EQ(s.degenerate_faces, 2u);
  EXPECT_EQ(s.duplicate_faces, 0u);
}

TEST(MeshStats, TwoHolesTouchingAtAVertexAreOneLoop) {
  // 4×4 cells, holes at cells (1,1) and (2,2): they share grid vertex (2,2).
  const TopologyStats s = topo(grid_with_holes(4, 4, {{1, 1}, {2, 2}}));
  EXPECT_EQ(s.boundary_edges, 16u + 8u);
  EXPECT_EQ(s.boundary_loops, 2u);  // outer rim + the touching pair
  EXPECT_EQ(s.nonmanifold_vertices, 1u);
  EXPECT_EQ(s.nonmanifold_edges, 0u);
  EXPECT_EQ(s.components, 1u);
  // Apart, the same holes make three loops.
  EXPECT_EQ(topo(grid_with_holes(5, 5, {{1, 1}, {3, 3}})).boundary_loops, 3u);
}

TEST(MeshStats, ComponentsConnectThroughVerticesOnly) {
  MeshBuffers m = soup({0, 0, 0, 1, 0, 0, 0, 1, 0, 5, 0, 0, 6, 0, 0, 5, 1, 0}, {0, 1, 2, 3, 4, 5});
  EXPECT_EQ(topo(m).components, 2u);
  EXPECT_EQ(topo(m).boundary_loops, 2u);
}

TEST(MeshStats, EmptyMesh) {
  const TopologyStats s = topo(soup({0, 0, 0}, {}));
  EXPECT_EQ(s.faces, 0u);
  EXPECT_EQ(s.isolated_vertices, 1u);
  EXPECT_EQ(s.components, 0u);
  EXPECT_FALSE(s.closed_manifold);
  const QualityStats q = compute_quality(soup({0, 0, 0}, {}).view());
  EXPECT_EQ(q.triangles, 0u);
  EXPECT_EQ(q.q_histogram.size(), 20u);
}

TEST(MeshStats, RejectsOutOfRangeIndices) {
  const MeshBuffers m = soup({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2, 0, 3, 1});
  EXPECT_THROW(compute_topology_stats(m.view()), InputError);
  EXPECT_THROW(compute_quality(m.view()), InputError);
  try {
    compute_topology_stats(m.view());
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("face 1 uses vertex 3 of 3"), std::string::npos) << e.what();
  }
}

TEST(MeshStats, IcosphereIsClosedOrientedGenusZero) {
  const MeshBuffers m = make_icosphere(3);
  const TopologyStats s = topo(m);
  EXPECT_EQ(s.vertices, 642u);
  EXPECT_EQ(s.edges, 1920u);
  EXPECT_EQ(s.euler_characteristic, 2);
  EXPECT_TRUE(s.closed_manifold);
  EXPECT_TRUE(s.consistently_oriented);
  EXPECT_EQ(s.genus, 0);
  EXPECT_EQ(s.components, 1u);
  EXPECT_EQ(s.nonmanifold_vertices, 0u);
  const QualityStats q = compute_quality(m.view());
  EXPECT_NEAR(q.percent_valence6, 100.0 * 630.0 / 642.0, 1e-9);  // 12 valence-5 vertices
  EXPECT_GT(q.q_min, 0.8);
  EXPECT_LE(q.q_avg, 1.0);
}

TEST(MeshStats, TorusHasGenusOne) {
  const MeshBuffers m = make_torus(16, 24);
  const TopologyStats s = topo(m);
  EXPECT_EQ(s.euler_characteristic, 0);
  EXPECT_EQ(s.genus, 1);
  EXPECT_TRUE(s.closed_manifold);
  EXPECT_TRUE(s.consistently_oriented);
  EXPECT_DOUBLE_EQ(compute_quality(m.view()).percent_valence6, 100.0);
}

TEST(MeshStats, BoundaryFacesApart) {
  // 7 × 5 vertices, 48 right-isosceles faces; those with a rim corner are the boundary ones.
  const MeshBuffers m = make_grid(7, 5, 6.0f, 4.0f);
  const QualityStats q = compute_quality(m.view());
  // A face is off the boundary when its three corners are interior vertices (x in 1..5, y in 1..3).
  uint64_t off = 0;
  for (size_t f = 0; f < m.triangles.size(); f += 3) {
    bool inner = true;
    for (int k = 0; k < 3; ++k) {
      const float x = m.positions[3 * size_t(m.triangles[f + k])], y = m.positions[3 * size_t(m.triangles[f + k]) + 1];
      inner = inner && x > 0.5f && x < 5.5f && y > 0.5f && y < 3.5f;
    }
    off += inner;
  }
  EXPECT_EQ(q.boundary_triangles, q.triangles - off);
  EXPECT_NEAR(q.q_avg_boundary, q.q_avg, 1e-9);  // all faces alike
  EXPECT_NEAR(q.q_avg_off_boundary, q.q_avg, 1e-9);
  EXPECT_NEAR(q.q_min_boundary, q.q_min, 1e-9);
  const QualityStats closed = compute_quality(make_icosphere(2).view());
  EXPECT_EQ(closed.boundary_triangles, 0u);
  EXPECT_EQ(closed.q_avg_boundary, 0.0);
  EXPECT_NEAR(closed.q_avg_off_boundary, closed.q_avg, 1e-12);
}

TEST(MeshStats, FiguresTogetherEqualTheTwoCalls) {
  // A grid with holes, a bowtie, a repeated face: every figure of both structs must agree.
  MeshBuffers m = grid_with_holes(9, 7, {{2, 2}, {5, 3}});
  const uint32_t base = m.vertex_count();
  for (float x : {10.f, 0.f, 0.f, 11.f, 0.f, 0.f, 10.f, 1.f, 0.f, 9.f, -1.f, 0.f, 9.f, 0.f, 0.f})
    m.positions.push_back(x);
  m.triangles.insert(m.triangles.end(), {base, base + 1, base + 2, base, base + 3, base + 4, base, base + 1, base + 2});
  const MeshFigures both = compute_mesh_figures(m.view());
  const TopologyStats t = compute_topology_stats(m.view());
  const QualityStats q = compute_quality(m.view());
  EXPECT_EQ(both.topology.boundary_loops, t.boundary_loops);
  EXPECT_EQ(both.topology.components, t.components);
  EXPECT_EQ(both.topology.nonmanifold_vertices, t.nonmanifold_vertices);
  EXPECT_GT(t.nonmanifold_vertices, 0u) << "the bowtie";
  EXPECT_EQ(both.topology.duplicate_faces, t.duplicate_faces);
  EXPECT_EQ(t.duplicate_faces, 1u);
  EXPECT_EQ(both.topology.euler_characteristic, t.euler_characteristic);
  EXPECT_EQ(both.topology.edges, t.edges);
  EXPECT_EQ(both.quality.q_avg, q.q_avg);
  EXPECT_EQ(both.quality.q_avg_boundary, q.q_avg_boundary);
  EXPECT_EQ(both.quality.boundary_triangles, q.boundary_triangles);
  EXPECT_EQ(both.quality.percent_valence6, q.percent_valence6);
  EXPECT_EQ(both.quality.edge_length_cv, q.edge_length_cv);
  EXPECT_EQ(both.quality.q_histogram, q.q_histogram);
}

TEST(MeshStats, GridBoundaryAndQuality) {
  const int nx = 7, ny = 5;  // unit cells: sizes nx − 1, ny − 1
  const MeshBuffers m = make_grid(nx, ny, float(nx - 1), float(ny - 1));
  const TopologyStats s = topo(m);
  EXPECT_EQ(s.boundary_edges, uint64_t(2 * (nx - 1) + 2 * (ny - 1)));
  EXPECT_EQ(s.boundary_loops, 1u);
  EXPECT_EQ(s.euler_characteristic, 1);
  EXPECT_EQ(s.genus, -1);
  const QualityStats q = compute_quality(m.view());
  EXPECT_DOUBLE_EQ(q.percent_valence6, 100.0);
  // Every triangle is right isosceles; 58 unit edges and 24 diagonals.
  const double qr = std::sqrt(3.0) * (std::sqrt(2.0) - 1.0);
  EXPECT_NEAR(q.q_min, qr, 1e-6);
  EXPECT_NEAR(q.q_avg, qr, 1e-6);
  const double mean = (58.0 + 24.0 * std::sqrt(2.0)) / 82.0;
  const double var = (58.0 * (1 - mean) * (1 - mean) + 24.0 * (std::sqrt(2.0) - mean) * (std::sqrt(2.0) - mean)) / 82.0;
  EXPECT_NEAR(q.edge_length_mean, mean, 1e-6);
  EXPECT_NEAR(q.edge_length_cv, std::sqrt(var) / mean, 1e-6);
}

TEST(MeshStats, EquilateralTriangleQuality) {
  const float h = float(std::sqrt(3.0) / 2.0);
  const QualityStats q = compute_quality(soup({0, 0, 0, 1, 0, 0, 0.5f, h, 0}, {0, 1, 2}).view());
  EXPECT_EQ(q.triangles, 1u);
  EXPECT_NEAR(q.q_min, 1.0, 1e-6);
  EXPECT_NEAR(q.min_angle_min, 60.0, 1e-4);
  EXPECT_NEAR(q.max_angle_max, 60.0, 1e-4);
  EXPECT_EQ(q.percent_angles_below_30, 0.0);
  EXPECT_EQ(q.q_histogram[19], 1u);
  EXPECT_EQ(q.min_angle_histogram.size(), 12u);
  EXPECT_EQ(q.min_angle_histogram[11], 1u);  // [55°, 60°], closed at 60°
  EXPECT_EQ(q.percent_valence6, 0.0);  // no interior vertex
}

TEST(MeshStats, RightIsoscelesTriangleQuality) {
  const QualityStats q = compute_quality(soup({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2}).view());
  const double expected = std::sqrt(3.0) * (std::sqrt(2.0) - 1.0);  // 0.7174
  EXPECT_NEAR(q.q_min, expected, 1e-12);
  EXPECT_NEAR(q.min_angle_min, 45.0, 1e-12);
  EXPECT_NEAR(q.min_angle_avg, 45.0, 1e-12);
  EXPECT_NEAR(q.max_angle_max, 90.0, 1e-12);
  EXPECT_EQ(q.q_histogram[14], 1u);
  EXPECT_EQ(q.min_angle_histogram[9], 1u);
  EXPECT_NEAR(q.edge_length_mean, (2.0 + std::sqrt(2.0)) / 3.0, 1e-12);
}

TEST(MeshStats, SkinnyAndDegenerateTriangleQuality) {
  // A 12° sliver (angles 12°, 84°, 84°) and a collinear triangle.
  const double t = std::tan(84.0 * M_PI / 180.0) / 2.0;
  const QualityStats q =
      compute_quality(soup({0, 0, 0, 1, 0, 0, 0.5f, float(t), 0, 3, 0, 0, 4, 0, 0, 5, 0, 0}, {0, 1, 2, 3, 4, 5}).view());
  EXPECT_EQ(q.triangles, 2u);
  EXPECT_EQ(q.q_min, 0.0);
  EXPECT_NEAR(q.min_angle_min, 0.0, 1e-12);
  EXPECT_NEAR(q.min_angle_avg, 6.0, 1e-3);
  EXPECT_NEAR(q.max_angle_max, 180.0, 1e-12);
  EXPECT_NEAR(q.percent_angles_below_30, 100.0 * 3.0 / 6.0, 1e-9);
  EXPECT_NEAR(q.percent_triangles_below_30, 100.0, 1e-9);
  EXPECT_EQ(q.q_histogram[0], 1u);
  EXPECT_EQ(q.min_angle_histogram[0], 1u);
  EXPECT_EQ(q.min_angle_histogram[2], 1u);
}

TEST(MeshStats, InvariantUnderFaceOrderAndCornerRotation) {
  MeshBuffers m = grid_with_holes(6, 6, {{1, 1}, {2, 2}, {4, 1}});
  m.triangles.insert(m.triangles.end(), {1, 8, 0});  // repeats face (0,1,8): 0–8 and 1–8 get 3 faces
  const TopologyStats a = topo(m);
  std::mt19937 rng(7);
  std::vector<size_t> order(m.face_count());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), rng);
  MeshBuffers p;
  p.positions = m.positions;
  for (size_t f : order) {
    const size_t r = rng() % 3;
    for (size_t k = 0; k < 3; ++k) p.triangles.push_back(m.triangles[3 * f + (k + r) % 3]);
  }
  const TopologyStats b = topo(p);
  EXPECT_EQ(a.boundary_edges, b.boundary_edges);
  EXPECT_EQ(a.boundary_loops, b.boundary_loops);
  EXPECT_EQ(a.nonmanifold_edges, b.nonmanifold_edges);
  EXPECT_EQ(a.nonmanifold_vertices, b.nonmanifold_vertices);
  EXPECT_EQ(a.duplicate_faces, 1u);
  EXPECT_EQ(b.duplicate_faces, 1u);
  EXPECT_EQ(a.nonmanifold_edges, 2u);
  EXPECT_EQ(a.boundary_loops, 3u);
}

// ---- MANIFEST figures -------------------------------------------------------------------------

struct Expected {
  std::string file;
  uint64_t vertices, faces, boundary_edges, boundary_loops, nonmanifold_edges, duplicate_faces, components,
      unreferenced_vertices;
};

void expect_manifest(const std::string& path, const Expected& e) {
  SCOPED_TRACE(path);
  const MeshBuffers m = read_mesh(path);
  const TopologyStats s = compute_topology_stats(m.view());
  EXPECT_EQ(s.vertices, e.vertices);
  EXPECT_EQ(s.faces, e.faces);
  EXPECT_EQ(s.boundary_edges, e.boundary_edges);
  EXPECT_EQ(s.boundary_loops, e.boundary_loops);
  EXPECT_EQ(s.nonmanifold_edges, e.nonmanifold_edges);
  EXPECT_EQ(s.duplicate_faces, e.duplicate_faces);
  EXPECT_EQ(s.components, e.components);
  EXPECT_EQ(s.isolated_vertices, e.unreferenced_vertices);
}

TEST(MeshStats, BundledMeshesMatchManifest) {
  // Copied from shared/data/MANIFEST.tsv so the suite runs without ../shared.
  const std::vector<Expected> rows = {
      {"beetle_nonmanifold.obj", 1148, 2053, 296, 23, 47, 0, 2, 0},
      {"bun_zipper_res2.ply", 8171, 16301, 123, 5, 150, 87, 1, 25},
      {"cgal_elephant.off", 2775, 5558, 0, 0, 0, 0, 1, 0},
      {"cgal_elephant_with_holes.off", 2798, 4463, 1353, 106, 0, 0, 1, 0},
      {"cgal_fandisk.off.zst", 6475, 12946, 0, 0, 0, 0, 1, 0},
      {"cgal_hand.off", 1197, 2390, 0, 0, 0, 0, 1, 0},
      {"fertility.off.zst", 4494, 9000, 0, 0, 0, 0, 1, 0},
  };
  for (const Expected& e : rows) expect_manifest(test::data_path(e.file), e);
}

TEST(MeshStats, SharedMeshesMatchManifest) {
  const auto manifest = test::shared_data_path("MANIFEST.tsv");
  if (!manifest) GTEST_SKIP() << "../shared/data absent";
  std::ifstream in(*manifest);
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  auto split = [](const std::string& s) {
    std::vector<std::string> cols;
    std::stringstream ss(s);
    for (std::string c; std::getline(ss, c, '\t');) cols.push_back(c);
    return cols;
  };
  std::map<std::string, size_t> col;
  const auto header = split(line);
  for (size_t i = 0; i < header.size(); ++i) col[header[i]] = i;
  for (const char* name : {"file", "vertices", "faces", "boundary_edges", "boundary_loops", "nonmanifold_edges",
                           "duplicate_faces", "components", "unreferenced_vertices"})
    ASSERT_TRUE(col.count(name)) << "MANIFEST.tsv lacks column " << name;
  int rows = 0;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    const auto c = split(line);
    ASSERT_GT(c.size(), col["unreferenced_vertices"]) << line;
    auto n = [&](const char* name) { return std::stoull(c[col[name]]); };
    const Expected e{c[col["file"]],    n("vertices"),          n("faces"),           n("boundary_edges"),
                     n("boundary_loops"), n("nonmanifold_edges"), n("duplicate_faces"), n("components"),
                     n("unreferenced_vertices")};
    const auto path = test::shared_data_path(e.file);
    if (!path) continue;
    expect_manifest(*path, e);
    ++rows;
  }
  EXPECT_GT(rows, 0);
  RecordProperty("meshes_checked", rows);
}

}  // namespace
}  // namespace streamcvd
