#include "streamcvd/streaming/store/adjacency.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <cassert>
#include <cstring>
#include <utility>

#include "streamcvd/core/mesh/mesh_view.h"
#include "streamcvd/core/mesh/union_find.h"
#include "streamcvd/streaming/store/counting_sort.h"

namespace streamcvd {
namespace {

constexpr size_t kVertexGrain = 2048;
// Vertices per block of build_vertex_vertex_adjacency (fixed: the blocks define its layout).
constexpr uint64_t kRingBlock = 4096;
constexpr uint32_t kPrefetchAhead = 8;  // vertices
constexpr uint32_t kScanBlocks = 64;  // vertex blocks of the parallel prefix sums

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

// Sorts a[0, n) for n ≤ 8 with Batcher's 19-comparator network on 8 slots padded with the
// largest value: branch-free, where insertion sort mispredicts on nearly every neighbour.
void sort8_padded(uint32_t* a, uint32_t n) {
  uint32_t x[8];
  for (uint32_t i = 0; i < 8; ++i) x[i] = i < n ? a[i] : UINT32_MAX;
  auto cmp = [&](int i, int j) {
    const uint32_t lo = std::min(x[i], x[j]), hi = std::max(x[i], x[j]);
    x[i] = lo;
    x[j] = hi;
  };
  cmp(0, 1), cmp(2, 3), cmp(4, 5), cmp(6, 7);
  cmp(0, 2), cmp(1, 3), cmp(4, 6), cmp(5, 7);
  cmp(1, 2), cmp(5, 6), cmp(0, 4), cmp(3, 7);
  cmp(1, 5), cmp(2, 6);
  cmp(1, 4), cmp(3, 6);
  cmp(2, 4), cmp(3, 5);
  cmp(3, 4);
  for (uint32_t i = 0; i < n; ++i) a[i] = x[i];
}

// In-place inclusive prefix sum, in parallel over kScanBlocks blocks (their totals, then each
// block from its base): integer sums, so the same result for any split.
void inclusive_prefix_sum(std::span<uint64_t> a) {
  auto block_begin = [&](uint32_t k) { return a.size() * k / kScanBlocks; };
  std::array<uint64_t, kScanBlocks + 1> base{};
  tbb::parallel_for(uint32_t(0), kScanBlocks, [&](uint32_t k) {
    uint64_t total = 0;
    for (size_t i = block_begin(k); i != block_begin(k + 1); ++i) total += a[i];
    base[k + 1] = total;
  });
  for (uint32_t k = 0; k < kScanBlocks; ++k) base[k + 1] += base[k];
  tbb::parallel_for(uint32_t(0), kScanBlocks, [&](uint32_t k) {
    uint64_t sum = base[k];
    for (size_t i = block_begin(k); i != block_begin(k + 1); ++i) a[i] = sum += a[i];
  });
}

// Splits [0, n) into `parts` nearly equal ranges; part p is [range_begin(n, parts, p), range_begin(n, parts, p + 1)).
uint32_t range_begin(uint32_t n, uint32_t parts, uint32_t p) { return uint32_t(uint64_t(n) * p / parts); }

// Number of vertex ranges for the scan-based passes: one per thread (each scans all corners, so
// more ranges than threads only costs), at most 8. The output never depends on it.
uint32_t scan_parts(uint32_t vertex_count) {
  const int threads = tbb::this_task_arena::max_concurrency();
  return std::max<uint32_t>(1, std::min<uint32_t>({uint32_t(std::max(threads, 1)), 8u, vertex_count}));
}

// Per-thread scratch of compute_vertex_flags.
struct FanScratch {
  std::vector<uint64_t> edges;   // (neighbour << 32) | local face index
  std::vector<uint32_t> parent;  // union-find over local faces
  std::vector<uint8_t> used;     // local face has at least one edge
  std::vector<uint32_t> ring;    // a ring that may not fit its destination
};

// Fast path of vertex_flags for the usual vertex: at most kMaxSimpleFan distinct faces, each
// with v once and consistently oriented, forming one closed fan (a cycle) or one open fan (a
// path). With v rotated first, face i is (v, a_i, b_i); faces i and j share an edge {v, u} iff
// b_i == a_j == u. All a_i distinct and all b_i distinct means no edge has more than two faces;
// the fan is then one cycle or one path of the "next" map b_i → a_j. Returns false (nothing
// written) for anything else, which vertex_flags handles in general. Needs no sort of edges, only
// of the ≤ k + 1 neighbours.
constexpr size_t kMaxSimpleFan = 16;

bool simple_fan(std::span<const uint32_t> triangles, std::span<const uint32_t> faces, uint32_t v, uint8_t& flags,
                uint32_t& ring_size, uint32_t* ring) {
  const size_t k = faces.size();
  if (k == 0 || k > kMaxSimpleFan) return false;
  uint32_t a[kMaxSimpleFan + 1], b[kMaxSimpleFan];  // a also receives the open end's b
  bool bad = false;
  for (size_t i = 0; i < k; ++i) {
    const uint32_t* t = &triangles[3 * size_t(faces[i])];
    const uint32_t t0 = t[0], t1 = t[1], t2 = t[2];
    // Rotate v first without branches: which corner holds v is unpredictable.
    const bool c0 = t0 == v, c1 = t1 == v;
    a[i] = c0 ? t1 : c1 ? t2 : t0;
    b[i] = c0 ? t2 : c1 ? t0 : t1;
    bad |= (a[i] == v) | (b[i] == v) | (a[i] == b[i]);  // degenerate (also a face listed twice)
  }
  for (size_t i = 0; i < k; ++i)
    for (size_t j = i + 1; j < k; ++j) bad |= (a[i] == a[j]) | (b[i] == b[j]);
  if (bad) return false;
  // next[i]: the face after i around v (its a is i's b), or k at an open end.
  uint8_t next[kMaxSimpleFan + 1];
  size_t open_ends = 0, start = 0;
  bool is_next_of_some[kMaxSimpleFan + 1] = {};
  for (size_t i = 0; i < k; ++i) {
    uint8_t n = uint8_t(k);
    for (size_t j = 0; j < k; ++j) n = a[j] == b[i] ? uint8_t(j) : n;  // a_j distinct: at most one
    next[i] = n;
    is_next_of_some[n] = true;
    open_ends += n == k;
  }
  next[k] = uint8_t(k);
  if (open_ends > 1) return false;
  if (open_ends == 1)
    while (start < k && is_next_of_some[start]) ++start;  // the path's first face
  // One fan iff walking from `start` first reaches the end (k for a path, start for a cycle)
  // after exactly k steps. Fixed trip count, no data-dependent exit.
  const size_t end = open_ends ? k : start;
  size_t i = start;
  bool one_fan = true;
  for (size_t step = 1; step < k; ++step) {
    i = next[i];
    one_fan &= i != end;
  }
  if (!one_fan || next[i] != end) return false;
  flags = open_ends ? kVertexBoundary : 0;
  ring_size = uint32_t(k + open_ends);  // the a_i, plus the open end's b
  if (ring) {
    if (open_ends) a[k] = b[i];  // i is the path's last face
    if (ring_size <= 8) {
      sort8_padded(a, ring_size);
    } else {
      sort_small(a, a + ring_size);
    }
    std::copy(a, a + ring_size, ring);
  }
  return true;
}

// VertexFlag bits of v and its number of distinct neighbours; with `ring` non-null also writes
// them there, ascending (the same edge sort yields all three).
uint8_t vertex_flags(std::span<const uint32_t> triangles, std::span<const uint32_t> faces, uint32_t v, FanScratch& s,
                     uint32_t& ring_size, uint32_t* ring = nullptr) {
  ring_size = 0;
  if (faces.empty()) return kVertexIsolated;
  if (uint8_t flags = 0; simple_fan(triangles, faces, v, flags, ring_size, ring)) return flags;
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
  reset_sets(std::span<uint32_t>(s.parent));
  uint8_t flags = 0;
  for (size_t i = 0; i < s.edges.size();) {
    size_t j = i + 1;
    while (j < s.edges.size() && (s.edges[j] >> 32) == (s.edges[i] >> 32)) ++j;
    const size_t count = j - i;  // faces on edge {v, u}
    if (ring) ring[ring_size] = uint32_t(s.edges[i] >> 32);
    ++ring_size;
    if (count == 1) flags |= kVertexBoundary;
    if (count > 2) flags |= kVertexNonManifold;
    const uint32_t first = uint32_t(s.edges[i]);
    s.used[first] = 1;
    for (size_t k = i + 1; k < j; ++k) {
      const uint32_t f = uint32_t(s.edges[k]);
      s.used[f] = 1;
      join_sets(s.parent, f, first);
    }
    i = j;
  }
  uint32_t fans = 0;
  for (uint32_t i = 0; i < local; ++i) fans += s.used[i] && set_root(s.parent, i) == i;
  if (fans > 1) flags |= kVertexNonManifold;
  return flags;
}

}  // namespace

template <typename Offsets, typename Indices>
void build_vertex_face_adjacency(std::span<const uint32_t> triangles, uint32_t first_vertex, uint32_t vertex_count,
                                 Offsets& offsets, Indices& faces) {
  const size_t corners = triangles.size() - triangles.size() % 3;
  assert(corners / 3 <= UINT32_MAX);
  // Corners of the range, as local vertex ids; others map to vertex_count (a sink slot).
  auto local = [&](size_t i) {
    const uint32_t v = triangles[i] - first_vertex;  // wraps for ids below the range
    return v < vertex_count ? v : vertex_count;
  };
  offsets.resize(size_t(vertex_count) + 2);
  if (counting_sort_parts(corners) > 1 && corners <= UINT32_MAX) {
    // A stable counting sort of the corners by local vertex (the sink last): one pass over the
    // corners per phase, and lists come out ascending (face order). 32-bit cursors, hence the
    // corner limit.
    counting_sort(
        corners, vertex_count + 1, local, offsets,
        [&](uint64_t i, uint32_t at) {
          if (at < faces.size()) faces[at] = uint32_t(i / 3);  // the sink bucket comes last: beyond the size
        },
        [&] { faces.resize(offsets[vertex_count]); });  // a no-op for a reused array of that size
    offsets.pop_back();
    return;
  }
  // One task, or too many corners for 32-bit cursors: each task owns a vertex range and scans
  // every corner in face order, keeping its own (no atomics, lists ascending without a sort).
  // Counts go to offsets[v + 2]; after the prefix sum offsets[v + 1] is v's start, and the fill
  // turns it into v's end = the start of v + 1: CSR without a cursor array.
  std::fill(offsets.begin(), offsets.end(), 0);
  const uint32_t parts = scan_parts(vertex_count);
  auto each_part = [&](auto&& body) {
    tbb::parallel_for(uint32_t(0), parts, [&](uint32_t p) {
      const uint32_t lo = range_begin(vertex_count, parts, p), hi = range_begin(vertex_count, parts, p + 1);
      for (size_t i = 0; i < corners; ++i)
        if (const uint32_t v = local(i); v >= lo && v < hi) body(v, i);
    });
  };
  each_part([&](uint32_t v, size_t) { ++offsets[size_t(v) + 2]; });
  inclusive_prefix_sum(offsets);
  faces.resize(offsets[size_t(vertex_count) + 1]);
  each_part([&](uint32_t v, size_t i) { faces[offsets[size_t(v) + 1]++] = uint32_t(i / 3); });
  offsets.pop_back();
}

template <typename Offsets, typename Indices>
void build_vertex_vertex_adjacency(std::span<const uint32_t> triangles, uint32_t first_vertex,
                                   std::span<const uint64_t> vf_offsets, std::span<const uint32_t> vertex_face,
                                   Offsets& offsets, Indices& neighbours, std::span<uint8_t> flags) {
  assert(!vf_offsets.empty());
  assert(flags.empty() || flags.size() + 1 == vf_offsets.size());
  const uint32_t vertex_count = uint32_t(vf_offsets.size() - 1);
  auto faces_of = [&](uint32_t v) { return vertex_face.subspan(vf_offsets[v], vf_offsets[v + 1] - vf_offsets[v]); };
  // One pass: each block of kRingBlock vertices writes its rings back to back into a slot of
  // sum(deg_f + 1) entries at `slot_begin(b)` (a vertex of one fan has at most deg_f + 1
  // neighbours, so the slots hold nearly every block), recording exact sizes; the blocks are then
  // moved down to their final offsets in order (each moves left: in place). A block whose rings
  // do not fit (many vertices of several fans) goes to a side buffer instead, and the layout is
  // then copied into an exact array. Block boundaries are fixed, so the result does not depend
  // on the threads.
  const uint64_t n_blocks = (uint64_t(vertex_count) + kRingBlock - 1) / kRingBlock;
  auto block_begin = [&](uint64_t b) { return uint32_t(std::min<uint64_t>(b * kRingBlock, vertex_count)); };
  auto slot_begin = [&](uint64_t b) { return vf_offsets[block_begin(b)] + block_begin(b); };
  offsets.resize(size_t(vertex_count) + 1);  // every entry is written below
  offsets[0] = 0;
  neighbours.resize(vf_offsets[vertex_count] + vertex_count);
  std::vector<uint64_t> block_size(n_blocks, 0);
  std::vector<std::vector<uint32_t>> side(n_blocks);  // blocks that overflowed their slot (rare)
  tbb::enumerable_thread_specific<FanScratch> fans;
  tbb::parallel_for(uint64_t(0), n_blocks, [&](uint64_t b) {
    FanScratch& s = fans.local();
    const uint64_t slot_end = slot_begin(b + 1);
    uint64_t at = slot_begin(b);
    std::vector<uint32_t>* spill = nullptr;
    const uint32_t block_end = block_begin(b + 1);
    for (uint32_t v = block_begin(b); v != block_end; ++v) {
      // The faces of a vertex a few ahead are fetched while this one is worked on: the fan
      // test is bound by the latency of those scattered triangle reads.
      if (v + kPrefetchAhead < block_end)
        for (uint32_t f : faces_of(v + kPrefetchAhead)) __builtin_prefetch(&triangles[3 * size_t(f)]);
      const auto faces = faces_of(v);
      s.ring.resize(2 * faces.size());  // ≤ 2 new neighbours per face
      const bool direct = !spill && at + 2 * faces.size() <= slot_end;
      uint32_t* out = direct ? neighbours.data() + at : s.ring.data();
      uint32_t size = 0;
      const uint8_t f = vertex_flags(triangles, faces, first_vertex + v, s, size, out);
      if (!flags.empty()) flags[v] = f;
      offsets[size_t(v) + 1] = size;
      if (!direct && !spill && at + size <= slot_end) {
        std::copy(out, out + size, neighbours.data() + at);
      } else if (!direct) {
        if (!spill) {  // switch this block to its side buffer, with what it already wrote
          spill = &side[b];
          spill->assign(neighbours.data() + slot_begin(b), neighbours.data() + at);
        }
        spill->insert(spill->end(), out, out + size);
      }
      at += size;
    }
    block_size[b] = at - slot_begin(b);
  });
  inclusive_prefix_sum(offsets);
  const uint64_t total = offsets.back();
  const bool spilled = std::any_of(side.begin(), side.end(), [](const auto& v) { return !v.empty(); });
  if (!spilled) {
    // Serial and in order: block b's target offsets[first of b] ≤ slot_begin(b), and it may
    // overlap earlier blocks' slots, which have moved already.
    for (uint64_t b = 0; b < n_blocks; ++b) {
      const uint32_t* from = neighbours.data() + slot_begin(b);
      uint32_t* to = neighbours.data() + offsets[block_begin(b)];
      if (from != to && block_size[b] > 0) std::memmove(to, from, block_size[b] * sizeof(uint32_t));
    }
    neighbours.resize(total);
    return;
  }
  Indices exact(total);
  tbb::parallel_for(uint64_t(0), n_blocks, [&](uint64_t b) {
    const uint32_t* from = side[b].empty() ? neighbours.data() + slot_begin(b) : side[b].data();
    std::copy(from, from + block_size[b], exact.data() + offsets[block_begin(b)]);
  });
  neighbours.swap(exact);
}

template void build_vertex_face_adjacency(std::span<const uint32_t>, uint32_t, uint32_t, std::vector<uint64_t>&,
                                          std::vector<uint32_t>&);
template void build_vertex_face_adjacency(std::span<const uint32_t>, uint32_t, uint32_t, DefaultInitVector<uint64_t>&,
                                          DefaultInitVector<uint32_t>&);
template void build_vertex_vertex_adjacency(std::span<const uint32_t>, uint32_t, std::span<const uint64_t>,
                                            std::span<const uint32_t>, std::vector<uint64_t>&, std::vector<uint32_t>&,
                                            std::span<uint8_t>);
template void build_vertex_vertex_adjacency(std::span<const uint32_t>, uint32_t, std::span<const uint64_t>,
                                            std::span<const uint32_t>, DefaultInitVector<uint64_t>&,
                                            DefaultInitVector<uint32_t>&, std::span<uint8_t>);

void compute_vertex_flags(std::span<const uint32_t> triangles, std::span<const uint64_t> vf_offsets,
                          std::span<const uint32_t> vertex_face, std::span<uint8_t> flags) {
  assert(!vf_offsets.empty() && flags.size() + 1 == vf_offsets.size());
  tbb::enumerable_thread_specific<FanScratch> scratch;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, uint32_t(flags.size()), kVertexGrain),
                    [&](const tbb::blocked_range<uint32_t>& r) {
                      FanScratch& s = scratch.local();
                      uint32_t size = 0;
                      for (uint32_t v = r.begin(); v != r.end(); ++v)
                        flags[v] = vertex_flags(
                            triangles, vertex_face.subspan(vf_offsets[v], vf_offsets[v + 1] - vf_offsets[v]), v, s,
                            size);
                    });
}

}  // namespace streamcvd
