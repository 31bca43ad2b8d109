// The 1-ring connectivity test of the constrained pass (§VI-B), shared by the serial and the
// parallel clustering loops. Internal header: the label accessor lets the parallel loop read
// labels atomically while the serial loop reads them plainly, with the same logic.
#pragma once

#include <cstdint>

#include "streamcvd/core/mesh/mesh_view.h"
#include "streamcvd/core/mesh/union_find.h"

namespace streamcvd::detail {

/// True when removing v from cluster `a` keeps `a` connected: v's neighbours in `a` are
/// connected through the triangles around v. Conservative: false when the 1-ring holds more
/// than 64 neighbours in `a`. `label(u)` returns the label of vertex u. O(degree²) worst case.
/// Thread-safety: the caller must hold cluster `a` (its member set must not change meanwhile);
/// moves between other clusters do not change the result (only equality with `a` is tested).
template <class LabelOf>
bool removal_keeps_connected(const MeshView& mesh, const LabelOf& label, uint32_t v, int32_t a) {
  uint32_t ids[64];
  uint8_t parent[64];
  int n = 0;
  for (uint32_t u : mesh.neighbours(v))
    if (label(u) == a) {
      if (n == 64) return false;
      parent[n] = uint8_t(n);
      ids[n++] = u;
    }
  if (n <= 1) return n == 1;
  auto index_of = [&](uint32_t u) {
    for (int i = 0; i < n; ++i)
      if (ids[i] == u) return i;
    return -1;
  };
  int groups = n;
  const uint32_t* T = mesh.triangles.data();
  for (uint32_t f : mesh.faces_of(v)) {
    uint32_t c0 = T[3 * f], c1 = T[3 * f + 1], c2 = T[3 * f + 2];
    uint32_t p = c0 == v ? c1 : c0, q = c2 == v ? c1 : c2;
    if (c1 == v) { p = c0; q = c2; }
    if (label(p) != a || label(q) != a || p == q) continue;
    int ip = index_of(p), iq = index_of(q);
    if (ip < 0 || iq < 0) continue;
    groups -= join_sets(std::span<uint8_t>(parent, size_t(n)), uint8_t(ip), uint8_t(iq));
  }
  return groups == 1;
}

}  // namespace streamcvd::detail
