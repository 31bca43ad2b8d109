// The vertex → face CSR of a triangle list in RAM (an output mesh: the quality pass, the strip
// shaping, the flat-face safety net). The store's own CSR is built by the store build
// (streaming/store/adjacency.h); this one is for meshes that change as a pass edits them.
#pragma once

#include <bit>
#include <cstdint>
#include <span>
#include <vector>

namespace streamcvd {

/// Faces around each of the V vertices of `T` (3 indices per face): vertex v's faces are
/// faces[offsets[v] .. offsets[v + 1]), ascending. Faces whose first index is `removed` are left
/// out (a pass that marks deleted faces so). O(V + F), serial, no allocation beyond the outputs
/// (reused across calls).
inline void build_vertex_faces(std::span<const uint32_t> T, size_t V, std::vector<uint32_t>& offsets,
                               std::vector<uint32_t>& faces, uint32_t removed = UINT32_MAX) {
  offsets.assign(V + 1, 0);
  for (size_t f = 0; f < T.size(); f += 3)
    if (T[f] != removed)
      for (int i = 0; i < 3; ++i) ++offsets[T[f + i] + 1];
  for (size_t v = 0; v < V; ++v) offsets[v + 1] += offsets[v];
  faces.resize(offsets[V]);
  std::vector<uint32_t> fill(offsets.begin(), offsets.end() - 1);
  for (size_t f = 0; f < T.size(); f += 3)
    if (T[f] != removed)
      for (int i = 0; i < 3; ++i) faces[fill[T[f + i]]++] = uint32_t(f / 3);
}

/// Colour of the vertices that share a face with too many colours around them: they go alone.
constexpr uint32_t kSerialColour = 64;

/// The vertices v of `order` with active[v] ≠ 0 in colour classes, for Gauss-Seidel passes run
/// class by class in parallel: greedily, in `order`, each takes the smallest colour no vertex of
/// its faces has, so no two vertices of a class share a face and a class's moves are independent
/// (the result does not depend on the thread count). Vertices with every colour below
/// kSerialColour around them form class kSerialColour, to be run one at a time. Returns the
/// classes' vertices, class k at [begin[k], begin[k + 1]), each in `order`'s order.
/// O(Σ face-list sizes), serial; 1 byte per vertex of T.
inline std::vector<uint32_t> colour_classes(std::span<const uint32_t> T, std::span<const uint32_t> offsets,
                                            std::span<const uint32_t> faces, std::span<const uint32_t> order,
                                            std::span<const uint8_t> active, std::vector<uint32_t>& begin) {
  std::vector<uint8_t> colour(offsets.size() - 1, UINT8_MAX);
  begin.assign(kSerialColour + 2, 0);
  for (const uint32_t v : order) {
    if (!active[v]) continue;
    uint64_t used = 0;
    for (uint32_t i = offsets[v]; i < offsets[v + 1]; ++i)
      for (uint32_t h = 3 * faces[i]; h < 3 * faces[i] + 3; ++h)
        if (colour[T[h]] < kSerialColour) used |= uint64_t(1) << colour[T[h]];
    colour[v] = uint8_t(~used ? uint32_t(std::countr_zero(~used)) : kSerialColour);
    ++begin[colour[v] + 1];
  }
  for (uint32_t k = 0; k <= kSerialColour; ++k) begin[k + 1] += begin[k];
  std::vector<uint32_t> classes(begin.back());
  std::vector<uint32_t> fill(begin.begin(), begin.end() - 1);
  for (const uint32_t v : order)
    if (active[v]) classes[fill[colour[v]]++] = v;
  return classes;
}

}  // namespace streamcvd
