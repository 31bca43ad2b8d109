// compute_topology_stats(MeshView): the soup version's figures (core/measure/mesh_stats.cpp, its
// conventions in core/mesh/topology_conventions.h) without its global array of edge uses.
//
// Everything the soup version reads off one run of that sorted array (the uses of one edge) is
// here read off one vertex's fan: the faces of v (vertex→face, ascending, a face repeating v
// listed once per corner) give every use of every edge at v, in the same (face, corner) terms.
// Sorted by the other end u they are the runs of the soup version for the edges {v, u}, complete
// (every use of {v, u} is in a face of v). Hence, per vertex and with a fan-sized scratch only:
// - edges, boundary / non-manifold edges, orientation: counted from the smaller end (u > v), so
//   each edge once;
// - non-manifold vertex: an edge at v with > 2 uses, or v's corners falling into several classes
//   when joined across its 2-use edges (the soup version's corner union-find, restricted to v);
// - degenerate and duplicate faces: among the faces v owns (v = their smallest vertex): two
//   faces with the same vertex set have the same owner, so duplicates never cross owners;
// - components (faces joined through shared vertices = v joined to every u of its fan) and
//   boundary loops (v joined to u along each 1-use edge) feed two chunk-wise union-finds.
// Most fans are simple (≤ 16 faces, each holding v once, no two running the same way along an
// edge at v): visit_simple_fan settles those without the sort and the corner union-find, 4× faster
// on the dragon; anything else goes to visit_fan, the general case above.
// Neither vertex→vertex nor the store's flags are read: the fan gives the neighbours anyway, and
// the flags count a face (a,a,b) once on edge {a,b} where TopologyStats counts its two uses.
//
// The zero-area threshold needs the bounding box before the faces are seen; the chunks' boxes
// give it (the store computed them), and the exact box, accumulated in the same pass, checks it:
// when they differ (non-finite coordinates, or a chunk box that is off) the degenerate faces are
// counted again with the exact threshold. So the chunk boxes save a pass, never change a figure.
#include "streamcvd/core/measure/store_stats.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <span>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/chunked_components.h"
#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/mesh/topology_conventions.h"
#include "streamcvd/core/mesh/union_find.h"

namespace streamcvd {
namespace {

using topology::Box;

// An edge use at vertex v, packed so that sorting the keys sorts by the other end u:
// u << 32 | local face << 3 | v's corner slot << 1 | forward (the use runs v → u).
constexpr int kFaceShift = 3;
constexpr uint64_t kMaxFanFaces = uint64_t(1) << (32 - kFaceShift);

uint32_t use_end(uint64_t use) { return uint32_t(use >> 32); }
uint32_t use_corner(uint64_t use) { return uint32_t(use) >> 1; }  // local face · 4 + slot
bool use_forward(uint64_t use) { return use & 1; }

// Valences are small (~6 faces, ~12 uses): insertion sort; big fans fall back to std::sort.
template <typename T>
void sort_small(T* first, T* last) {
  if (last - first > 32) {
    std::sort(first, last);
    return;
  }
  for (T* i = first + (first != last); i < last; ++i) {
    T x = *i;
    T* j = i;
    for (; j > first && x < *(j - 1); --j) *j = *(j - 1);
    *j = x;
  }
}

// Counts of one vertex range, summed over ranges afterwards (integers: any order gives the same).
struct Partial {
  uint64_t referenced = 0, owned_faces = 0, edges = 0, boundary_edges = 0, nonmanifold_edges = 0;
  uint64_t nonmanifold_vertices = 0, duplicate_faces = 0, degenerate_faces = 0;
  bool oriented = true;
  Box box;
};

// Per-thread scratch: the two union-finds of a range, and one fan.
struct Scratch {
  RangePieceBuilder parts, loops;
  std::vector<uint32_t> faces;   // distinct faces of v, ascending
  std::vector<uint64_t> uses;    // edge uses at v (see use_end)
  std::vector<uint32_t> corner;  // union-find over local face · 4 + slot
  std::vector<std::array<uint32_t, 3>> owned;  // vertex sets of the faces v owns
  uint32_t begin = 0;                           // first vertex of the range being visited

  // Whether v makes the join {v, u} (both graphs are symmetric and every vertex is visited):
  // inside the range once, from the smaller end (the builders unite the same either way);
  // across ranges from both ends, which is how the merge pairs them up.
  bool joins(uint32_t v, uint32_t u) const { return u > v || u < begin; }
};

// More than one class among v's corners once joined across its 2-use edges (already united in
// s.corner): a bowtie, or a fan cut by non-manifold or degenerate faces.
bool several_fans(std::span<const uint32_t> tri, uint32_t v, Scratch& s) {
  uint32_t classes = 0;
  for (uint32_t lf = 0; lf < s.faces.size(); ++lf)
    for (uint32_t k = 0; k < 3; ++k) {
      const uint32_t c = lf << 2 | k;
      if (tri[3 * size_t(s.faces[lf]) + k] == v && set_root(s.corner, c) == c && ++classes > 1) return true;
    }
  return false;
}

// The figures of vertex v (referenced, its faces `fan`) into p, its joins into the builders.
void visit_fan(const MeshView& m, uint32_t v, std::span<const uint32_t> fan, double zero, Scratch& s, Partial& p) {
  const auto tri = m.triangles;
  s.faces.clear();
  s.uses.clear();
  s.owned.clear();
  uint64_t corners_at_v = 0;
  for (size_t i = 0; i < fan.size(); ++i) {
    const uint32_t f = fan[i];
    if (i > 0 && f == fan[i - 1]) continue;  // a face repeating v is listed once per corner
    // Out of order, a repeat would pass for another face: its edges counted twice, silently.
    if (i > 0 && f < fan[i - 1])
      throw InputError("compute_topology_stats: the face list of vertex " + std::to_string(v) + " is not ascending");
    const uint64_t lf = s.faces.size();
    if (lf >= kMaxFanFaces)
      throw InputError("compute_topology_stats: vertex " + std::to_string(v) + " has more than " +
                       std::to_string(kMaxFanFaces) + " faces");
    s.faces.push_back(f);
    const uint32_t t[3] = {tri[3 * size_t(f)], tri[3 * size_t(f) + 1], tri[3 * size_t(f) + 2]};
    for (uint32_t k = 0; k < 3; ++k) {
      const uint32_t x = t[k], y = t[k == 2 ? 0 : k + 1];
      corners_at_v += x == v;
      if (x == y) continue;  // self-loop: not an edge
      // The corner of the use that holds v, as the soup version's corner_of picks it.
      if (x == v) s.uses.push_back(uint64_t(y) << 32 | lf << kFaceShift | k << 1 | 1);
      else if (y == v) s.uses.push_back(uint64_t(x) << 32 | lf << kFaceShift | (k == 2 ? 0 : k + 1) << 1);
    }
    if (std::min({t[0], t[1], t[2]}) == v) {  // v owns f
      ++p.owned_faces;
      p.degenerate_faces += topology::degenerate(m.positions, t[0], t[1], t[2], zero);
      s.owned.push_back(topology::vertex_set(t[0], t[1], t[2]));
    }
  }
  // Cheap, and a wrong vertex→face list would otherwise give plausible wrong figures.
  if (corners_at_v != fan.size())
    throw InputError("compute_topology_stats: the face list of vertex " + std::to_string(v) +
                     " does not match its corners in the triangles");

  sort_small(s.uses.data(), s.uses.data() + s.uses.size());
  s.corner.resize(4 * s.faces.size());
  reset_sets(std::span<uint32_t>(s.corner));
  bool nonmanifold = false;
  s.parts.add(v);
  for (size_t i = 0, j; i < s.uses.size(); i = j) {
    const uint32_t u = use_end(s.uses[i]);
    for (j = i + 1; j < s.uses.size() && use_end(s.uses[j]) == u; ++j) {
    }
    const size_t n = j - i;  // faces using edge {v, u}, counted as uses
    const bool joins = s.joins(v, u);
    if (joins) s.parts.join(v, u);
    if (n == 1) {
      if (joins) s.loops.join(v, u);
    } else if (n == 2) {
      join_sets(s.corner, use_corner(s.uses[i]), use_corner(s.uses[i + 1]));
    } else {
      nonmanifold = true;
    }
    if (u < v) continue;  // counted from u
    ++p.edges;
    p.boundary_edges += n == 1;
    p.nonmanifold_edges += n > 2;
    // Two uses: one must run v → u and the other u → v.
    if (n == 2) p.oriented = p.oriented && use_forward(s.uses[i]) != use_forward(s.uses[i + 1]);
  }
  p.nonmanifold_vertices += nonmanifold || several_fans(tri, v, s);

  sort_small(s.owned.data(), s.owned.data() + s.owned.size());
  for (size_t k = 1; k < s.owned.size(); ++k) p.duplicate_faces += s.owned[k] == s.owned[k - 1];
}

// Fast path for the usual vertex: at most kMaxSimpleFan faces, each holding v once and two other
// distinct vertices, no two running the same way along an edge at v. With v rotated first, face
// i is (v, a_i, b_i): its uses at v are v → a_i and b_i → v. All a_i distinct and all b_i
// distinct leave every edge at v with one or two uses, and two only as a_j = b_i: one each way,
// so consistently oriented; faces i, j then share that edge (i's "next" is j), and v is manifold
// iff the next links make one path or one cycle. No sort, no union-find. Returns false, having
// changed nothing, for any other fan (visit_fan handles it).
constexpr size_t kMaxSimpleFan = 16;

bool visit_simple_fan(const MeshView& m, uint32_t v, std::span<const uint32_t> fan, double zero, Scratch& s,
                      Partial& p) {
  const size_t k = fan.size();
  if (k > kMaxSimpleFan) return false;
  const auto tri = m.triangles;
  uint32_t a[kMaxSimpleFan], b[kMaxSimpleFan];
  bool bad = false;
  for (size_t i = 0; i < k; ++i) {
    const uint32_t* t = &tri[3 * size_t(fan[i])];
    const uint32_t t0 = t[0], t1 = t[1], t2 = t[2];
    // Rotate v first without branches: which corner holds v is unpredictable.
    const bool c0 = t0 == v, c1 = t1 == v, c2 = t2 == v;
    a[i] = c0 ? t1 : c1 ? t2 : t0;
    b[i] = c0 ? t2 : c1 ? t0 : t1;
    bad |= (int(c0) + int(c1) + int(c2) != 1) | (a[i] == b[i]);  // also a face listed twice
  }
  for (size_t i = 0; i < k; ++i)
    for (size_t j = i + 1; j < k; ++j) bad |= (a[i] == a[j]) | (b[i] == b[j]);
  if (bad) return false;
  // next[i]: the face j with a_j = b_i (at most one, a distinct), k if none (b_i is a boundary end).
  uint8_t next[kMaxSimpleFan];
  bool has_prev[kMaxSimpleFan] = {};
  size_t open_ends = 0;
  for (size_t i = 0; i < k; ++i) {
    uint8_t n = uint8_t(k);
    for (size_t j = 0; j < k; ++j) n = a[j] == b[i] ? uint8_t(j) : n;
    next[i] = n;
    if (n < k) has_prev[n] = true;
    open_ends += n == k;
  }
  // One fan: a single cycle through all faces, or a single path from the face without predecessor.
  bool one_fan = false;
  if (open_ends <= 1) {
    size_t i = 0;
    if (open_ends == 1)
      while (has_prev[i]) ++i;
    const size_t start = i, end = open_ends ? k : start;
    size_t steps = 0;
    do {
      i = next[i];
      ++steps;
    } while (i != end && steps <= k);
    one_fan = steps == k;
  }

  p.nonmanifold_vertices += !one_fan;
  s.parts.add(v);
  for (size_t j = 0; j < k; ++j) {  // edges {v, a_j}: two uses iff a_j is some b_i
    const uint32_t u = a[j];
    if (s.joins(v, u)) {
      s.parts.join(v, u);
      if (!has_prev[j]) s.loops.join(v, u);
    }
    if (u > v) ++p.edges, p.boundary_edges += !has_prev[j];
  }
  for (size_t i = 0; i < k; ++i) {  // edges {v, b_i} with b_i no a_j: one use
    if (next[i] < k) continue;
    const uint32_t u = b[i];
    if (s.joins(v, u)) {
      s.parts.join(v, u);
      s.loops.join(v, u);
    }
    if (u > v) ++p.edges, ++p.boundary_edges;
  }
  for (size_t i = 0; i < k; ++i) {
    if (a[i] < v || b[i] < v) continue;  // not owned by v
    ++p.owned_faces;
    const uint32_t* t = &tri[3 * size_t(fan[i])];  // the area in the face's own corner order
    p.degenerate_faces += topology::degenerate(m.positions, t[0], t[1], t[2], zero);
    // Same vertex set, a_i ≠ a_j: only (v, x, y) against (v, y, x).
    for (size_t j = i + 1; j < k; ++j) p.duplicate_faces += a[i] == b[j] && b[i] == a[j] && a[j] > v && b[j] > v;
  }
  return true;
}

void visit_range(const MeshView& m, VertexRange r, double zero, Scratch& s, Partial& p) {
  for (uint32_t v = r.begin; v != r.end; ++v) {
    p.box.add(&m.positions[3 * size_t(v)]);
    const std::span<const uint32_t> fan = m.faces_of(v);
    if (fan.empty()) continue;  // isolated: in neither graph
    ++p.referenced;
    if (!visit_simple_fan(m, v, fan, zero, s, p)) visit_fan(m, v, fan, zero, s, p);
  }
}

// Box of the chunks' boxes: the exact box whenever every coordinate is finite.
Box chunk_box(std::span<const Chunk> chunks) {
  Box b;
  for (const Chunk& c : chunks) {
    b.add(c.bbox_min);
    b.add(c.bbox_max);
  }
  return b;
}

}  // namespace

TopologyStats compute_topology_stats(const MeshView& mesh) {
  const uint32_t nv = mesh.vertex_count();
  TopologyStats s;
  s.vertices = nv;
  s.faces = mesh.face_count();
  uint32_t covered = 0;  // the chunks must tile [0, V): each range is visited exactly once
  for (const Chunk& c : mesh.chunks) {
    if (c.vertex_begin != covered || c.vertex_end < c.vertex_begin)
      throw InputError("compute_topology_stats: the chunks do not tile the vertices");
    covered = c.vertex_end;
  }
  if (covered != nv) throw InputError("compute_topology_stats: the chunks do not cover the vertices");
  const std::vector<VertexRange> ranges = chunk_ranges(mesh.chunks);

  const double zero_guess = topology::zero_area(chunk_box(mesh.chunks));
  std::vector<Partial> partial(ranges.size());
  std::vector<RangePieces> parts(ranges.size()), loops(ranges.size());
  tbb::enumerable_thread_specific<Scratch> scratch;
  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, ranges.size(), 1),
      [&](const tbb::blocked_range<size_t>& rr) {
        Scratch& sc = scratch.local();
        for (size_t i = rr.begin(); i != rr.end(); ++i) {
          const RangeVisit visit(mesh, "info", ranges[i], kReadsAllArrays);
          sc.parts.begin(ranges[i]);
          sc.loops.begin(ranges[i]);
          sc.begin = ranges[i].begin;
          visit_range(mesh, ranges[i], zero_guess, sc, partial[i]);
          parts[i] = sc.parts.finish();
          loops[i] = sc.loops.finish();
        }
      },
      tbb::simple_partitioner());

  Partial all;
  for (const Partial& p : partial) {
    all.referenced += p.referenced;
    all.owned_faces += p.owned_faces;
    all.edges += p.edges;
    all.boundary_edges += p.boundary_edges;
    all.nonmanifold_edges += p.nonmanifold_edges;
    all.nonmanifold_vertices += p.nonmanifold_vertices;
    all.duplicate_faces += p.duplicate_faces;
    all.degenerate_faces += p.degenerate_faces;
    all.oriented = all.oriented && p.oriented;
    all.box.merge(p.box);
  }
  if (all.owned_faces != s.faces)
    throw InputError("compute_topology_stats: " + std::to_string(all.owned_faces) + " faces found in the face lists of " +
                     "their smallest vertex, " + std::to_string(s.faces) + " in the triangles");
  all.box.finish(nv > 0 ? &mesh.positions[0] : nullptr);
  const double zero = topology::zero_area(all.box);
  if (!(zero == zero_guess)) {
    const auto tri = mesh.triangles;
    all.degenerate_faces = tbb::parallel_reduce(
        tbb::blocked_range<uint64_t>(0, s.faces, 1 << 14), uint64_t(0),
        [&](const tbb::blocked_range<uint64_t>& r, uint64_t n) {
          for (uint64_t f = r.begin(); f != r.end(); ++f)
            n += topology::degenerate(mesh.positions, tri[3 * f], tri[3 * f + 1], tri[3 * f + 2], zero);
          return n;
        },
        std::plus<>());
  }

  for (int i = 0; i < 3; ++i) s.bbox_min[i] = float(all.box.lo[i]), s.bbox_max[i] = float(all.box.hi[i]);
  s.edges = all.edges;
  s.boundary_edges = all.boundary_edges;
  s.boundary_loops = merge_range_pieces(ranges, loops).components;
  s.nonmanifold_edges = all.nonmanifold_edges;
  s.nonmanifold_vertices = all.nonmanifold_vertices;
  s.duplicate_faces = all.duplicate_faces;
  s.degenerate_faces = all.degenerate_faces;
  s.isolated_vertices = nv - all.referenced;
  s.components = merge_range_pieces(ranges, parts).components;
  s.consistently_oriented = all.oriented;
  topology::derive_figures(s, all.referenced);
  return s;
}

}  // namespace streamcvd
