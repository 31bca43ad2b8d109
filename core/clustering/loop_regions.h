// The regions of the parallel clustering loop (core/clustering/parallel_clustering.cpp): contiguous
// vertex ranges of the Hilbert-ordered store (a region never straddles two chunks), which
// region each vertex is in and whether all its neighbours are, and per partition the census
// that tells in O(1) which clusters one region holds alone. Internal header.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "streamcvd/core/mesh/large_array.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd::detail {

constexpr uint32_t kMaxRegions = 65535;  // region ids are 16-bit

// Contiguous vertex ranges (Hilbert order: spatially compact) and, per vertex, whether all its
// neighbours lie in its own range.
struct Partition {
  std::vector<uint32_t> begin;  // regions + 1 boundaries, from 0 to V
  LargeArray<uint8_t> interior;
  LargeArray<uint16_t> region;  // region of each vertex (at most kMaxRegions regions)
  uint32_t size() const { return uint32_t(begin.size() - 1); }
};

// Per-cluster census under one partition, kept exact through every move, so that a cluster's
// owner is found in O(1) per loop instead of a scan of all vertices: c lies in region r alone
// iff Σ region = n·r and Σ region² = n·r² (n = its vertex count; equality in Cauchy-Schwarz).
// With region < 2^16 and n < 2^32 the sums are exact in 64 bits.
struct Census {
  std::vector<uint32_t> boundary;   // vertices of the cluster that are not region-interior
  std::vector<uint64_t> sum, sum2;  // Σ region, Σ region²
  void move(const Partition& p, uint32_t u, int32_t from, int32_t to) {
    const uint64_t r = p.region[u];
    const uint32_t b = !p.interior[u];
    boundary[from] -= b;
    boundary[to] += b;
    sum[from] -= r;
    sum[to] += r;
    sum2[from] -= r * r;
    sum2[to] += r * r;
  }
};


/// Region boundaries (regions + 1 entries, from 0 to V): each store chunk split into pieces of
/// about `length` vertices, at most kMaxRegions regions. Depends only on the chunk table and V.
std::vector<uint32_t> region_bounds(const MeshView& mesh, uint32_t length);

/// The boundaries shifted by half a region: clusters cut by one partition are inside the other.
std::vector<uint32_t> shifted_bounds(const std::vector<uint32_t>& bounds);

/// A partition of `bounds` with its per-vertex arrays allocated from `storage`, to be filled by
/// mark_vertex for every vertex (ParallelLoop::run does it in its one pass over the neighbour
/// lists). O(regions); the arrays are V bytes and 2·V bytes.
Partition allocate_partition(uint32_t vertex_count, std::vector<uint32_t> bounds, ArrayStorage& storage);

/// Records that vertex v with sorted neighbour list `nb` lies in region r of `p`: interior when
/// every neighbour does too (the first and last bound them all). O(1); distinct vertices may be
/// marked concurrently.
inline void mark_vertex(Partition& p, uint32_t r, uint32_t v, std::span<const uint32_t> nb) {
  p.region[v] = uint16_t(r);
  p.interior[v] = nb.empty() || (nb.front() >= p.begin[r] && nb.back() < p.begin[r + 1]);
}

/// The census of `labels` (−1 skipped) under partition `p`, for `cluster_count` clusters. O(V),
/// serial on purpose: three plain adds per vertex (~1 ms per million vertices) cost less than the
/// atomic adds a parallel accumulation would need. Visits `mesh`'s chunks in turn (work arrays).
Census make_census(const MeshView& mesh, const Partition& p, std::span<const int32_t> labels, uint32_t cluster_count);

}  // namespace streamcvd::detail
