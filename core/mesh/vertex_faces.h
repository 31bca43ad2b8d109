// The vertex → face CSR of a triangle list in RAM (an output mesh: the quality pass, the strip
// shaping, the flat-face safety net). The store's own CSR is built by the store build
// (streaming/store/adjacency.h); this one is for meshes that change as a pass edits them.
#pragma once

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

}  // namespace streamcvd
