#include "streamcvd/streaming/store/subdivision_stream.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/store/store.h"

namespace streamcvd {

void stream_subdivision(const MeshView& mesh, MeshSink& sink, ArrayStorage& storage, VertexAttributeRows attributes,
                        uint32_t block) {
  const uint32_t V = mesh.vertex_count();
  const uint64_t F = mesh.face_count();
  // first_edge[v]: index of v's first upper edge {v, u > v}; neighbour lists are sorted.
  LargeArray<uint64_t> first_edge(size_t(V) + 1, storage, "subdivision edge offsets");
  auto upper = [&](uint32_t v) {
    const auto nb = mesh.neighbours(v);
    return nb.subspan(size_t(std::upper_bound(nb.begin(), nb.end(), v) - nb.begin()));
  };
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, V, 1 << 14), [&](const tbb::blocked_range<uint32_t>& r) {
    for (uint32_t v = r.begin(); v != r.end(); ++v) first_edge[v + 1] = upper(v).size();
  });
  for (uint32_t v = 0; v < V; ++v) first_edge[v + 1] += first_edge[v];
  const uint64_t E = first_edge[V];
  if (uint64_t(V) + E > std::numeric_limits<uint32_t>::max())
    throw InputError("subdivision: " + std::to_string(uint64_t(V) + E) + " vertices, at most 2^32-1 supported");

  MeshHeaderInfo header;
  header.vertices = uint64_t(V) + E;
  header.faces = 4 * F;  // an upper bound: faces repeating a vertex are copied once
  header.vertices_before_triangles = true;
  header.attributes.assign(attributes.names.begin(), attributes.names.end());
  const size_t A = attributes.names.size();
  if (A > 0 && attributes.values.size() != A * V)
    throw std::invalid_argument("subdivision: " + std::to_string(attributes.values.size()) + " attribute values for " +
                                std::to_string(V) + " vertices of " + std::to_string(A) + " attributes");
  sink.begin(header);
  const float* P = mesh.positions.data();
  const float* X = attributes.values.data();
  std::vector<float> xyz, rows;
  for (uint32_t v0 = 0; v0 < V; v0 += block) {
    const uint32_t v1 = uint32_t(std::min<uint64_t>(V, uint64_t(v0) + block));
    sink.vertices({P + 3 * size_t(v0), 3 * size_t(v1 - v0)}, A ? attributes.values.subspan(A * v0, A * (v1 - v0)) : std::span<const float>());
  }
  // Midpoints, a block of vertices' upper edges at a time.
  for (uint32_t v0 = 0; v0 < V;) {
    uint32_t v1 = v0;
    while (v1 < V && first_edge[v1 + 1] - first_edge[v0] <= block) ++v1;
    if (v1 == v0) ++v1;  // a vertex with more upper edges than a block
    xyz.resize(3 * size_t(first_edge[v1] - first_edge[v0]));
    rows.resize(A * size_t(first_edge[v1] - first_edge[v0]));
    tbb::parallel_for(tbb::blocked_range<uint32_t>(v0, v1, 1024), [&](const tbb::blocked_range<uint32_t>& r) {
      for (uint32_t v = r.begin(); v != r.end(); ++v) {
        size_t at = 3 * size_t(first_edge[v] - first_edge[v0]), row = A * size_t(first_edge[v] - first_edge[v0]);
        for (uint32_t u : upper(v)) {
          for (int c = 0; c < 3; ++c) xyz[at++] = 0.5f * (P[3 * size_t(v) + c] + P[3 * size_t(u) + c]);
          for (size_t k = 0; k < A; ++k) rows[row++] = float(0.5 * (double(X[A * v + k]) + double(X[A * u + k])));
        }
      }
    });
    sink.vertices(xyz, rows);
    v0 = v1;
  }
  // Faces: the midpoint of {a, b} is V + first_edge[lo] + the rank of hi among lo's upper edges.
  auto midpoint = [&](uint32_t a, uint32_t b) {
    const uint32_t lo = std::min(a, b), hi = std::max(a, b);
    const auto up = upper(lo);
    return uint32_t(V + first_edge[lo] + uint64_t(std::lower_bound(up.begin(), up.end(), hi) - up.begin()));
  };
  const uint32_t* T = mesh.triangles.data();
  std::vector<uint32_t> tri;
  std::vector<uint32_t> count;
  const uint64_t faces_per_block = std::max<uint64_t>(1, block / 4);
  for (uint64_t f0 = 0; f0 < F; f0 += faces_per_block) {
    const uint64_t f1 = std::min(F, f0 + faces_per_block);
    tri.resize(12 * size_t(f1 - f0));
    count.assign(size_t(f1 - f0), 0);
    tbb::parallel_for(tbb::blocked_range<uint64_t>(f0, f1, 2048), [&](const tbb::blocked_range<uint64_t>& r) {
      for (uint64_t f = r.begin(); f != r.end(); ++f) {
        const uint32_t a = T[3 * f], b = T[3 * f + 1], c = T[3 * f + 2];
        uint32_t* out = &tri[12 * size_t(f - f0)];
        if (a == b || b == c || a == c) {
          out[0] = a, out[1] = b, out[2] = c;
          count[f - f0] = 1;
          continue;
        }
        const uint32_t ab = midpoint(a, b), bc = midpoint(b, c), ca = midpoint(c, a);
        const uint32_t t[12] = {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca};
        std::copy(t, t + 12, out);
        count[f - f0] = 4;
      }
    });
    // Compact the copied degenerate faces (rare) so that faces stay in order.
    size_t n = 0;
    for (uint64_t i = 0; i < f1 - f0; ++i)
      for (uint32_t k = 0; k < 3 * count[i]; ++k) tri[n++] = tri[12 * i + k];
    sink.triangles({tri.data(), n});
  }
  ReadStats stats;
  stats.vertices = header.vertices;
  sink.end(stats);
}

MeshBuffers subdivide_linear(const TriangleSoupView& soup) {
  const MeshStore store = MeshStore::build(soup, {.hilbert_order = false, .clean_topology = false});  // the soup as given
  struct Collect final : MeshSink {
    MeshBuffers out;
    void begin(const MeshHeaderInfo&) override {}
    void vertices(std::span<const float> xyz, std::span<const float>) override {
      out.positions.insert(out.positions.end(), xyz.begin(), xyz.end());
    }
    void triangles(std::span<const uint32_t> c) override { out.triangles.insert(out.triangles.end(), c.begin(), c.end()); }
    void end(const ReadStats&) override {}
  } collect;
  // The store keeps the soup's vertex ids (no Hilbert order); its faces come in owner order, so
  // the soup's own triangles stand in for them to keep the input face order (only the neighbour
  // lists are read besides).
  MeshView view = store.view();
  view.triangles = soup.triangles;
  stream_subdivision(view, collect);
  return std::move(collect.out);
}

}  // namespace streamcvd
