// Tests of the repair's edits (core/dual/cluster_repair.h): a defective cluster is cut between
// the two arcs along which it meets a neighbour, a band is cut across, and a cluster between
// two others (a lens on their frontier) is dissolved rather than split, and a cluster in
// pieces is cut along its pieces, a cluster meeting a hole twice is cut between its stretches;
// parts_are_discs tells a clean cut from one that is not.
#include "streamcvd/core/dual/cluster_repair.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <set>
#include <vector>

#include "streamcvd/core/clustering/clustering.h"
#include "streamcvd/core/clustering/item_data.h"
#include "streamcvd/core/dual/dual_mesh.h"
#include "streamcvd/core/dual/dual_topology.h"
#include "streamcvd/core/dual/repair.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

std::vector<uint32_t> members_of(const std::vector<int32_t>& labels, int32_t c) {
  std::vector<uint32_t> m;
  for (uint32_t v = 0; v < labels.size(); ++v)
    if (labels[v] == c) m.push_back(v);
  return m;
}

// Labels of a grid of nx × ny vertices by position (column i, row j): label_of(i, j). The store
// orders vertices its own way, so the grid's indices do not tell where a vertex is.
std::vector<int32_t> grid_labels(const MeshView& view, int nx, int ny, auto&& label_of) {
  std::vector<int32_t> labels(view.vertex_count());
  for (uint32_t v = 0; v < view.vertex_count(); ++v)
    labels[v] = label_of(std::lround(view.positions[3 * v] * (nx - 1)), std::lround(view.positions[3 * v + 1] * (ny - 1)));
  return labels;
}

// Labels of the members of `c`'s old vertices that lie next to a vertex labelled `y`.
std::set<int32_t> labels_next_to(const MeshView& view, const std::vector<int32_t>& labels,
                                 std::span<const uint32_t> old_members, int32_t y, auto&& keep) {
  std::set<int32_t> out;
  for (uint32_t v : old_members) {
    if (!keep(v)) continue;
    for (uint32_t n : view.neighbours(v))
      if (labels[n] == y) out.insert(labels[v]);
  }
  return out;
}

// Cuts cluster 0 at a defect, its second part labelled 3; returns its members before the cut.
std::vector<uint32_t> cut_cluster_zero(const MeshView& view, std::vector<int32_t>& labels) {
  const std::vector<uint32_t> a = members_of(labels, 0);
  detail::SplitScratch scratch;
  const int32_t new_label = 3;
  EXPECT_EQ(detail::split_cluster(view, labels, a, {&new_label, 1}, scratch, true), 1u);
  return a;
}

TEST(ClusterSplit, ACutBetweenTheTwoArcsWhereAClusterMeetsItsNeighbour) {
  // Grid 20 × 10: A (0) left, B (1) right, C (2) a wedge across their frontier in rows 4–5, so
  // A meets B along two arcs (rows 0–3 and 6–9): the dual edge A–B has four faces.
  const int nx = 20, ny = 10;
  MeshStore store = MeshStore::build(make_grid(nx, ny).view());
  const MeshView view = store.view();
  std::vector<int32_t> labels = grid_labels(view, nx, ny, [](long i, long j) {
    return (j == 4 || j == 5) && i >= 8 && i <= 11 ? 2 : i < 10 ? 0 : 1;
  });
  const std::vector<uint32_t> a = cut_cluster_zero(view, labels);
  auto row = [&](uint32_t v) { return int(std::lround(view.positions[3 * v + 1] * (ny - 1))); };
  const std::set<int32_t> top = labels_next_to(view, labels, a, 1, [&](uint32_t v) { return row(v) <= 3; });
  const std::set<int32_t> bottom = labels_next_to(view, labels, a, 1, [&](uint32_t v) { return row(v) >= 6; });
  ASSERT_EQ(top.size(), 1u) << "the arc along rows 0-3 stays in one part";
  ASSERT_EQ(bottom.size(), 1u);
  EXPECT_NE(*top.begin(), *bottom.begin()) << "each part keeps one arc";
  EXPECT_TRUE(clusters_connected(view, labels, 4));
  // The dual edge between B and each part of A now has two faces at most.
  const std::vector<dual::Face> faces = dual::collect_triples(view, labels).faces;
  for (int32_t part : {0, 3}) {
    const auto on_edge = std::count_if(faces.begin(), faces.end(), [&](const dual::Face& f) {
      return std::count(f.begin(), f.end(), uint32_t(part)) == 1 && std::count(f.begin(), f.end(), 1u) == 1;
    });
    EXPECT_LE(on_edge, 2) << "part " << part;
  }
}

TEST(ClusterSplit, PartsAreDiscsTellsACleanCutFromAnIslandOrABandAcross) {
  // Grid 12 × 12 in 3 × 3 blocks of 4 × 4 vertices, clusters 0–8; the centre one (4) touches
  // no boundary. It is cut three ways into 4 and 9: the compensating splits of the repair keep
  // a cut only when both parts are discs.
  const int nx = 12, ny = 12;
  MeshStore store = MeshStore::build(make_grid(nx, ny).view());
  const MeshView view = store.view();
  auto cut = [&](auto&& in_new_part) {
    return grid_labels(view, nx, ny, [&](long i, long j) {
      const int32_t block = int32_t(j / 4 * 3 + i / 4);
      return block == 4 && in_new_part(i, j) ? 9 : block;
    });
  };
  dual::FanScratch scratch;
  const std::array<int32_t, 2> parts = {4, 9};
  auto discs = [&](const std::vector<int32_t>& labels) {
    std::vector<uint32_t> members = members_of(labels, 4), more = members_of(labels, 9);
    members.insert(members.end(), more.begin(), more.end());
    std::sort(members.begin(), members.end());
    return detail::parts_are_discs(view, labels, members, parts, scratch);
  };
  EXPECT_TRUE(discs(cut([](long i, long) { return i >= 6; }))) << "halves side by side";
  EXPECT_FALSE(discs(cut([](long i, long j) { return i >= 5 && i <= 6 && j >= 5 && j <= 6; })))
      << "an island: no dual face, and 4 rings it";
  EXPECT_FALSE(discs(cut([](long i, long) { return i == 5 || i == 6; }))) << "a band across: 4 in two pieces";
  EXPECT_FALSE(discs(cut([](long, long) { return false; }))) << "an empty part has no fan";
}

TEST(ClusterSplit, AShortArcBesideALongOneGetsAFairPartNotASliver) {
  // Grid 30 × 20: A (0) left, B (1) right, C (2) a wedge across their frontier in rows 1–2, so
  // A meets B along a one-row arc (row 0) and a long one (rows 3–19). Grown from the arcs by
  // nearest hop, the short arc's part is a sliver of rows 0–1 that the next round cuts again.
  const int nx = 30, ny = 20;
  MeshStore store = MeshStore::build(make_grid(nx, ny).view());
  const MeshView view = store.view();
  std::vector<int32_t> labels = grid_labels(view, nx, ny, [](long i, long j) {
    return (j == 1 || j == 2) && i >= 12 && i <= 17 ? 2 : i < 15 ? 0 : 1;
  });
  const std::vector<uint32_t> a = cut_cluster_zero(view, labels);
  auto row = [&](uint32_t v) { return int(std::lround(view.positions[3 * v + 1] * (ny - 1))); };
  const std::set<int32_t> short_arc = labels_next_to(view, labels, a, 1, [&](uint32_t v) { return row(v) == 0; });
  const std::set<int32_t> long_arc = labels_next_to(view, labels, a, 1, [&](uint32_t v) { return row(v) >= 3; });
  ASSERT_EQ(short_arc.size(), 1u);
  ASSERT_EQ(long_arc.size(), 1u);
  EXPECT_NE(*short_arc.begin(), *long_arc.begin()) << "each part keeps one arc";
  EXPECT_TRUE(clusters_connected(view, labels, 4));
  const size_t part = size_t(std::count(labels.begin(), labels.end(), *short_arc.begin()));
  EXPECT_GE(4 * 2 * part, a.size()) << "the short arc's part has " << part << " of " << a.size() << " members";
}

TEST(ClusterSplit, AClusterMeetingAHoleTwiceIsCutBetweenItsTwoStretches) {
  // Grid 21 × 41 with a hole of 2 × 1 cells near the top (loop of 6 vertices: columns 9–11,
  // rows 35–36). Cluster 0 holds the loop's left and right sides and everything below, 1 its
  // top middle vertex and all above, 2 its bottom middle one: 0 meets the hole in two
  // stretches, so the ring 0, 1, 0, 2 cannot close. A farthest-point cut parts 0's top from its
  // bottom, both stretches in one part; cut from the stretches, each part holds one and the
  // ring is four distinct clusters.
  const int nx = 21, ny = 41;
  MeshBuffers grid = make_grid(nx, ny);
  std::vector<uint32_t> kept;
  for (size_t f = 0; f < grid.face_count(); ++f) {
    double x = 0, y = 0;
    for (int k = 0; k < 3; ++k) {
      x += grid.positions[3 * size_t(grid.triangles[3 * f + k])] * (nx - 1) / 3.0;
      y += grid.positions[3 * size_t(grid.triangles[3 * f + k]) + 1] * (ny - 1) / 3.0;
    }
    if (!(x > 9 && x < 11 && y > 35 && y < 36)) kept.insert(kept.end(), &grid.triangles[3 * f], &grid.triangles[3 * f + 3]);
  }
  grid.triangles = kept;
  MeshStore store = MeshStore::build(grid.view());
  const MeshView view = store.view();
  const std::vector<int32_t> before = grid_labels(view, nx, ny, [](long i, long j) {
    if (j >= 37 || (i == 10 && j == 36)) return 1;
    if (i == 10 && (j == 35 || j == 34)) return 2;
    return 0;
  });
  ASSERT_TRUE(clusters_connected(view, before, 3));
  const BoundaryLoops loops = find_boundary_loops(view);
  ASSERT_EQ(loops.offsets.size(), 3u) << "the outer loop and the hole";
  const uint32_t hole = loops.offsets[1] - loops.offsets[0] == 6 ? 0 : 1;
  const std::span<const uint32_t> loop(loops.vertices.data() + loops.offsets[hole], 6);
  auto at = [&](const std::vector<int32_t>& labels, long i, long j) {
    for (uint32_t v : loop)
      if (std::lround(view.positions[3 * v] * (nx - 1)) == i && std::lround(view.positions[3 * v + 1] * (ny - 1)) == j)
        return labels[v];
    ADD_FAILURE() << "(" << i << ", " << j << ") is not on the hole";
    return -1;
  };
  const int32_t new_label = 3;
  for (const bool with_loop : {false, true}) {
    std::vector<int32_t> labels = before;
    detail::SplitScratch scratch;
    const std::span<const uint32_t> hole_loop = with_loop ? loop : std::span<const uint32_t>();
    ASSERT_EQ(detail::split_cluster(view, labels, members_of(before, 0), {&new_label, 1}, scratch, false, nullptr, hole_loop), 1u);
    EXPECT_EQ(at(labels, 9, 35), at(labels, 9, 36)) << "the left stretch stays in one part";
    EXPECT_EQ(at(labels, 11, 35), at(labels, 11, 36)) << "the right stretch stays in one part";
    EXPECT_EQ(at(labels, 9, 35) != at(labels, 11, 35), with_loop) << (with_loop ? "each part holds one stretch"
                                                                                 : "a farthest-point cut keeps both");
    EXPECT_TRUE(clusters_connected(view, labels, 4));
  }
}

TEST(ClusterSplit, ABandRoundATubeIsCutAcrossNotAlongIt) {
  // Torus of 120 rings × 8: clusters of 12 rings each are bands round the tube, longer than
  // they are round, so a farthest-point split cuts them along the tube into two bands. A cut
  // across gives two pieces that each touch both neighbours.
  const int rings = 120, segments = 8;
  MeshStore store = MeshStore::build(make_torus(rings, segments).view());
  const MeshView view = store.view();
  std::vector<int32_t> labels(view.vertex_count());
  for (uint32_t v = 0; v < view.vertex_count(); ++v) {  // ring index from the angle round the z axis
    const double u = std::atan2(view.positions[3 * v + 1], view.positions[3 * v]);
    const long ring = std::lround((u < 0 ? u + 2 * M_PI : u) / (2 * M_PI) * rings) % rings;
    labels[v] = int32_t(ring / 12);
  }
  const std::vector<uint32_t> band = members_of(labels, 3);  // rings 36–47, between bands 2 and 4
  detail::SplitScratch scratch;
  const int32_t new_label = 10;
  ASSERT_EQ(detail::split_cluster(view, labels, band, {&new_label, 1}, scratch, true), 1u);
  for (int32_t part : {3, 10}) {
    const std::vector<uint32_t> m = members_of(labels, part);
    ASSERT_FALSE(m.empty());
    std::set<int32_t> neighbours;
    for (uint32_t v : m)
      for (uint32_t n : view.neighbours(v))
        if (labels[n] != part) neighbours.insert(labels[n]);
    EXPECT_TRUE(neighbours.count(2) && neighbours.count(4)) << "part " << part << " touches both neighbouring bands";
  }
  EXPECT_TRUE(clusters_connected(view, labels, 11));
}

TEST(ClusterSplit, AClusterInPiecesIsCutAlongItsPieces) {
  // Grid 20 × 20: cluster 1 is two squares apart (4 × 4 vertices each) inside cluster 0. A
  // farthest-point split finds both seeds in the first square and leaves the other one apart;
  // the split must part the two squares, so every cluster is connected afterwards.
  const int nx = 20, ny = 20;
  MeshStore store = MeshStore::build(make_grid(nx, ny).view());
  const MeshView view = store.view();
  std::vector<int32_t> labels = grid_labels(view, nx, ny, [](long i, long j) {
    const bool square_a = i >= 3 && i <= 6 && j >= 3 && j <= 6, square_b = i >= 12 && i <= 15 && j >= 12 && j <= 15;
    return square_a || square_b ? 1 : 0;
  });
  ASSERT_FALSE(clusters_connected(view, labels, 2));
  for (const bool at_defect : {false, true}) {
    std::vector<int32_t> split = labels;
    detail::SplitScratch scratch;
    const int32_t new_label = 2;
    EXPECT_EQ(detail::split_cluster(view, split, members_of(labels, 1), {&new_label, 1}, scratch, at_defect), 1u);
    EXPECT_EQ(members_of(split, 1).size(), 16u) << "at_defect " << at_defect;
    EXPECT_EQ(members_of(split, 2).size(), 16u) << "at_defect " << at_defect;
    EXPECT_TRUE(clusters_connected(view, split, 3)) << "at_defect " << at_defect;
  }
}

TEST(RepairLoop, ALensOnAFrontierIsDissolvedAndTheCountKept) {
  // 8 × 8 tiles on a grid, and a small cluster (64) on the frontier of tiles 27 and 35 only:
  // its dual vertex has two faces on the same three vertices. It joins a neighbour, a split
  // elsewhere keeps the count, and the dual is left without defects.
  constexpr uint32_t K = 65;
  MeshStore store = MeshStore::build(make_grid(161, 161).view());
  const MeshView view = store.view();
  std::vector<int32_t> labels(view.vertex_count());
  for (uint32_t v = 0; v < view.vertex_count(); ++v) {
    const double x = view.positions[3 * v], y = view.positions[3 * v + 1];
    labels[v] = std::hypot(x - 0.5, y - 0.4375) < 0.02 ? 64 : std::min(7, int(x * 8)) * 8 + std::min(7, int(y * 8));
  }
  std::set<int32_t> lens_neighbours;
  for (uint32_t v : members_of(labels, 64))
    for (uint32_t n : view.neighbours(v))
      if (labels[n] != 64) lens_neighbours.insert(labels[n]);
  ASSERT_EQ(lens_neighbours, (std::set<int32_t>{27, 35}));
  const ItemData items = compute_item_data(view);
  const BoundaryLoops loops = find_boundary_loops(view);
  std::vector<uint8_t> adjustable(K, 1);
  ClusteringReport report;
  DefectRepairOptions options;
  options.clustering = test::metric_i_one_thread();
  const DefectRepairResult r = repair_dual_defects(view, items, labels, K, adjustable, loops, options, report, ram_storage());
  EXPECT_GE(r.islands, 1u) << "the lens is dissolved";
  EXPECT_LE(r.rounds, 2u);
  EXPECT_EQ(r.defect_vertices, 0u);
  std::vector<double> z(3 * size_t(K), 0.0);
  EXPECT_TRUE(find_manifold_defects(build_dual_mesh(view, labels, K, z, {}, &loops).mesh.view()).empty());
  const std::vector<uint32_t> sizes = dual::cluster_sizes(view, labels, K);
  EXPECT_EQ(std::count(sizes.begin(), sizes.end(), 0u), 0) << "the cluster count stays K";
  EXPECT_TRUE(clusters_connected(view, labels, K));
}

}  // namespace
}  // namespace streamcvd
