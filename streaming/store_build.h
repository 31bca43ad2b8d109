// Passes of the in-RAM store build (MeshStore::build, streaming/store.h), one function each.
// Internal to the store: store.cpp runs them in order and hands each finished array to the writer.
// All are TBB-parallel and deterministic (the output never depends on the number of threads).
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "core/default_init_vector.h"
#include "core/mesh_view.h"

namespace streamcvd::store_build {

/// Axis-aligned box of the finite coordinates added to it.
struct Bbox {
  float lo[3] = {std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity(),
                 std::numeric_limits<float>::infinity()};
  float hi[3] = {-std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                 -std::numeric_limits<float>::infinity()};
  void add(const float* p) {
    for (int k = 0; k < 3; ++k)
      if (std::isfinite(p[k])) lo[k] = std::min(lo[k], p[k]), hi[k] = std::max(hi[k], p[k]);
  }
  void add(const Bbox& b) {
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], b.lo[k]), hi[k] = std::max(hi[k], b.hi[k]);
  }
  // An empty box (no finite coordinate on an axis) becomes [0, 0] on that axis.
  void finish() {
    for (int k = 0; k < 3; ++k)
      if (!(lo[k] <= hi[k])) lo[k] = hi[k] = 0;
  }
};

/// Bounding box of the finite coordinates of vertices [begin, end). Parallel, O(end - begin).
Bbox bounding_box(std::span<const float> positions, size_t begin, size_t end);

// Smallest i in [0, n) with bad(i), or n. Parallel and deterministic.
template <typename Pred>
uint64_t first_violation(uint64_t n, Pred bad) {
  return tbb::parallel_reduce(
      tbb::blocked_range<uint64_t>(0, n, 1 << 16), n,
      [&](const tbb::blocked_range<uint64_t>& r, uint64_t found) {
        for (uint64_t i = r.begin(); i != r.end() && i < found; ++i)
          if (bad(i)) return i;
        return found;
      },
      [](uint64_t a, uint64_t b) { return std::min(a, b); });
}

/// Throws InputError unless positions and triangles are multiples of 3, V and F < 2^32 and every
/// index < V. Parallel O(F).
void check_soup(const TriangleSoupView& soup);

/// Input vertex id of each store vertex (order.size() = V): sorted by (Hilbert key in the grid of
/// `box`, input id). O(V) counting sort + small per-cell sorts; parallel.
void hilbert_order(std::span<const float> positions, const Bbox& box, std::span<uint32_t> order);

/// Input faces `in` remapped by new_of_old into `out` (3F), stably counting-sorted by owner
/// (smallest new vertex id), corner order kept; owned gets V+1 entries (faces of owner v are
/// [owned[v], owned[v+1])). A non-empty `in_place` must view the same memory as `in`, which is
/// then remapped in place first (one lookup per corner instead of two). O(F + V); parallel.
void sort_faces_by_owner(std::span<const uint32_t> in, std::span<uint32_t> in_place,
                         std::span<const uint32_t> new_of_old, DefaultInitVector<uint32_t>& owned,
                         DefaultInitVector<uint32_t>& out);

/// Chunk vertex and face ranges: round(F / target) chunks of ~target owned faces, cut between
/// vertices (owned as above). O(C log V).
std::vector<Chunk> cut_chunks(std::span<const uint32_t> owned, uint64_t target);

/// Bounding box and halo1/halo3 face counts of every chunk of `m` (its chunks' ranges set).
/// Parallel over chunks, O(V + F + halo sizes).
void chunk_extras(const MeshView& m, std::span<Chunk> chunks);

}  // namespace streamcvd::store_build
