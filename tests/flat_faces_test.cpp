// Tests of the flat-face safety net (core/dual/flat_faces.h): a flat face along the boundary whose
// middle vertex is interior is dropped, one across an interior edge is flipped away, one whose
// middle vertex is on the boundary already is nudged; the result stays manifold, oriented and
// keeps V and χ. On the dragon (seeds whose strips gave a flat face) the output has none.
#include "streamcvd/core/dual/flat_faces.h"

#include <gtest/gtest.h>

#include <vector>

#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/remesh.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

// u = 0, v = 1 on the x axis, m = 2 at their middle (collinear), top = 3, below = 4.
std::vector<float> points() { return {0, 0, 0, 1, 0, 0, 0.5f, 0, 0, 0.5f, 1, 0, 0.5f, -1, 0}; }

void expect_clean(const std::vector<float>& P, const std::vector<uint32_t>& T, int64_t euler) {
  const TopologyStats s = compute_topology_stats(TriangleSoupView{P, T});
  EXPECT_EQ(s.degenerate_faces, 0u);
  EXPECT_EQ(s.nonmanifold_edges, 0u);
  EXPECT_EQ(s.nonmanifold_vertices, 0u);
  EXPECT_EQ(s.duplicate_faces, 0u);
  EXPECT_TRUE(s.consistently_oriented);
  EXPECT_EQ(s.euler_characteristic, euler);
}

TEST(FlatFaces, BoundaryFaceOverAnInteriorVertexIsDropped) {
  // A strip triangle (p, p_next, b) with b projected onto the boundary between p and p_next.
  std::vector<float> P = points();
  std::vector<uint32_t> T = {0, 1, 2, 0, 2, 3, 2, 1, 3};
  EXPECT_EQ(compute_topology_stats(TriangleSoupView{P, T}).degenerate_faces, 1u);
  const FlatFaceRepair r = repair_flat_faces(P, T);
  EXPECT_EQ(r.faces_removed, 1u);
  EXPECT_EQ(r.remaining, 0u);
  EXPECT_EQ(T.size(), 6u);
  EXPECT_EQ(P, points());  // no vertex moved
  expect_clean(P, T, 1);
}

TEST(FlatFaces, FlatFaceAcrossAnInteriorEdgeIsFlipped) {
  std::vector<float> P = points();
  std::vector<uint32_t> T = {0, 1, 2, 1, 0, 4, 0, 2, 3, 2, 1, 3};
  const FlatFaceRepair r = repair_flat_faces(P, T);
  EXPECT_EQ(r.flips, 1u);
  EXPECT_EQ(r.remaining, 0u);
  EXPECT_EQ(T.size(), 12u);
  expect_clean(P, T, 1);
}

TEST(FlatFaces, MiddleVertexOnTheBoundaryIsNudgedInwards) {
  // Dropping the face would pinch m (a bowtie): m moves off the line by a few ulps instead.
  std::vector<float> P = points();
  std::vector<uint32_t> T = {0, 1, 2, 0, 2, 3};
  const FlatFaceRepair r = repair_flat_faces(P, T);
  EXPECT_EQ(r.nudges, 1u);
  EXPECT_EQ(r.remaining, 0u);
  EXPECT_EQ(T.size(), 6u);
  EXPECT_GT(P[7], 0.0f);     // towards top, inside the surface
  EXPECT_LT(P[7], 1e-9f);    // a tiny move
  expect_clean(P, T, 1);
}

TEST(FlatFaces, NonFlatMeshIsUntouched) {
  std::vector<float> P = points();
  P[7] = 0.25f;
  std::vector<uint32_t> T = {0, 1, 2, 1, 0, 4, 0, 2, 3, 2, 1, 3};
  const std::vector<uint32_t> before = T;
  const FlatFaceRepair r = repair_flat_faces(P, T);
  EXPECT_EQ(r.faces_removed + r.flips + r.nudges + r.remaining, 0u);
  EXPECT_EQ(T, before);
}

TEST(FlatFaces, ShortEdgeOnADebrisPieceIsSpreadApart) {
  // A closed five-vertex debris piece of dragon ×121 → 1M (1.5 % of an output edge wide), whose
  // vertices 2 and 4 nearly coincide: faces (0, 4, 2) and (1, 2, 4) were flat, and no nudge of a
  // few ulps gave both an area (the job failed its degenerate check). A separate triangle sets
  // the bounding box, hence the flat threshold, as the rest of the dragon did.
  std::vector<float> P = {-0.057800442f,  0.156051546f,  -0.013250513f,  -0.0578002483f, 0.156058893f,
                          -0.0132580092f, -0.0578002296f, 0.156054422f,  -0.01325355f,   -0.0578005314f,
                          0.15605469f,    -0.0132537624f, -0.0578002259f, 0.156054333f,  -0.0132534513f,
                          0.2f,           0.156f,        -0.013f,        0.2f,           0.2f,
                          -0.013f,        0.2f,           0.156f,        0.03f};
  std::vector<uint32_t> T = {0, 2, 3, 0, 3, 4, 0, 4, 2, 1, 2, 4, 1, 3, 2, 1, 4, 3, 5, 6, 7};
  const std::vector<float> before = P;
  EXPECT_EQ(compute_topology_stats(TriangleSoupView{P, T}).degenerate_faces, 2u);
  const FlatFaceRepair r = repair_flat_faces(P, T);
  EXPECT_EQ(r.remaining, 0u);
  EXPECT_EQ(r.faces_removed + r.flips, 0u);
  EXPECT_GE(r.nudges, 1u);
  EXPECT_EQ(T.size(), 21u);
  for (size_t i = 0; i < P.size(); ++i) EXPECT_NEAR(P[i], before[i], 1e-5) << i;  // stays within the piece
  expect_clean(P, T, 3);  // the closed piece (χ = 2) and the triangle (χ = 1)
}

TEST(FlatFaces, DragonSeedsWithCollinearStripsHaveNoFlatFace) {
  // At N = 20000 (metric I) seeds 10 and 15 gave one flat strip triangle each (dropped), seeds
  // 35 and 45 one (nudged), with the chunk-wise initial sampling (the global one had such
  // triangles at seeds 5 and 9, and at 3 and 12 under the former cap of 12 repair rounds). Since
  // the strips are spaced like the clusters and shaped (core/dual/strip_shape.h) the net acts once over
  // the four seeds (it may act on none): the output must still have no degenerate face.
  const auto path = test::shared_data_path("stanford_dragon_vrip.ply");
  if (!path) GTEST_SKIP() << "../shared/data absent";
  MeshStore store = MeshStore::build(read_mesh(*path).view());
  uint64_t edits = 0;
  for (uint64_t seed : {10, 15, 35, 45}) {
    RemeshOptions o;
    o.clustering = test::metric_i_one_thread();
    o.vertices = 20000;
    o.seed = seed;
    const RemeshResult r = remesh(store.view(), o);
    EXPECT_EQ(compute_topology_stats(r.mesh.view()).degenerate_faces, 0u) << "seed " << seed;
    edits += r.checks.flat_faces.faces_removed + r.checks.flat_faces.flips + r.checks.flat_faces.nudges;
  }
  std::printf("  flat-face edits of the safety net over the four seeds: %llu\n", (unsigned long long)edits);
}

}  // namespace
}  // namespace streamcvd
