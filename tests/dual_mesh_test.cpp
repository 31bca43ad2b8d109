// Tests of core/dual/dual_mesh.h: the dual of hand-built clusterings (§VI-C), boundary strips
// (§VI-D), the manifold-defect finder and the last-resort defect removal.
#include "streamcvd/core/dual/dual_mesh.h"
#include "streamcvd/core/dual/dual_topology.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numeric>
#include <set>
#include <string>
#include <vector>

#include "streamcvd/core/clustering/clustering.h"
#include "streamcvd/core/clustering/item_data.h"
#include "streamcvd/core/dual/placement.h"
#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

// A store in input vertex order (no Hilbert renumbering) so hand-built labels can use input ids.
struct Stored {
  MeshStore store;
  MeshView view;
  explicit Stored(const MeshBuffers& soup)
      : store(MeshStore::build(soup.view(), StoreBuildOptions{.faces_per_chunk = uint64_t(1) << 20, .hilbert_order = false})),
        view(store.view()) {
    auto ids = store.original_vertex_ids();
    for (uint32_t v = 0; v < ids.size(); ++v) EXPECT_EQ(ids[v], v) << "store reordered vertices";
  }
};

// Centroid of each cluster's vertex positions (3 doubles per cluster).
std::vector<double> vertex_centroids(const MeshView& mesh, const std::vector<int32_t>& labels, uint32_t K) {
  std::vector<double> z(3 * size_t(K), 0.0);
  std::vector<uint32_t> n(K, 0);
  for (uint32_t v = 0; v < mesh.vertex_count(); ++v) {
    if (labels[v] < 0) continue;
    ++n[labels[v]];
    for (int k = 0; k < 3; ++k) z[3 * labels[v] + k] += mesh.positions[3 * v + k];
  }
  for (uint32_t c = 0; c < K; ++c)
    for (int k = 0; k < 3; ++k) z[3 * c + k] /= std::max(n[c], 1u);
  return z;
}

// Signed area of output face f projected on the xy plane (positive = counter-clockwise = +z).
double signed_area_xy(const MeshBuffers& m, size_t f) {
  const float* a = &m.positions[3 * size_t(m.triangles[3 * f])];
  const float* b = &m.positions[3 * size_t(m.triangles[3 * f + 1])];
  const float* c = &m.positions[3 * size_t(m.triangles[3 * f + 2])];
  return 0.5 * ((double(b[0]) - a[0]) * (double(c[1]) - a[1]) - (double(b[1]) - a[1]) * (double(c[0]) - a[0]));
}

// Grid index (i, j) of a make_grid vertex on [0,1]² with n vertices per side.
int grid_i(const MeshView& m, uint32_t v, int n) { return int(std::lround(m.positions[3 * v] * float(n - 1))); }
int grid_j(const MeshView& m, uint32_t v, int n) { return int(std::lround(m.positions[3 * v + 1] * float(n - 1))); }

// Number of input boundary edges (used by one face) whose two ends lie in different clusters:
// the cluster changes met walking the boundary loops.
uint64_t boundary_changes(const MeshView& m, const std::vector<int32_t>& labels) {
  std::map<std::pair<uint32_t, uint32_t>, int> uses;
  for (uint64_t f = 0; f < m.face_count(); ++f)
    for (int k = 0; k < 3; ++k) ++uses[std::minmax(m.triangles[3 * f + k], m.triangles[3 * f + (k + 1) % 3])];
  uint64_t n = 0;
  for (auto& [e, count] : uses)
    if (count == 1 && labels[e.first] != labels[e.second]) ++n;
  return n;
}

// Every output vertex has a source; a strip vertex's sources lie where it does (the mean of their
// positions), so data interpolated from them matches its position. Returns the source counts.
std::multiset<uint32_t> expect_sources_locate_strip_vertices(const MeshView& input, const DualMesh& d) {
  std::multiset<uint32_t> counts;
  EXPECT_EQ(d.source_of_output_vertex.size(), d.mesh.vertex_count());
  for (uint32_t o = 0; o < d.source_of_output_vertex.size(); ++o) {
    const VertexSource s = d.source_of_output_vertex[o];
    EXPECT_EQ(s.count == 0, d.cluster_of_output_vertex[o] >= 0) << "vertex " << o;
    if (s.count == 0) continue;
    counts.insert(s.count);
    EXPECT_LE(size_t(s.begin) + s.count, d.source_vertices.size());
    for (int k = 0; k < 3; ++k) {
      double mean = 0;
      for (uint32_t i = 0; i < s.count; ++i) mean += input.positions[3 * size_t(d.source_vertices[s.begin + i]) + k];
      EXPECT_NEAR(mean / s.count, d.mesh.positions[3 * size_t(o) + k], 1e-6) << "vertex " << o;
    }
  }
  return counts;
}

// --- the dual of hand-built clusterings ----------------------------------------------------------

TEST(DualMesh, OneTrianglePerTriplePointWithInputOrientation) {
  // One input triangle, one cluster per corner: exactly one output triangle, same orientation.
  MeshBuffers tri;
  tri.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  tri.triangles = {0, 1, 2};
  Stored m(tri);
  std::vector<int32_t> labels = {2, 0, 1};
  for (bool strips : {false, true}) {
    SCOPED_TRACE(strips ? "strips" : "no strips");
    DualMesh d = build_dual_mesh(m.view, labels, 3, vertex_centroids(m.view, labels, 3), {.boundary_strips = strips});
    ASSERT_EQ(d.mesh.vertex_count(), 3u);
    ASSERT_EQ(d.mesh.face_count(), 1u);  // strips: clusters of one vertex along the loop add nothing
    EXPECT_EQ(d.boundary_vertices_added, 0u);
    EXPECT_GT(signed_area_xy(d.mesh, 0), 0.0) << "dual triangle flipped";
    EXPECT_EQ(d.cluster_of_output_vertex, (std::vector<int32_t>{0, 1, 2}));
  }
}

TEST(DualMesh, ThreeClustersOnAGridMeetAtOneTriplePoint) {
  // 7×7 grid: cluster 0 = left (i ≤ 2), 1 = bottom right, 2 = top right.
  const int n = 7;
  Stored m(make_grid(n, n));
  std::vector<int32_t> labels(m.view.vertex_count());
  for (uint32_t v = 0; v < labels.size(); ++v)
    labels[v] = grid_i(m.view, v, n) <= 2 ? 0 : (grid_j(m.view, v, n) <= 2 ? 1 : 2);
  const auto z = vertex_centroids(m.view, labels, 3);

  DualMesh d = build_dual_mesh(m.view, labels, 3, z, {.boundary_strips = false});
  ASSERT_EQ(d.mesh.vertex_count(), 3u);
  ASSERT_EQ(d.mesh.face_count(), 1u);
  EXPECT_GT(signed_area_xy(d.mesh, 0), 0.0);
  for (uint32_t c = 0; c < 3; ++c)
    for (int k = 0; k < 3; ++k) EXPECT_FLOAT_EQ(d.mesh.positions[3 * c + k], float(z[3 * c + k]));

  // With strips the output is a disc: the triple-point triangle, one triangle (p, b, a) per
  // cluster change along the boundary, and one chord triangle per strip vertex (one per change,
  // plus one per square corner the strip keeps).
  DualMesh s = build_dual_mesh(m.view, labels, 3, z);
  EXPECT_EQ(boundary_changes(m.view, labels), 3u);
  EXPECT_GE(s.boundary_vertices_added, 3u);
  EXPECT_LE(s.boundary_vertices_added, 3u + 4u);
  EXPECT_EQ(s.mesh.vertex_count(), 3u + s.boundary_vertices_added);
  EXPECT_EQ(s.mesh.face_count(), 1u + 3u + s.boundary_vertices_added);
  TopologyStats t = compute_topology_stats(s.mesh.view());
  EXPECT_EQ(t.nonmanifold_edges, 0u);
  EXPECT_EQ(t.nonmanifold_vertices, 0u);
  EXPECT_EQ(t.boundary_loops, 1u);
  EXPECT_EQ(t.euler_characteristic, 1);
  EXPECT_TRUE(t.consistently_oriented);
  EXPECT_EQ(t.degenerate_faces, 0u);
  // Every face, strips included, keeps the input orientation: corners are strip vertices, so no
  // strip triangle folds over a corner cluster's centroid.
  size_t interior = 0;
  for (size_t f = 0; f < s.mesh.face_count(); ++f) {
    EXPECT_GT(signed_area_xy(s.mesh, f), 0.0) << "face " << f;
    bool all_clusters = true;
    for (int k = 0; k < 3; ++k) all_clusters &= s.cluster_of_output_vertex[s.mesh.triangles[3 * f + k]] >= 0;
    interior += all_clusters;
  }
  EXPECT_EQ(interior, 1u);
  EXPECT_EQ(uint64_t(std::count(s.cluster_of_output_vertex.begin(), s.cluster_of_output_vertex.end(), -1)),
            s.boundary_vertices_added);
  EXPECT_TRUE(find_manifold_defects(s.mesh.view()).empty());
  // Three edge midpoints (two sources each), the rest corner copies (one).
  const std::multiset<uint32_t> counts = expect_sources_locate_strip_vertices(m.view, s);
  EXPECT_EQ(counts.count(2), 3u);
  EXPECT_EQ(counts.count(1), s.boundary_vertices_added - 3);
}

TEST(DualMesh, AClosedHoleCentreLiesAtTheMeanOfItsLoop) {
  // 8×8 grid without its central cell: a square hole whose four corners lie in four quadrant
  // clusters. Narrower than the closing diameter, the hole closes by a fan from its centroid.
  const int n = 8;
  MeshBuffers grid = make_grid(n, n);
  MeshBuffers holed = grid;
  holed.triangles.clear();
  for (size_t f = 0; f < grid.face_count(); ++f) {
    double cx = 0, cy = 0;
    for (int k = 0; k < 3; ++k) {
      cx += grid.positions[3 * size_t(grid.triangles[3 * f + k])] / 3.0;
      cy += grid.positions[3 * size_t(grid.triangles[3 * f + k]) + 1] / 3.0;
    }
    if (std::abs(cx - 0.5) < 0.0625 && std::abs(cy - 0.5) < 0.0625) continue;
    holed.triangles.insert(holed.triangles.end(), grid.triangles.begin() + 3 * f, grid.triangles.begin() + 3 * f + 3);
  }
  ASSERT_EQ(holed.face_count() + 2, grid.face_count());
  Stored m(holed);
  std::vector<int32_t> labels(m.view.vertex_count());
  for (uint32_t v = 0; v < labels.size(); ++v)
    labels[v] = (grid_i(m.view, v, n) <= 3 ? 0 : 1) + (grid_j(m.view, v, n) <= 3 ? 0 : 2);
  DualMesh d = build_dual_mesh(m.view, labels, 4, vertex_centroids(m.view, labels, 4), {.close_hole_diameter = 0.5});
  EXPECT_EQ(d.holes_closed, 1u);
  EXPECT_EQ(expect_sources_locate_strip_vertices(m.view, d).count(4), 1u) << "no centroid of the 4-vertex hole";
}

TEST(DualMesh, DuplicateFacesAreRemoved) {
  // Two separate input triangles with the same three clusters in the same order: one output face.
  MeshBuffers two;
  two.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 3, 0, 0, 4, 0, 0, 3, 1, 0};
  two.triangles = {0, 1, 2, 3, 4, 5};
  Stored m(two);
  std::vector<int32_t> labels = {0, 1, 2, 0, 1, 2};
  DualMesh d = build_dual_mesh(m.view, labels, 3, vertex_centroids(m.view, labels, 3), {.boundary_strips = false});
  EXPECT_EQ(d.mesh.face_count(), 1u);
  EXPECT_EQ(d.duplicate_faces_removed, 1u);
  // The same triangles with opposite cluster orders are different faces (a fold, not a duplicate):
  // the defect finder reports it.
  std::vector<int32_t> folded = {0, 1, 2, 0, 2, 1};
  DualMesh f = build_dual_mesh(m.view, folded, 3, vertex_centroids(m.view, folded, 3), {.boundary_strips = false});
  EXPECT_EQ(f.mesh.face_count(), 2u);
  EXPECT_EQ(f.duplicate_faces_removed, 0u);
  EXPECT_EQ(find_manifold_defects(f.mesh.view()).size(), 3u);
}

TEST(DualMesh, EmptyClustersAndFreeVerticesGiveNoOutput) {
  const int n = 6;
  Stored m(make_grid(n, n));
  std::vector<int32_t> labels(m.view.vertex_count());
  // Clusters 0, 2, 4 used; 1 and 3 empty; one corner vertex free (−1).
  for (uint32_t v = 0; v < labels.size(); ++v)
    labels[v] = grid_i(m.view, v, n) < 3 ? 0 : (grid_j(m.view, v, n) < 3 ? 2 : 4);
  labels[0] = -1;
  DualMesh d = build_dual_mesh(m.view, labels, 5, vertex_centroids(m.view, labels, 5), {.boundary_strips = false});
  EXPECT_EQ(d.cluster_of_output_vertex, (std::vector<int32_t>{0, 2, 4}));
  EXPECT_EQ(d.mesh.vertex_count(), 3u);
  for (uint32_t i : d.mesh.triangles) EXPECT_LT(i, 3u);
}

TEST(DualMesh, BoundaryStripVerticesFollowClusterChangesAlongTheBoundary) {
  // k vertical bands on a 25×25 grid: the boundary loop changes cluster 2(k − 1) times.
  const int n = 25;
  Stored m(make_grid(n, n));
  for (uint32_t k : {3u, 4u, 6u, 9u}) {
    SCOPED_TRACE("bands " + std::to_string(k));
    std::vector<int32_t> labels(m.view.vertex_count());
    for (uint32_t v = 0; v < labels.size(); ++v) labels[v] = int32_t(uint32_t(grid_i(m.view, v, n)) * k / n);
    const uint64_t changes = boundary_changes(m.view, labels);
    EXPECT_EQ(changes, 2u * (k - 1));
    DualMesh d = build_dual_mesh(m.view, labels, k, vertex_centroids(m.view, labels, k));
    // One strip vertex per change, plus the square's corners (at most 4) kept by the strip.
    EXPECT_GE(d.boundary_vertices_added, changes);
    EXPECT_LE(d.boundary_vertices_added, changes + 4);
    EXPECT_EQ(d.mesh.vertex_count(), k + d.boundary_vertices_added);
    // Bands have no triple point: strips only, one (p, b, a) per change + one chord per strip vertex.
    EXPECT_EQ(d.mesh.face_count(), changes + d.boundary_vertices_added);
    EXPECT_EQ(d.holes_closed, 0u);
    TopologyStats t = compute_topology_stats(d.mesh.view());
    EXPECT_EQ(t.nonmanifold_edges, 0u);
    EXPECT_EQ(t.nonmanifold_vertices, 0u);
    EXPECT_EQ(t.boundary_loops, 1u);
    EXPECT_EQ(t.euler_characteristic, 1) << "output is not a disc";
    EXPECT_TRUE(t.consistently_oriented);
    EXPECT_EQ(t.isolated_vertices, 0u);
    EXPECT_TRUE(find_manifold_defects(d.mesh.view()).empty());
    expect_sources_locate_strip_vertices(m.view, d);
  }
  // Two clusters around the boundary: the strip would fold, the loop is closed instead.
  std::vector<int32_t> halves(m.view.vertex_count());
  for (uint32_t v = 0; v < halves.size(); ++v) halves[v] = grid_i(m.view, v, n) < n / 2 ? 0 : 1;
  DualMesh h = build_dual_mesh(m.view, halves, 2, vertex_centroids(m.view, halves, 2));
  EXPECT_EQ(h.boundary_vertices_added, 0u);
  EXPECT_EQ(h.holes_closed, 1u);
  EXPECT_EQ(h.mesh.face_count(), 0u);
}

// Unit disc: a square grid on [−1,1]² mapped by (x√(1 − y²/2), y√(1 − x²/2)), which sends the
// square's border onto the circle (no boundary corner) and keeps the orientation (+z).
MeshBuffers make_disc(int n) {
  MeshBuffers m = make_grid(n, n, 2.0f, 2.0f);
  for (size_t i = 0; i < m.positions.size(); i += 3) {
    double x = m.positions[i] - 1.0, y = m.positions[i + 1] - 1.0;
    m.positions[i] = float(x * std::sqrt(1 - y * y / 2));
    m.positions[i + 1] = float(y * std::sqrt(1 - x * x / 2));
  }
  return m;
}

TEST(DualMesh, DiscSectorsAroundACentreGiveAFlatOrientedDisc) {
  // Eight sectors around a central cluster: 8 triple points (centre, s_i, s_i+1), 8 cluster
  // changes along the circle. Every output face must keep the input orientation (+z).
  Stored m(make_disc(41));
  const uint32_t sectors = 8, K = sectors + 1;
  std::vector<int32_t> labels(m.view.vertex_count());
  for (uint32_t v = 0; v < labels.size(); ++v) {
    double x = m.view.positions[3 * v], y = m.view.positions[3 * v + 1];
    double angle = std::atan2(y, x) + M_PI;  // [0, 2π]
    labels[v] = std::hypot(x, y) < 0.45 ? int32_t(sectors)
                                          : int32_t(std::min<uint32_t>(sectors - 1, uint32_t(angle / (2 * M_PI) * sectors)));
  }
  ASSERT_TRUE(clusters_connected(m.view, labels, K));
  DualMesh d = build_dual_mesh(m.view, labels, K, vertex_centroids(m.view, labels, K));
  EXPECT_EQ(boundary_changes(m.view, labels), sectors);
  EXPECT_EQ(d.boundary_vertices_added, sectors);
  EXPECT_EQ(d.mesh.vertex_count(), K + sectors);
  EXPECT_EQ(d.mesh.face_count(), 3u * sectors);
  TopologyStats t = compute_topology_stats(d.mesh.view());
  EXPECT_EQ(t.boundary_loops, 1u);
  EXPECT_EQ(t.euler_characteristic, 1);
  EXPECT_TRUE(t.consistently_oriented);
  EXPECT_EQ(t.nonmanifold_edges + t.nonmanifold_vertices + t.duplicate_faces + t.degenerate_faces, 0u);
  for (size_t f = 0; f < d.mesh.face_count(); ++f) EXPECT_GT(signed_area_xy(d.mesh, f), 0.0) << "face " << f << " folded";
  EXPECT_TRUE(find_manifold_defects(d.mesh.view()).empty());
}

// A converged metric-I clustering of a uniform sphere (icosphere level 4, K = 120, seed 17) and
// its clusters' centroids, 3 doubles each.
struct SphereClustering {
  static constexpr uint32_t K = 120;
  MeshStore store = MeshStore::build(make_icosphere(4).view());
  MeshView view = store.view();
  std::vector<int32_t> labels;
  std::vector<double> centroids = std::vector<double>(3 * K);
  SphereClustering() {
    const ItemData items = compute_item_data(view);
    const ComponentBudget b = plan_component_budget(view, items, K, SmallComponents::Keep, ram_storage());
    labels = test::to_vector(initial_sampling(view, items, b, 17, ram_storage()));
    minimize_clustering(view, items, labels, K, test::metric_i_one_thread());
    const std::vector<ClusterSums> sums = accumulate_clusters(items, labels, K);
    for (uint32_t c = 0; c < K; ++c)
      for (int k = 0; k < 3; ++k) centroids[3 * c + k] = items.origin[k] + sums[c].sum[k] / sums[c].weight;
  }
};

TEST(DualMesh, ConvergedClusteringOfASphereGivesAClosedManifold) {
  // End to end without repair: the clustering of a uniform sphere should already dualise cleanly.
  const SphereClustering s;
  DualMesh d = build_dual_mesh(s.view, s.labels, s.K, s.centroids);
  EXPECT_EQ(d.mesh.vertex_count(), s.K);
  TopologyStats t = compute_topology_stats(d.mesh.view());
  EXPECT_TRUE(t.closed_manifold);
  EXPECT_TRUE(t.consistently_oriented);
  EXPECT_EQ(t.genus, 0);
  EXPECT_EQ(t.duplicate_faces, 0u);
  EXPECT_EQ(t.isolated_vertices, 0u);
  EXPECT_TRUE(find_manifold_defects(d.mesh.view()).empty());
}

// project_onto_clusters with a selection: the selected sites move exactly where the full
// projection puts them (onto the unit sphere, from inside it), the others stay.
TEST(DualMesh, ProjectionOfSelectedClustersMatchesTheFullOne) {
  const SphereClustering s;
  std::vector<double> all = s.centroids, some = s.centroids;
  project_onto_clusters(s.view, s.labels, all);
  std::vector<uint8_t> selected(s.K, 0);
  for (uint32_t c = 0; c < s.K; c += 3) selected[c] = 1;
  project_onto_clusters(s.view, s.labels, some, selected);
  for (uint32_t c = 0; c < s.K; ++c) {
    const double r = std::sqrt(all[3 * c] * all[3 * c] + all[3 * c + 1] * all[3 * c + 1] + all[3 * c + 2] * all[3 * c + 2]);
    EXPECT_NEAR(r, 1.0, 2e-3) << c;  // on the icosphere's faces
    for (int k = 0; k < 3; ++k)
      EXPECT_EQ(some[3 * c + k], selected[c] ? all[3 * c + k] : s.centroids[3 * c + k]) << c;
  }
}

// --- find_manifold_defects -----------------------------------------------------------------------

std::vector<uint32_t> defects_of(std::vector<float> positions, std::vector<uint32_t> triangles) {
  MeshBuffers m;
  m.positions = std::move(positions);
  m.triangles = std::move(triangles);
  return find_manifold_defects(m.view());
}

std::vector<float> points(int n) {
  std::vector<float> p;
  for (int i = 0; i < n; ++i) p.insert(p.end(), {float(i % 3), float(i / 3), float(i % 2)});
  return p;
}

using Ids = std::vector<uint32_t>;

TEST(ManifoldDefects, CleanMeshesHaveNone) {
  EXPECT_TRUE(defects_of(points(3), {0, 1, 2}).empty());                                 // one triangle
  EXPECT_TRUE(defects_of(points(4), {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3}).empty());      // tetrahedron
  EXPECT_TRUE(defects_of(points(4), {0, 1, 2, 0, 2, 3}).empty());                        // quad
  EXPECT_TRUE(find_manifold_defects(make_icosphere(2).view()).empty());
  EXPECT_TRUE(find_manifold_defects(make_torus(12, 8).view()).empty());
  EXPECT_TRUE(find_manifold_defects(make_grid(5, 4).view()).empty());
}

TEST(ManifoldDefects, FlagsBowtieVertex) {
  // Two triangles sharing only vertex 0.
  EXPECT_EQ(defects_of(points(5), {0, 1, 2, 0, 3, 4}), (Ids{0}));
  // Two closed fans (tetrahedra) glued at vertex 0.
  EXPECT_EQ(defects_of(points(7), {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3, 0, 5, 4, 0, 4, 6, 0, 6, 5, 4, 5, 6}), (Ids{0}));
}

TEST(ManifoldDefects, ClosedFansAroundAVertexAreListed) {
  // The faces at vertex 0 of two tetrahedra glued there: two closed fans, a ring's pinch.
  dual::FanScratch scratch;
  using Links = std::vector<std::vector<uint32_t>>;
  const std::vector<dual::Face> pinch = {{0, 2, 1}, {0, 5, 4}, {0, 1, 3}, {0, 4, 6}, {0, 3, 2}, {0, 6, 5}};
  EXPECT_EQ(dual::closed_fans(0, pinch, scratch), (Links{{1, 2, 3}, {4, 5, 6}}));
  const std::vector<dual::Face> one = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}};
  EXPECT_EQ(dual::closed_fans(0, one, scratch), (Links{{1, 2, 3}}));
  // An open fan (a boundary vertex) and an edge used twice one way are no closed fans.
  EXPECT_TRUE(dual::closed_fans(0, std::span(one).first(2), scratch).empty());
  const std::vector<dual::Face> flipped = {{0, 2, 1}, {0, 1, 3}, {0, 2, 3}};
  EXPECT_TRUE(dual::closed_fans(0, flipped, scratch).empty());
}

TEST(ManifoldDefects, FlagsEdgeWithThreeFaces) {
  EXPECT_EQ(defects_of(points(5), {0, 1, 2, 1, 0, 3, 0, 1, 4}), (Ids{0, 1}));
}

TEST(ManifoldDefects, FlagsInconsistentOrientation) {
  // The shared edge 0→1 used twice in the same direction.
  EXPECT_EQ(defects_of(points(4), {0, 1, 2, 0, 1, 3}), (Ids{0, 1}));
}

TEST(ManifoldDefects, FlagsDuplicateFace) {
  // The same vertex set in opposite orientations: every edge looks manifold, only the set repeats.
  EXPECT_EQ(defects_of(points(3), {0, 1, 2, 0, 2, 1}), (Ids{0, 1, 2}));
  // Same orientation (also a same-direction edge use).
  EXPECT_EQ(defects_of(points(4), {0, 1, 2, 0, 2, 3, 0, 2, 3}), (Ids{0, 2, 3}));
}

TEST(ManifoldDefects, FlagsIsolatedAndDegenerate) {
  EXPECT_EQ(defects_of(points(4), {0, 1, 2}), (Ids{3}));
  EXPECT_EQ(defects_of(points(4), {0, 1, 2, 3, 3, 1}), (Ids{1, 3}));
}

// The dual of a soup for the removal tests: vertex v of cluster `cluster` (v when −1), lying at
// input vertex 2v (odd vertices a strip's: source {2v, 2v + 1}), so both travel with it.
DualMesh dual_of(MeshBuffers m, int32_t cluster = -1) {
  DualMesh d;
  d.mesh = std::move(m);
  for (uint32_t v = 0; v < d.mesh.vertex_count(); ++v) {
    d.cluster_of_output_vertex.push_back(cluster >= 0 ? cluster : int32_t(v));
    d.source_of_output_vertex.push_back({uint32_t(d.source_vertices.size()), v % 2 ? 2u : 1u});
    d.source_vertices.push_back(2 * v);
    if (v % 2) d.source_vertices.push_back(2 * v + 1);
  }
  return d;
}

// remove_manifold_defects must leave a defect-free mesh and keep cluster ids and sources with
// their vertices.
void expect_removal_cleans(const MeshBuffers& input, const std::string& what, uint64_t expect_vertices_removed_at_least) {
  SCOPED_TRACE(what);
  ASSERT_FALSE(find_manifold_defects(input.view()).empty()) << "test mesh has no defect";
  const std::vector<float> original = input.positions;
  DualMesh d = dual_of(input);
  const MeshBuffers& m = d.mesh;
  const std::vector<int32_t>& ids = d.cluster_of_output_vertex;
  const uint64_t faces_before = m.face_count();
  DefectRemoval r = remove_manifold_defects(d);
  EXPECT_TRUE(find_manifold_defects(m.view()).empty());
  ASSERT_EQ(ids.size(), m.vertex_count());
  ASSERT_EQ(d.source_of_output_vertex.size(), m.vertex_count());
  EXPECT_EQ(m.face_count() + r.faces_removed, faces_before);
  EXPECT_GE(r.vertices_removed, expect_vertices_removed_at_least);
  EXPECT_GT(m.face_count(), 0u) << "removal deleted the whole mesh";
  for (uint32_t v = 0; v < m.vertex_count(); ++v) {
    ASSERT_GE(ids[v], 0);
    for (int k = 0; k < 3; ++k) EXPECT_EQ(m.positions[3 * v + k], original[3 * size_t(ids[v]) + k]);
    const VertexSource s = d.source_of_output_vertex[v];
    ASSERT_EQ(s.count, ids[v] % 2 ? 2u : 1u);
    EXPECT_EQ(d.source_vertices[s.begin], 2u * uint32_t(ids[v]));
  }
  for (uint32_t i : m.triangles) EXPECT_LT(i, m.vertex_count());
  TopologyStats t = compute_topology_stats(m.view());
  EXPECT_EQ(t.nonmanifold_edges, 0u);
  EXPECT_EQ(t.nonmanifold_vertices, 0u);
  EXPECT_EQ(t.duplicate_faces, 0u);
  EXPECT_EQ(t.isolated_vertices, 0u);
  EXPECT_TRUE(t.consistently_oriented);
}

TEST(ManifoldDefects, RemovalLeavesADefectFreeMesh) {
  const MeshBuffers sphere = make_icosphere(2);
  const uint32_t V = sphere.vertex_count();
  {  // bowtie: an extra triangle hanging off vertex 0
    MeshBuffers m = sphere;
    m.positions.insert(m.positions.end(), {3, 0, 0, 3, 1, 0});
    m.triangles.insert(m.triangles.end(), {0, V, V + 1});
    expect_removal_cleans(m, "bowtie", 2);
  }
  {  // a third face on the edge of face 0
    MeshBuffers m = sphere;
    m.positions.insert(m.positions.end(), {3, 0, 0});
    m.triangles.insert(m.triangles.end(), {sphere.triangles[0], sphere.triangles[1], V});
    expect_removal_cleans(m, "edge with three faces", 1);
  }
  {  // duplicate of face 5
    MeshBuffers m = sphere;
    m.triangles.insert(m.triangles.end(), {sphere.triangles[15], sphere.triangles[16], sphere.triangles[17]});
    expect_removal_cleans(m, "duplicate face", 0);
  }
  {  // isolated vertex
    MeshBuffers m = sphere;
    m.positions.insert(m.positions.end(), {5, 5, 5});
    DualMesh d = dual_of(m);
    const DefectRemoval r = remove_manifold_defects(d);
    EXPECT_EQ(r.faces_removed, 0u);
    EXPECT_EQ(r.vertices_removed, 1u);
    EXPECT_EQ(d.mesh.vertex_count(), V);
    EXPECT_EQ(d.source_of_output_vertex.size(), V);
    EXPECT_TRUE(find_manifold_defects(d.mesh.view()).empty());
  }
  {  // all of them at once, plus a degenerate face
    MeshBuffers m = sphere;
    m.positions.insert(m.positions.end(), {3, 0, 0, 3, 1, 0, 4, 4, 4});
    m.triangles.insert(m.triangles.end(), {0, V, V + 1, sphere.triangles[30], sphere.triangles[31], sphere.triangles[32],
                                           sphere.triangles[60], sphere.triangles[61], sphere.triangles[61]});
    expect_removal_cleans(m, "everything", 3);
  }
  {  // a clean mesh is left untouched
    DualMesh d = dual_of(sphere, 7);
    const DefectRemoval r = remove_manifold_defects(d);
    EXPECT_EQ(r.faces_removed, 0u);
    EXPECT_EQ(r.vertices_removed, 0u);
    EXPECT_EQ(d.mesh.triangles, sphere.triangles);
  }
}

}  // namespace
}  // namespace streamcvd
