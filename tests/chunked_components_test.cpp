// core/chunked_components: pieces inside ranges, their merge across frontiers, labels, and the
// checks that catch one-sided joins; against a plain union-find over all vertices.
#include "streamcvd/core/mesh/chunked_components.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <numeric>
#include <random>
#include <stdexcept>

#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/store/store.h"

namespace streamcvd {
namespace {

// An undirected graph as adjacency lists; members are the vertices listed in `member`.
struct Graph {
  uint32_t n = 0;
  std::vector<std::vector<uint32_t>> adj;
  std::vector<bool> member;
  explicit Graph(uint32_t count) : n(count), adj(count), member(count, false) {}
  void add(uint32_t v) { member[v] = true; }
  void edge(uint32_t a, uint32_t b) {
    adj[a].push_back(b);
    adj[b].push_back(a);
    member[a] = member[b] = true;
  }
  RangeFill fill() const {
    return [this](size_t, VertexRange r, RangePieceBuilder& b) {
      for (uint32_t v = r.begin; v != r.end; ++v) {
        if (member[v]) b.add(v);
        for (uint32_t u : adj[v]) b.join(v, u);
      }
    };
  }
};

// Component id of every vertex by a plain union-find, numbered by smallest vertex; kNoComponent
// for non-members. The reference the chunked version must reproduce exactly.
std::vector<uint32_t> reference_labels(const Graph& g, uint64_t& count) {
  std::vector<uint32_t> parent(g.n);
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (uint32_t v = 0; v < g.n; ++v)
    for (uint32_t u : g.adj[v]) {
      const uint32_t a = find(v), b = find(u);
      parent[std::max(a, b)] = std::min(a, b);
    }
  std::vector<uint32_t> label(g.n, kNoComponent);
  std::map<uint32_t, uint32_t> id_of_root;
  for (uint32_t v = 0; v < g.n; ++v)
    if (g.member[v]) label[v] = id_of_root.emplace(find(v), uint32_t(id_of_root.size())).first->second;
  count = id_of_root.size();
  return label;
}

std::vector<VertexRange> tiling(uint32_t n, uint32_t size) {
  std::vector<VertexRange> r;
  for (uint32_t b = 0; b < n; b += size) r.push_back({b, std::min(n, b + size)});
  return r;
}

std::vector<uint32_t> chunked_labels(const Graph& g, std::span<const VertexRange> ranges, uint64_t& count) {
  std::vector<uint32_t> label(g.n, 12345);
  const ComponentTable t = chunked_component_labels(ranges, g.fill(), label);
  count = t.components;
  EXPECT_EQ(chunked_components(ranges, g.fill()).components, count);  // the table alone agrees
  return label;
}

TEST(ChunkedComponents, RandomGraphsMatchAPlainUnionFindForEveryTiling) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 20; ++trial) {
    const uint32_t n = 50 + uint32_t(rng() % 400);
    Graph g(n);
    // Sparse random edges (many components), some long ones crossing many ranges, a few
    // isolated members and non-members.
    const uint32_t edges = n / 2 + rng() % n;
    for (uint32_t e = 0; e < edges; ++e) {
      const uint32_t a = rng() % n, b = (rng() % 4 == 0) ? rng() % n : std::min<uint32_t>(n - 1, a + 1 + uint32_t(rng() % 5));
      g.edge(a, b);  // a == b is a self-join: a member, nothing joined
    }
    for (uint32_t k = 0; k < n / 20; ++k) g.add(rng() % n);
    uint64_t expected_count = 0;
    const std::vector<uint32_t> expected = reference_labels(g, expected_count);
    for (uint32_t size : {1u, 2u, 3u, 17u, 64u, n}) {
      uint64_t count = 0;
      const std::vector<VertexRange> ranges = tiling(n, size);
      EXPECT_EQ(chunked_labels(g, ranges, count), expected) << "trial " << trial << ", ranges of " << size;
      EXPECT_EQ(count, expected_count) << "trial " << trial << ", ranges of " << size;
    }
  }
}

TEST(ChunkedComponents, OneComponentThroughEveryRange) {
  // A path zig-zagging between the ends, so every range joins far-away ranges.
  const uint32_t n = 1000;
  Graph g(n);
  for (uint32_t i = 0; i < n / 2; ++i) {
    g.edge(i, n - 1 - i);
    if (i + 1 < n / 2) g.edge(n - 1 - i, i + 1);
  }
  uint64_t count = 0;
  const std::vector<uint32_t> labels = chunked_labels(g, tiling(n, 7), count);
  EXPECT_EQ(count, 1u);
  EXPECT_TRUE(std::all_of(labels.begin(), labels.end(), [](uint32_t l) { return l == 0; }));
}

TEST(ChunkedComponents, PiecesOfARangeJoinedOnlyThroughAnotherRange) {
  // Range 0 = [0, 4): vertices 0 and 2 are two pieces there, joined through vertex 5 of range 1;
  // 1 is a piece of its own, 3 takes no part. Range 1 = [4, 8): 4-7 and 5, 6 alone.
  Graph g(8);
  g.edge(0, 5);
  g.edge(2, 5);
  g.add(1);
  g.edge(4, 7);
  g.add(6);
  const std::vector<VertexRange> ranges = tiling(8, 4);
  RangePieceBuilder b;
  b.begin(ranges[0]);
  g.fill()(0, ranges[0], b);
  std::vector<uint32_t> piece(4);
  const RangePieces p0 = b.finish(piece);
  EXPECT_EQ(p0.pieces, 3u);
  EXPECT_EQ(piece, (std::vector<uint32_t>{0, 1, 2, kNoComponent}));  // numbered by smallest vertex
  EXPECT_EQ(p0.exported, (std::vector<FrontierTie>{{0, 0}, {2, 2}}));
  EXPECT_TRUE(p0.imported.empty());
  b.begin(ranges[1]);
  g.fill()(1, ranges[1], b);
  const RangePieces p1 = b.finish();
  EXPECT_EQ(p1.pieces, 3u);  // {4, 7}, {5}, {6}
  EXPECT_EQ(p1.imported, (std::vector<FrontierTie>{{0, 1}, {2, 1}}));
  EXPECT_TRUE(p1.exported.empty());

  const std::vector<RangePieces> pieces = {p0, p1};
  const ComponentTable t = merge_range_pieces(ranges, pieces);
  EXPECT_EQ(t.components, 4u);  // {0, 2, 5}, {1}, {4, 7}, {6}
  EXPECT_EQ(t.component(0, 0), 0u);
  EXPECT_EQ(t.component(0, 2), 0u);
  EXPECT_EQ(t.component(1, 1), 0u);
  EXPECT_EQ(t.component(0, 1), 1u);
  EXPECT_EQ(t.component(1, 0), 2u);
  EXPECT_EQ(t.component(1, 2), 3u);
}

TEST(ChunkedComponents, OneSidedJoinsThrow) {
  const std::vector<VertexRange> ranges = tiling(6, 3);
  // Range 1 joins 4 → 1 but range 0 never joins 1 → 4: an import without an export.
  RangeFill import_only = [](size_t i, VertexRange, RangePieceBuilder& b) {
    if (i == 1) b.join(4, 1);
  };
  EXPECT_THROW(chunked_components(ranges, import_only), std::logic_error);
  // Range 0 joins 1 → 4 but range 1 never joins back: an export nobody imports.
  RangeFill export_only = [](size_t i, VertexRange, RangePieceBuilder& b) {
    if (i == 0) b.join(1, 4);
  };
  EXPECT_THROW(chunked_components(ranges, export_only), std::logic_error);
  RangeFill both = [](size_t i, VertexRange, RangePieceBuilder& b) {
    if (i == 0) b.join(1, 4);
    if (i == 1) b.join(4, 1);
  };
  EXPECT_EQ(chunked_components(ranges, both).components, 1u);
}

TEST(ChunkedComponents, RangesMustTile) {
  const std::vector<VertexRange> gap = {{0, 3}, {4, 6}};
  const std::vector<RangePieces> pieces(2);
  EXPECT_THROW(merge_range_pieces(gap, pieces), std::logic_error);
}

TEST(ChunkedComponents, ChunkRangesTileEachChunk) {
  std::vector<Chunk> chunks(3);
  const uint32_t ends[] = {10, 11, 40};
  for (int i = 0; i < 3; ++i) {
    chunks[i].vertex_begin = i == 0 ? 0 : ends[i - 1];
    chunks[i].vertex_end = ends[i];
  }
  // At least 8 ranges: 3 parts per chunk, but the one-vertex chunk cannot be cut.
  const std::vector<VertexRange> r = chunk_ranges(chunks, 1u << 20, 8);
  ASSERT_EQ(r.size(), 7u);
  EXPECT_EQ(r.front().begin, 0u);
  EXPECT_EQ(r.back().end, 40u);
  for (size_t i = 1; i < r.size(); ++i) EXPECT_EQ(r[i].begin, r[i - 1].end);
  for (const VertexRange& x : r) EXPECT_GT(x.size(), 0u);
  // No range over max_vertices: the 29-vertex chunk is cut into 3 parts of ≤ 10.
  const std::vector<VertexRange> small = chunk_ranges(chunks, 10, 1);
  EXPECT_EQ(small.size(), 5u);
  for (const VertexRange& x : small) EXPECT_LE(x.size(), 10u);
  EXPECT_TRUE(chunk_ranges({}, 10, 16).empty());
}

// Components of a store's mesh graph (vertices sharing a face), its chunks as the ranges: two
// shapes interleaved along the Hilbert curve, so both spread over many chunks.
TEST(ChunkedComponents, MeshComponentsAcrossStoreChunks) {
  MeshBuffers a = make_icosphere(3), b = make_torus(30, 12, 0.5f, 0.2f);
  const uint32_t offset = a.vertex_count();
  a.positions.insert(a.positions.end(), b.positions.begin(), b.positions.end());
  for (uint32_t v : b.triangles) a.triangles.push_back(v + offset);
  a.positions.insert(a.positions.end(), {5, 5, 5});  // an isolated vertex: no component
  const MeshStore store = MeshStore::build(a.view(), StoreBuildOptions{.faces_per_chunk = 100});
  const MeshView m = store.view();
  ASSERT_GT(m.chunks.size(), 10u);
  RangeFill fill = [&](size_t, VertexRange r, RangePieceBuilder& builder) {
    for (uint32_t v = r.begin; v != r.end; ++v) {
      if (!m.faces_of(v).empty()) builder.add(v);
      for (uint32_t u : m.neighbours(v)) builder.join(v, u);
    }
  };
  const std::vector<VertexRange> ranges = chunk_ranges(m.chunks);
  // Labels: the sphere's vertices one id, the torus's the other, the isolated vertex none.
  std::vector<uint32_t> label(m.vertex_count());
  const ComponentTable t = chunked_component_labels(ranges, fill, label);
  EXPECT_EQ(t.components, 2u);
  EXPECT_GT(t.frontier_records, 0u);
  const auto original = store.original_vertex_ids();
  std::map<uint32_t, uint64_t> sphere, torus;
  for (uint32_t v = 0; v < m.vertex_count(); ++v) {
    if (original[v] == a.vertex_count() - 1) EXPECT_EQ(label[v], kNoComponent);
    else ++(original[v] < offset ? sphere : torus)[label[v]];
  }
  ASSERT_EQ(sphere.size(), 1u);
  ASSERT_EQ(torus.size(), 1u);
  EXPECT_NE(sphere.begin()->first, torus.begin()->first);
  EXPECT_EQ(sphere.begin()->second, uint64_t(offset));
}

}  // namespace
}  // namespace streamcvd
