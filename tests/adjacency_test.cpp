#include "streamcvd/streaming/store/adjacency.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <optional>
#include <random>
#include <set>
#include <vector>

#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {
namespace {

struct Adjacency {
  std::vector<uint64_t> vf_off, vv_off;
  std::vector<uint32_t> vf, vv;
  std::vector<uint8_t> flags;

  Adjacency(const std::vector<uint32_t>& tri, uint32_t v_count) {
    build_vertex_face_adjacency(std::span<const uint32_t>(tri), 0, v_count, vf_off, vf);
    build_vertex_vertex_adjacency(std::span<const uint32_t>(tri), 0, std::span<const uint64_t>(vf_off), std::span<const uint32_t>(vf), vv_off, vv);
    flags.resize(v_count);
    compute_vertex_flags(tri, vf_off, vf, flags);
    // The fused pass gives the same neighbours and flags.
    std::vector<uint64_t> fused_off;
    std::vector<uint32_t> fused_vv;
    std::vector<uint8_t> fused_flags(v_count, 0xff);
    build_vertex_vertex_adjacency(std::span<const uint32_t>(tri), 0, std::span<const uint64_t>(vf_off), std::span<const uint32_t>(vf), fused_off, fused_vv, std::span<uint8_t>(fused_flags));
    EXPECT_EQ(fused_off, vv_off);
    EXPECT_EQ(fused_vv, vv);
    EXPECT_EQ(fused_flags, flags);
  }
  std::vector<uint32_t> faces(uint32_t v) const { return {vf.begin() + vf_off[v], vf.begin() + vf_off[v + 1]}; }
  std::vector<uint32_t> ring(uint32_t v) const { return {vv.begin() + vv_off[v], vv.begin() + vv_off[v + 1]}; }
};

using V = std::vector<uint32_t>;

TEST(Adjacency, Tetrahedron) {
  Adjacency a({0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2}, 4);
  EXPECT_EQ(a.vf_off, (std::vector<uint64_t>{0, 3, 6, 9, 12}));
  EXPECT_EQ(a.faces(0), (V{0, 1, 3}));
  EXPECT_EQ(a.faces(3), (V{1, 2, 3}));
  EXPECT_EQ(a.ring(0), (V{1, 2, 3}));
  EXPECT_EQ(a.ring(2), (V{0, 1, 3}));
  for (uint8_t f : a.flags) EXPECT_EQ(f, 0);
}

TEST(Adjacency, QuadHasBoundaryEverywhere) {
  Adjacency a({0, 1, 2, 0, 2, 3}, 4);
  EXPECT_EQ(a.ring(0), (V{1, 2, 3}));
  EXPECT_EQ(a.ring(1), (V{0, 2}));
  EXPECT_EQ(a.faces(2), (V{0, 1}));
  for (uint8_t f : a.flags) EXPECT_EQ(f, kVertexBoundary);
}

TEST(Adjacency, BowtieFinAndIsolatedVertex) {
  // Bowtie: triangles (0,1,2) and (0,3,4) share only vertex 0. Fin: three faces on edge {5,6}.
  // Vertex 10 is referenced by nothing.
  Adjacency a({0, 1, 2, 0, 3, 4, 5, 6, 7, 6, 5, 8, 5, 6, 9}, 11);
  EXPECT_EQ(a.flags[0], kVertexBoundary | kVertexNonManifold);
  for (uint32_t v : {1u, 2u, 3u, 4u, 7u, 8u, 9u}) EXPECT_EQ(a.flags[v], kVertexBoundary) << v;
  EXPECT_EQ(a.flags[5], kVertexBoundary | kVertexNonManifold);
  EXPECT_EQ(a.flags[6], kVertexBoundary | kVertexNonManifold);
  EXPECT_EQ(a.flags[10], kVertexIsolated);
  EXPECT_TRUE(a.faces(10).empty());
  EXPECT_TRUE(a.ring(10).empty());
  EXPECT_EQ(a.ring(5), (V{6, 7, 8, 9}));
}

TEST(Adjacency, ClosedFansWithoutBoundaryAreManifoldButTwoConesAreNot) {
  // Two closed tetrahedra glued at vertex 0: no boundary edge, yet vertex 0 has two fans.
  Adjacency a({0, 2, 1, 0, 1, 3, 1, 2, 3, 0, 3, 2, 0, 5, 4, 0, 4, 6, 4, 5, 6, 0, 6, 5}, 7);
  EXPECT_EQ(a.flags[0], kVertexNonManifold);
  for (uint32_t v = 1; v < 7; ++v) EXPECT_EQ(a.flags[v], 0) << v;
}

TEST(Adjacency, DegenerateFacesDoNotBreakCounts) {
  // Face 1 repeats vertex 0; face 2 is a point. Every corner still has one vertex-face entry.
  Adjacency a({0, 1, 2, 0, 0, 1, 3, 3, 3}, 4);
  EXPECT_EQ(a.vf.size(), 9u);
  EXPECT_EQ(a.faces(0), (V{0, 1, 1}));
  EXPECT_EQ(a.faces(3), (V{2, 2, 2}));
  EXPECT_EQ(a.ring(0), (V{1, 2}));
  EXPECT_TRUE(a.ring(3).empty());
  // Edge {0,1} is in faces 0 and 1 (two faces); {0,2} and {1,2} in one.
  EXPECT_EQ(a.flags[0], kVertexBoundary);
  EXPECT_EQ(a.flags[3], 0);  // only a point face: no edges, not isolated
}

// A closed fan of n triangles around vertex 0 (rim 1..n) capped by a fan around vertex n + 1,
// optionally with face `flip` reversed (inconsistent orientation) and the last rim face removed
// (open fan). Covers both the common-vertex fast path (n ≤ 16, oriented) and the general one.
std::vector<uint32_t> double_cone(uint32_t n, int flip, bool open) {
  std::vector<uint32_t> t;
  for (uint32_t i = 0; i < n; ++i) {
    const uint32_t a = 1 + i, b = 1 + (i + 1) % n;
    if (open && i == n - 1) continue;
    t.insert(t.end(), {0, a, b});
    t.insert(t.end(), {n + 1, b, a});
  }
  if (flip >= 0) std::swap(t[3 * size_t(flip) + 1], t[3 * size_t(flip) + 2]);
  return t;
}

TEST(Adjacency, FansOfAnySizeAndOrientation) {
  for (uint32_t n : {3u, 6u, 16u, 17u, 40u})
    for (int flip : {-1, 0, 3})
      for (bool open : {false, true}) {
        SCOPED_TRACE(::testing::Message() << "n " << n << " flip " << flip << " open " << open);
        Adjacency a(double_cone(n, flip, open), n + 2);
        const uint8_t apex = open ? kVertexBoundary : 0;
        EXPECT_EQ(a.flags[0], apex);
        EXPECT_EQ(a.flags[n + 1], apex);
        EXPECT_EQ(a.ring(0).size(), n);
        EXPECT_EQ(a.ring(0).front(), 1u);
        EXPECT_EQ(a.ring(0).back(), n);
        for (uint32_t v = 1; v <= n; ++v) {
          const bool on_cut = open && (v == n || v == 1);
          EXPECT_EQ(a.flags[v], on_cut ? kVertexBoundary : 0) << v;
          EXPECT_EQ(a.ring(v).size(), on_cut ? 3u : 4u) << v;
        }
      }
}

// Rings checked against sets, on a mesh whose vertex blocks (4096 vertices) include clean ones
// (a grid: every ring fits deg_f + 1) and ones with many multi-fan vertices, whose rings
// overflow that bound: stars of triangles meeting only at their centre, random triangles.
TEST(Adjacency, RingsMatchSetsWhenVerticesHaveManyFans) {
  std::vector<uint32_t> tri;
  const uint32_t side = 80;  // grid vertices 0 .. 6399
  for (uint32_t i = 0; i + 1 < side; ++i)
    for (uint32_t j = 0; j + 1 < side; ++j) {
      const uint32_t a = i * side + j, b = a + 1, c = a + side, d = c + 1;
      tri.insert(tri.end(), {a, b, d, a, d, c});
    }
  uint32_t next = side * side;
  for (int star = 0; star < 200; ++star) {  // centre + 10 separate triangles: ring 20, deg 10
    const uint32_t centre = next++;
    for (int k = 0; k < 10; ++k, next += 2) tri.insert(tri.end(), {centre, next, next + 1});
  }
  std::mt19937 rng(7);
  const uint32_t first_random = next, v_count = next + 3000;
  std::uniform_int_distribution<uint32_t> pick(first_random, v_count - 1);
  for (int k = 0; k < 6000; ++k) tri.insert(tri.end(), {pick(rng), pick(rng), pick(rng)});
  Adjacency a(tri, v_count);
  std::vector<std::set<uint32_t>> sets(v_count);
  for (size_t f = 0; f < tri.size(); f += 3)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        if (tri[f + i] != tri[f + j]) sets[tri[f + i]].insert(tri[f + j]);
  for (uint32_t v = 0; v < v_count; ++v)
    ASSERT_EQ(a.ring(v), V(sets[v].begin(), sets[v].end())) << v;
  EXPECT_EQ(a.ring(side * side).size(), 20u);
}

// Big enough for the parallel paths (several corner ranges, several ring blocks): the same CSR
// arrays with 1, 2 and 8 threads, equal to a direct serial construction.
TEST(Adjacency, LargeMeshSameForAnyThreadCount) {
  std::vector<uint32_t> tri;
  const uint32_t side = 300;
  for (uint32_t i = 0; i + 1 < side; ++i)
    for (uint32_t j = 0; j + 1 < side; ++j) {
      const uint32_t a = i * side + j, b = a + 1, c = a + side, d = c + 1;
      tri.insert(tri.end(), {a, b, d, a, d, c});
    }
  std::mt19937 rng(11);
  std::shuffle(tri.begin(), tri.end(), rng);  // scattered corners: every range touches every vertex
  const uint32_t v_count = side * side;
  std::vector<std::vector<uint32_t>> lists(v_count);
  for (size_t i = 0; i < tri.size(); ++i) lists[tri[i]].push_back(uint32_t(i / 3));
  std::vector<uint64_t> expected_off{0};
  std::vector<uint32_t> expected_vf;
  for (const auto& l : lists) {
    expected_vf.insert(expected_vf.end(), l.begin(), l.end());
    expected_off.push_back(expected_vf.size());
  }
  std::optional<Adjacency> reference;
  for (int threads : {1, 2, 8}) {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, threads);
    Adjacency a(tri, v_count);
    EXPECT_EQ(a.vf_off, expected_off) << threads;
    EXPECT_EQ(a.vf, expected_vf) << threads;
    if (!reference) {
      reference.emplace(std::move(a));
      continue;
    }
    EXPECT_EQ(a.vv_off, reference->vv_off) << threads;
    EXPECT_EQ(a.vv, reference->vv) << threads;
    EXPECT_EQ(a.flags, reference->flags) << threads;
  }
}

TEST(Adjacency, EmptyMesh) {
  Adjacency a({}, 3);
  EXPECT_EQ(a.vf_off, (std::vector<uint64_t>{0, 0, 0, 0}));
  EXPECT_EQ(a.vv_off, (std::vector<uint64_t>{0, 0, 0, 0}));
  for (uint8_t f : a.flags) EXPECT_EQ(f, kVertexIsolated);
  Adjacency none({}, 0);
  EXPECT_EQ(none.vf_off.size(), 1u);
  EXPECT_EQ(none.vv_off.size(), 1u);
}

}  // namespace
}  // namespace streamcvd
