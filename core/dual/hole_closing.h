// Holes below the output resolution (§VI-D): which boundary loops close in the dual instead of
// getting a strip, and the triangles that close them. A strip along a hole narrower than an
// output edge is made of slivers whatever its vertices do (a slit's two sides are a fraction of
// an edge apart), so such a hole is closed: its ring of clusters — the clusters met along the
// loop, in order — is triangulated like any patch of the output. Decided from the labels and
// the input alone, so the repair's labels-only checks (core/dual/defect_tracker.h) and
// build_dual_mesh close the same holes with the same faces. Internal to core/.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd::dual {

/// True when every two vertices of `loop` (ids into the 3·V floats xyz) are closer than
/// `d`. The bounding box decides most loops in O(n); the others are compared pairwise, up to
/// 4096 vertices (larger ones: the box's diagonal decides).
bool diameter_below(std::span<const float> xyz, std::span<const uint32_t> loop, double d);

/// Extent of `loop` across its main direction: the spread of its vertices along the second
/// principal axis of their covariance (a slit's width, a round hole's diameter). O(n).
double loop_width(std::span<const float> xyz, std::span<const uint32_t> loop);

/// Triangulates the ring of clusters around a hole: ring[t] is the cluster the loop enters at
/// its t-th change (distinct, at least 3). Each cluster stands at the mean of the loop vertices
/// it holds (stretch t: loop positions changes[t] + 1 … changes[t + 1]); the triangulation of
/// least total edge length among those (dynamic programming, O(m³), m ≤ 64) whose diagonals
/// join clusters that share no input edge — a diagonal between clusters already neighbours
/// would give their dual edge a third face — is returned as cluster-id triples oriented as the
/// dual faces around the hole (the ring runs against them). Clusters are found neighbours by a
/// flood over the input vertices labelled with ring clusters, from the loop (O(their size)); the
/// hole closes only when that flood also meets a cluster off the ring (the loop bounds a hole in
/// a larger surface, not the whole of a thin piece). `taken`: cluster pairs (smaller id << 32 |
/// larger, sorted) that are diagonals of holes closed before, barred too: two holes closed with
/// the same diagonal give it four faces. Empty when no such triangulation exists.
/// Deterministic, thread-safe (pure).
std::vector<std::array<uint32_t, 3>> triangulate_hole_ring(const MeshView& mesh, std::span<const uint32_t> loop,
                                                           std::span<const uint32_t> changes,
                                                           std::span<const int32_t> ring,
                                                           std::span<const int32_t> labels,
                                                           std::span<const uint64_t> taken = {});

/// The key of the cluster pair {a, b} in triangulate_hole_ring's `taken`.
inline uint64_t cluster_pair_key(uint32_t a, uint32_t b) {
  return a < b ? uint64_t(a) << 32 | b : uint64_t(b) << 32 | a;
}

}  // namespace streamcvd::dual
