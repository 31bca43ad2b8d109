#include "core/adjacency.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cassert>

#include "core/mesh_view.h"

namespace streamcvd {
namespace {

constexpr size_t kVertexGrain = 2048;

// Valences are small (~6): insertion sort beats std::sort there; big fans fall back to it.
template <typename T>
void sort_small(T* first, T* last) {
  if (last - first < 2) return;  // also keeps `first + 1` off a null pointer (no faces at all)
  if (last - first > 32) {
    std::sort(first, last);
    return;
  }
  for (T* i = first + 1; i < last; ++i) {
    T x = *i;
    T* j = i;
    for (; j > first && x < *(j - 1); --j) *j = *(j - 1);
    *j = x;
  }
}

// In-place inclusive prefix sum. Serial: a few ms per 10M entries, memory-bound anyway.
void inclusive_prefix_sum(std::span<uint64_t> a) {
  uint64_t sum = 0;
  for (uint64_t& x : a) {
    sum += x;
    x = sum;
  }
}

// The distinct vertices other than v of each face around v, appended to `out` (v's neighbours,
// with repeats across faces). Faces listed twice in vf(v) (degenerate) are visited once.
void gather_ring(std::span<const uint32_t> triangles, std::span<const uint32_t> faces, uint32_t v,
                 std::vector<uint32_t>& out) {
  out.clear();
  for (size_t k = 0; k < faces.size(); ++k) {
    if (k > 0 && faces[k] == faces[k - 1]) continue;
    const uint32_t* t = &triangles[3 * size_t(faces[k])];
    for (int c = 0; c < 3; ++c)
      if (t[c] != v) out.push_back(t[c]);
  }
  sort_small(out.data(), out.data() + out.size());
  out.erase(std::unique(out.begin(), out.end()), out.end());
}

// Per-thread scratch of compute_vertex_flags.
struct FanScratch {
  std::vector<uint64_t> edges;   // (neighbour << 32) | local face index
  std::vector<uint32_t> parent;  // union-find over local faces
  std::vector<uint8_t> used;     // local face has at least one edge
};

uint32_t find_root(std::vector<uint32_t>& parent, uint32_t x) {
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

// VertexFlag bits of v; with `ring` non-null also writes v's sorted distinct neighbours there
// (the same edge sort yields both, so the fused pass saves one sort per vertex).
uint8_t vertex_flags(std::span<const uint32_t> triangles, std::span<const uint32_t> faces, uint32_t v, FanScratch& s,
                     uint32_t* ring = nullptr) {
  if (faces.empty()) return kVertexIsolated;
  s.edges.clear();
  uint32_t local = 0;
  for (size_t k = 0; k < faces.size(); ++k) {
    if (k > 0 && faces[k] == faces[k - 1]) continue;  // degenerate face listed twice
    const uint32_t* t = &triangles[3 * size_t(faces[k])];
    uint32_t other[2], n = 0;
    for (int c = 0; c < 3; ++c)
      if (t[c] != v && (n == 0 || other[0] != t[c])) other[n++] = t[c];
    for (uint32_t i = 0; i < n; ++i) s.edges.push_back(uint64_t(other[i]) << 32 | local);
    ++local;
  }
  sort_small(s.edges.data(), s.edges.data() + s.edges.size());
  s.parent.resize(local);
  s.used.assign(local, 0);
  for (uint32_t i = 0; i < local; ++i) s.parent[i] = i;
  uint8_t flags = 0;
  for (size_t i = 0; i < s.edges.size();) {
    size_t j = i + 1;
    while (j < s.edges.size() && (s.edges[j] >> 32) == (s.edges[i] >> 32)) ++j;
    const size_t count = j - i;  // faces on edge {v, u}
    if (ring) *ring++ = uint32_t(s.edges[i] >> 32);
    if (count == 1) flags |= kVertexBoundary;
    if (count > 2) flags |= kVertexNonManifold;
    const uint32_t first = uint32_t(s.edges[i]);
    s.used[first] = 1;
    for (size_t k = i + 1; k < j; ++k) {
      const uint32_t f = uint32_t(s.edges[k]);
      s.used[f] = 1;
      s.parent[find_root(s.parent, f)] = find_root(s.parent, first);
    }
    i = j;
  }
  uint32_t fans = 0;
  for (uint32_t i = 0; i < local; ++i) fans += s.used[i] && find_root(s.parent, i) == i;
  if (fans > 1) flags |= kVertexNonManifold;
  return flags;
}

}  // namespace

void build_vertex_face_adjacency(std::span<const uint32_t> triangles, uint32_t vertex_count,
                                 std::vector<uint64_t>& offsets, std::vector<uint32_t>& faces) {
  const size_t corners = triangles.size() - triangles.size() % 3;
  assert(corners / 3 <= UINT32_MAX);
  // Counts go to offsets[v + 2]; after the prefix sum offsets[v + 1] is v's start, and the
  // scatter's fetch_add turns it into v's end = the start of v + 1: CSR without a cursor array.
  offsets.assign(size_t(vertex_count) + 2, 0);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, corners, 1 << 14), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i)
      std::atomic_ref<uint64_t>(offsets[size_t(triangles[i]) + 2]).fetch_add(1, std::memory_order_relaxed);
  });
  inclusive_prefix_sum(offsets);
  faces.resize(corners);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, corners, 1 << 14), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      uint64_t pos =
          std::atomic_ref<uint64_t>(offsets[size_t(triangles[i]) + 1]).fetch_add(1, std::memory_order_relaxed);
      faces[pos] = uint32_t(i / 3);
    }
  });
  offsets.pop_back();
  // The scatter order depends on scheduling; sorting each short list makes it deterministic.
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, vertex_count, kVertexGrain),
                    [&](const tbb::blocked_range<uint32_t>& r) {
                      for (uint32_t v = r.begin(); v != r.end(); ++v)
                        sort_small(faces.data() + offsets[v], faces.data() + offsets[v + 1]);
                    });
}

void build_vertex_vertex_adjacency(std::span<const uint32_t> triangles, std::span<const uint64_t> vf_offsets,
                                   std::span<const uint32_t> vertex_face, std::vector<uint64_t>& offsets,
                                   std::vector<uint32_t>& neighbours, std::span<uint8_t> flags) {
  assert(!vf_offsets.empty());
  const uint32_t vertex_count = uint32_t(vf_offsets.size() - 1);
  tbb::enumerable_thread_specific<std::vector<uint32_t>> scratch;
  auto faces_of = [&](uint32_t v) { return vertex_face.subspan(vf_offsets[v], vf_offsets[v + 1] - vf_offsets[v]); };
  // Pass 1: count distinct neighbours into offsets[v + 1].
  offsets.assign(size_t(vertex_count) + 1, 0);
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, vertex_count, kVertexGrain),
                    [&](const tbb::blocked_range<uint32_t>& r) {
                      std::vector<uint32_t>& ring = scratch.local();
                      for (uint32_t v = r.begin(); v != r.end(); ++v) {
                        gather_ring(triangles, faces_of(v), v, ring);
                        offsets[size_t(v) + 1] = ring.size();
                      }
                    });
  inclusive_prefix_sum(offsets);
  // Pass 2: recompute each ring (cheaper than holding 2·3F candidate entries) and copy it out.
  neighbours.resize(offsets.back());
  if (!flags.empty()) {
    assert(flags.size() == vertex_count);
    tbb::enumerable_thread_specific<FanScratch> fans;
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, vertex_count, kVertexGrain),
                      [&](const tbb::blocked_range<uint32_t>& r) {
                        FanScratch& s = fans.local();
                        for (uint32_t v = r.begin(); v != r.end(); ++v)
                          flags[v] = vertex_flags(triangles, faces_of(v), v, s, neighbours.data() + offsets[v]);
                      });
    return;
  }
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, vertex_count, kVertexGrain),
                    [&](const tbb::blocked_range<uint32_t>& r) {
                      std::vector<uint32_t>& ring = scratch.local();
                      for (uint32_t v = r.begin(); v != r.end(); ++v) {
                        gather_ring(triangles, faces_of(v), v, ring);
                        assert(ring.size() == offsets[size_t(v) + 1] - offsets[v]);
                        std::copy(ring.begin(), ring.end(), neighbours.begin() + ptrdiff_t(offsets[v]));
                      }
                    });
}

void compute_vertex_flags(std::span<const uint32_t> triangles, std::span<const uint64_t> vf_offsets,
                          std::span<const uint32_t> vertex_face, std::span<uint8_t> flags) {
  assert(!vf_offsets.empty() && flags.size() + 1 == vf_offsets.size());
  tbb::enumerable_thread_specific<FanScratch> scratch;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, uint32_t(flags.size()), kVertexGrain),
                    [&](const tbb::blocked_range<uint32_t>& r) {
                      FanScratch& s = scratch.local();
                      for (uint32_t v = r.begin(); v != r.end(); ++v)
                        flags[v] = vertex_flags(
                            triangles, vertex_face.subspan(vf_offsets[v], vf_offsets[v + 1] - vf_offsets[v]), v, s);
                    });
}

}  // namespace streamcvd
