// The quality post-pass (core/dual/mesh_optimize.h): half-edge twins, max-min Q flips, tangential
// relaxation and the projection back onto the input by a walk in its faces.
#include "streamcvd/core/dual/mesh_optimize.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <string>
#include <utility>

#include "streamcvd/core/mesh/bvh.h"
#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/mesh/triangle_quality.h"
#include "streamcvd/core/mesh/vec3.h"
#include "streamcvd/core/mesh/vertex_faces.h"

namespace streamcvd {

namespace {

using namespace vec3;  // Vec3, sub, add, scale, dot, cross, norm, unit, point

// Twice the area vector of (a, b, c): its direction is the face normal.
Vec3 area_vector(const Vec3& a, const Vec3& b, const Vec3& c) { return cross(sub(b, a), sub(c, a)); }

constexpr int64_t kNoTwin = -1;

uint32_t next_in_face(uint32_t h) { return h - h % 3 + (h + 1) % 3; }
uint32_t prev_in_face(uint32_t h) { return h - h % 3 + (h + 2) % 3; }

// Twin half-edge of every half-edge h = 3f + k (edge T[h] → T[next_in_face(h)]); kNoTwin on
// boundary edges, non-manifold edges (more than two faces) and edges used twice in the same
// direction. O(F · valence) through the vertex-face CSR, in parallel: a pair of twins is
// written only from its half-edge leaving the smaller end, so no two tasks write one entry.
std::vector<int64_t> build_twins(std::span<const uint32_t> T, size_t V) {
  std::vector<uint32_t> offsets, faces;
  build_vertex_faces(T, V, offsets, faces);
  std::vector<int64_t> twin(T.size(), kNoTwin);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, T.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t h = r.begin(); h != r.end(); ++h) {
      const uint32_t a = T[h], b = T[next_in_face(uint32_t(h))];
      if (a >= b) continue;  // each edge once, from its smaller end
      uint32_t sharing = 0;
      int64_t reverse = kNoTwin;
      for (uint32_t i = offsets[a]; i < offsets[a + 1]; ++i) {
        const uint32_t f = faces[i];
        for (uint32_t g = 3 * f; g < 3 * f + 3; ++g) {
          if (T[g] == b) ++sharing;
          if (T[g] == b && T[next_in_face(g)] == a) reverse = g;
        }
      }
      if (sharing == 2 && reverse != kNoTwin) twin[h] = reverse, twin[size_t(reverse)] = int64_t(h);
    }
  });
  return twin;
}

// The mesh being optimized with its maintained connectivity.
struct Work {
  std::span<float> P;
  std::span<uint32_t> T;
  std::vector<int64_t> twin;         // kept valid by the flips
  std::vector<uint32_t> face_count;  // faces per vertex (unchanged by moves; flips shift it)
  std::vector<double> q;             // Q of every face, kept current
  double cos_max_dihedral = 1;  // flips only between faces bent less than this
};

double face_quality(const Work& w, size_t f) {
  return triangle_quality(point(w.P, w.T[3 * f]), point(w.P, w.T[3 * f + 1]), point(w.P, w.T[3 * f + 2]));
}

// True when vertex c already has neighbour d, or when c's faces do not form one fan (a
// non-manifold vertex: refuse, its other fans are not visited). Rotates around c through
// twins from half-edge h_out (c → x), both ways when the fan is open. O(valence).
bool has_neighbour_or_unsafe(const Work& w, uint32_t h_out, uint32_t d) {
  const uint32_t c = w.T[h_out];
  uint32_t faces = 0;
  uint32_t h = h_out;
  bool closed = false;
  for (;;) {  // clockwise: c → x, then the incoming y → c of the same face, twin = c → y
    ++faces;
    if (w.T[next_in_face(h)] == d || w.T[prev_in_face(h)] == d) return true;
    const int64_t t = w.twin[prev_in_face(h)];
    if (t == kNoTwin) break;
    h = uint32_t(t);
    if (h == h_out) {
      closed = true;
      break;
    }
    if (faces > w.face_count[c]) return true;
  }
  if (!closed) {
    h = h_out;
    for (;;) {  // the other way: twin of c → x is x → c, its next is c → z
      const int64_t t = w.twin[h];
      if (t == kNoTwin) break;
      h = next_in_face(uint32_t(t));
      ++faces;
      if (w.T[next_in_face(h)] == d || w.T[prev_in_face(h)] == d) return true;
      if (faces > w.face_count[c]) return true;
    }
  }
  return faces != w.face_count[c];
}

// Flips the edge of half-edge h when that raises the smaller Q of its two triangles (Lawson's
// max-min flip, with Q instead of the smallest angle). Returns true when flipped.
bool try_flip(Work& w, uint32_t h) {
  const int64_t hg = w.twin[h];
  if (hg == kNoTwin) return false;
  const uint32_t f = h / 3, g = uint32_t(hg) / 3;
  auto& T = w.T;
  const uint32_t a = T[h], b = T[next_in_face(h)], c = T[prev_in_face(h)];
  const uint32_t d = T[prev_in_face(uint32_t(hg))];
  if (c == d || a == b) return false;
  const Vec3 pa = point(w.P, a), pb = point(w.P, b), pc = point(w.P, c), pd = point(w.P, d);
  const Vec3 nf = unit(area_vector(pa, pb, pc)), ng = unit(area_vector(pb, pa, pd));
  // A sliver's normal says nothing about the surface (strip triangles at scan holes): next to
  // one, the well-shaped triangle alone gives the plane the new pair must stay in.
  const bool sliver = std::min(w.q[f], w.q[g]) < kSliverQuality;
  if (!sliver && dot(nf, ng) < w.cos_max_dihedral) return false;
  const double q_old = std::min(w.q[f], w.q[g]);
  const double q1 = triangle_quality(pa, pd, pc), q2 = triangle_quality(pd, pb, pc);
  // A relative margin: equal-quality pairs (a square's two diagonals) must not flip back and forth.
  if (std::min(q1, q2) <= q_old * (1 + 1e-6) + 1e-12) return false;
  // The new pair must be as flat as the old and keep its orientation: no fold, no zero area.
  const Vec3 n1 = area_vector(pa, pd, pc), n2 = area_vector(pd, pb, pc);
  const Vec3 n_old = !sliver ? add(nf, ng) : w.q[f] >= w.q[g] ? nf : ng;
  if (dot(n1, n_old) <= 0 || dot(n2, n_old) <= 0) return false;
  if (dot(unit(n1), unit(n2)) < w.cos_max_dihedral) return false;
  if (has_neighbour_or_unsafe(w, prev_in_face(h), d)) return false;  // c → a; would duplicate edge c-d
  const int64_t x1 = w.twin[next_in_face(h)], x2 = w.twin[prev_in_face(h)];
  const int64_t y1 = w.twin[next_in_face(uint32_t(hg))], y2 = w.twin[prev_in_face(uint32_t(hg))];
  // New faces (a, d, c) and (d, b, c) keep the orientation of the old pair (a, b, c), (b, a, d).
  T[3 * f] = a, T[3 * f + 1] = d, T[3 * f + 2] = c;
  T[3 * g] = d, T[3 * g + 1] = b, T[3 * g + 2] = c;
  auto link = [&](int64_t x, int64_t y) {
    w.twin[size_t(x)] = y;
    if (y != kNoTwin) w.twin[size_t(y)] = x;
  };
  link(3 * f, y1);             // a → d
  link(3 * f + 1, 3 * g + 2);  // d → c / c → d
  link(3 * f + 2, x2);         // c → a
  link(3 * g, y2);             // d → b
  link(3 * g + 1, x1);         // b → c
  --w.face_count[a], --w.face_count[b], ++w.face_count[c], ++w.face_count[d];
  w.q[f] = q1;
  w.q[g] = q2;
  return true;
}

// Flips from the queued half-edges until no flip helps (each flip raises the sorted Q vector
// lexicographically, so this terminates; the cap only bounds float ties). Returns the flips.
uint64_t flip_pass(Work& w, std::vector<uint32_t>& stack, std::vector<uint8_t>& queued) {
  uint64_t flips = 0;
  const uint64_t cap = 4 * uint64_t(w.T.size()) + 100;
  while (!stack.empty() && flips < cap) {
    const uint32_t h = stack.back();
    stack.pop_back();
    queued[h] = 0;
    if (w.twin[h] == kNoTwin || queued[size_t(w.twin[h])]) continue;  // its twin is queued anyway
    const uint32_t f = h / 3, g = uint32_t(w.twin[h]) / 3;
    if (!try_flip(w, h)) continue;
    ++flips;
    for (uint32_t e : {3 * f, 3 * f + 2, 3 * g, 3 * g + 1})
      if (!queued[e]) stack.push_back(e), queued[e] = 1;
  }
  for (uint32_t h : stack) queued[h] = 0;
  stack.clear();
  return flips;
}

// Vertices that may move: movable, with a surface face to project from, interior (no
// boundary or non-manifold edge) and not on a feature (no incident edge bent more than the
// feature angle). Decided once, on the input geometry of the pass.
std::vector<uint8_t> free_vertices(const Work& w, std::span<const uint8_t> movable, std::span<const uint32_t> surface_face,
                                   bool have_surface, double cos_feature) {
  const size_t V = w.P.size() / 3;
  std::vector<uint8_t> free(V, 0);
  for (size_t v = 0; v < V; ++v)
    free[v] = movable[v] && (!have_surface || surface_face[v] != UINT32_MAX) && w.face_count[v] > 0;
  // Which edges pin their ends, in parallel (one flag per half-edge), then applied in order.
  std::vector<uint8_t> pins(w.T.size(), 0);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, w.T.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t h = r.begin(); h != r.end(); ++h) {
      bool pinned = w.twin[h] == kNoTwin;
      if (!pinned && w.twin[h] > int64_t(h)) {
        const size_t f = h / 3, g = size_t(w.twin[h]) / 3;
        const Vec3 nf = unit(area_vector(point(w.P, w.T[3 * f]), point(w.P, w.T[3 * f + 1]), point(w.P, w.T[3 * f + 2])));
        const Vec3 ng = unit(area_vector(point(w.P, w.T[3 * g]), point(w.P, w.T[3 * g + 1]), point(w.P, w.T[3 * g + 2])));
        // A sliver's normal says nothing about the surface (strip triangles along holes, needles):
        // only a bend between two well-shaped triangles is a feature.
        pinned = dot(nf, ng) < cos_feature && std::min(w.q[f], w.q[g]) >= kSliverQuality;
      }
      pins[h] = pinned;
    }
  });
  for (size_t h = 0; h < w.T.size(); ++h)
    if (pins[h]) free[w.T[h]] = free[w.T[next_in_face(uint32_t(h))]] = 0;
  // A vertex whose faces form more than one fan (a defect left in the output) stays: tested
  // from its first half-edge, one vertex per task.
  std::vector<uint32_t> first_out(V, UINT32_MAX);
  for (size_t h = w.T.size(); h-- > 0;) first_out[w.T[h]] = uint32_t(h);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, V, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t v = r.begin(); v != r.end(); ++v)
      if (free[v] && first_out[v] != UINT32_MAX) free[v] = !has_neighbour_or_unsafe(w, first_out[v], UINT32_MAX);
  });
  return free;
}

struct RelaxParams {
  double step = 1, cos_normal_change = 0;
};

// Tangential relaxation of vertex v: a move towards the mean of its neighbours (uniform
// Laplacian, tangential part only), kept when the ring's Q sum rises, its smallest Q stays above
// min(old smallest, 0.5) and no ring triangle turns by more than the limit. The move stays in
// the tangent plane: the projection onto the surface is done once at the end (project_moved).
// Reads v's ring, writes v's position and its ring faces' Q. Returns true when v moved.
bool relax_vertex(Work& w, uint32_t v, std::span<const uint32_t> ring, const RelaxParams& params,
                  std::vector<Vec3>& old_normal) {
  const Vec3 p = point(w.P, v);
  Vec3 mean{0, 0, 0}, normal{0, 0, 0};
  double q_min_old = 1, q_sum_old = 0, edge_sum = 0;
  old_normal.clear();
  for (uint32_t f : ring) {
    const uint32_t* t = &w.T[3 * size_t(f)];
    const int kv = t[0] == v ? 0 : (t[1] == v ? 1 : 2);
    const Vec3 u = point(w.P, t[(kv + 1) % 3]), x = point(w.P, t[(kv + 2) % 3]);
    const Vec3 n = area_vector(p, u, x);
    // Each neighbour of an interior vertex is a corner of two ring faces: the mean of the
    // edge midpoints opposite v is the mean of the neighbours.
    mean = add(mean, scale(add(u, x), 0.5));
    edge_sum += norm(sub(u, p));
    normal = add(normal, n);
    old_normal.push_back(unit(n));
    q_min_old = std::min(q_min_old, w.q[f]);
    q_sum_old += w.q[f];
  }
  normal = unit(normal);
  Vec3 delta = sub(scale(mean, 1.0 / double(ring.size())), p);
  delta = sub(delta, scale(normal, dot(delta, normal)));  // tangential part only
  if (norm(delta) * params.step < 0.01 * edge_sum / double(ring.size())) return false;  // nothing to gain
  const Vec3 target = add(p, scale(delta, params.step));
  double q_min_new = 1, q_sum_new = 0;
  bool ok = true;
  for (size_t i = 0; i < ring.size() && ok; ++i) {
    const uint32_t* t = &w.T[3 * size_t(ring[i])];
    const int kv = t[0] == v ? 0 : (t[1] == v ? 1 : 2);
    const Vec3 u = point(w.P, t[(kv + 1) % 3]), x = point(w.P, t[(kv + 2) % 3]);
    // Slivers may turn (that is how they fatten) but not fold over.
    ok = dot(unit(area_vector(target, u, x)), old_normal[i]) >=
         (w.q[ring[i]] >= kSliverQuality ? params.cos_normal_change : 1e-3);
    const double q = triangle_quality(target, u, x);
    q_min_new = std::min(q_min_new, q);
    q_sum_new += q;
  }
  if (!ok || q_sum_new <= q_sum_old || q_min_new < std::min(q_min_old, 0.5)) return false;
  for (int k = 0; k < 3; ++k) w.P[3 * size_t(v) + k] = float(target[k]);
  for (uint32_t f : ring) w.q[f] = face_quality(w, f);  // of the float-rounded position
  return true;
}

// One sweep of tangential relaxation (relax_vertex) over the `active` vertices of `order`,
// colour class by colour class, each class in parallel (the result does not depend on the
// thread count). Marks moved vertices in `moved`; returns how many moved.
uint64_t relax_sweep(Work& w, std::span<const uint32_t> vf_offsets, std::span<const uint32_t> vf,
                     std::span<const uint32_t> order, std::span<const uint8_t> active, const RelaxParams& params,
                     std::vector<uint8_t>& moved) {
  std::vector<uint32_t> begin;
  const std::vector<uint32_t> classes = colour_classes(w.T, vf_offsets, vf, order, active, begin);
  auto ring_of = [&](uint32_t v) { return vf.subspan(vf_offsets[v], vf_offsets[v + 1] - vf_offsets[v]); };
  tbb::enumerable_thread_specific<std::vector<Vec3>> normals;
  for (uint32_t k = 0; k < kSerialColour; ++k)
    tbb::parallel_for(tbb::blocked_range<uint32_t>(begin[k], begin[k + 1], 512), [&](const tbb::blocked_range<uint32_t>& r) {
      std::vector<Vec3>& old_normal = normals.local();
      for (uint32_t i = r.begin(); i != r.end(); ++i)
        if (relax_vertex(w, classes[i], ring_of(classes[i]), params, old_normal)) moved[classes[i]] = 1;
    });
  std::vector<Vec3> old_normal;
  for (uint32_t i = begin[kSerialColour]; i < begin[kSerialColour + 1]; ++i)
    if (relax_vertex(w, classes[i], ring_of(classes[i]), params, old_normal)) moved[classes[i]] = 1;
  uint64_t moves = 0;
  for (const uint32_t v : classes) moves += moved[v];
  return moves;
}

// The chunk of `surface` owning face f (faces are sorted by owner vertex, chunk by chunk).
size_t chunk_of_face(const MeshView& surface, uint32_t f) {
  const auto ends_after = [](uint64_t face, const Chunk& c) { return face < c.face_end; };
  const auto it = std::upper_bound(surface.chunks.begin(), surface.chunks.end(), uint64_t(f), ends_after);
  return std::min<size_t>(size_t(it - surface.chunks.begin()), surface.chunks.size() - 1);
}

// The runs of `vertices` (sorted by surface face) whose faces lie in one chunk of `surface`:
// (first index, the chunk's vertices), closed by (vertices.size(), {}). One run with no
// vertex range when the surface has no chunks. O(n log chunks).
std::vector<std::pair<size_t, VertexRange>> runs_by_chunk(const MeshView& surface,
                                                          std::span<const uint32_t> surface_face,
                                                          std::span<const uint32_t> vertices) {
  std::vector<std::pair<size_t, VertexRange>> runs;
  size_t current = SIZE_MAX;
  for (size_t i = 0; i < vertices.size(); ++i) {
    const size_t c = surface.chunks.empty() ? 0 : chunk_of_face(surface, surface_face[vertices[i]]);
    if (c == current) continue;
    current = c;
    runs.push_back({i, surface.chunks.empty() ? VertexRange{}
                                              : VertexRange{surface.chunks[c].vertex_begin, surface.chunks[c].vertex_end}});
  }
  runs.push_back({vertices.size(), {}});
  return runs;
}

// Puts every moved vertex back onto the surface: the closest surface point of its tangent-plane
// position, plus its original offset from the surface when keep_offset (QEM points). The
// tangent-plane drift is second order (move² · curvature), so Q barely changes; a vertex whose
// projection would turn a ring triangle over keeps its tangent-plane position. Returns the
// vertices placed on the surface.
uint64_t project_moved(Work& w, const MeshView& surface, std::span<uint32_t> surface_face,
                       std::span<const uint32_t> order, std::span<const uint8_t> moved, std::span<const Vec3> original,
                       bool keep_offset) {
  std::vector<uint32_t> vf_offsets, vf;
  build_vertex_faces(w.T, w.P.size() / 3, vf_offsets, vf);
  // The walks, in parallel: each reads its own vertex's position and face only.
  std::vector<uint32_t> to_place;
  for (const uint32_t v : order)
    if (moved[v]) to_place.push_back(v);
  std::vector<Vec3> targets(to_place.size());
  std::vector<uint32_t> faces(to_place.size());
  auto walk = [&](size_t i) {
    const uint32_t v = to_place[i];
    Vec3 offset{0, 0, 0}, q;
    if (keep_offset) {
      surface_face[v] = closest_point_walk(surface, surface_face[v], original[v], q);
      offset = sub(original[v], q);
    }
    faces[i] = closest_point_walk(surface, surface_face[v], sub(point(w.P, v), offset), q);
    targets[i] = add(q, offset);
  };
  // `order` is sorted by surface face: the walks starting in one chunk of the input are one run
  // of it, visited with the chunk read ahead (out of core, faults one by one read 3x the input).
  // Out of core a walk that leaves its chunk faults a page in: read that page only.
  const auto runs = runs_by_chunk(surface, surface_face, to_place);
  const ScatteredReads scattered(surface);
  tbb::parallel_for(size_t(0), runs.size() - 1, [&](size_t k) {
    const RangeVisit visit(surface, "optimize", runs[k].second, kReadsPositions | kReadsTriangles | kReadsVertexFaces);
    tbb::parallel_for(tbb::blocked_range<size_t>(runs[k].first, runs[k + 1].first, 256), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) walk(i);
    });
  });
  // Applied in order: a move is refused when it would turn a ring face over, the ring as the
  // earlier moves left it.
  uint64_t projected = 0;
  for (size_t i = 0; i < to_place.size(); ++i) {
    const uint32_t v = to_place[i], face = faces[i];
    const Vec3 p = point(w.P, v), target = targets[i];
    bool ok = true;
    for (uint32_t i = vf_offsets[v]; i < vf_offsets[v + 1] && ok; ++i) {
      const uint32_t* t = &w.T[3 * size_t(vf[i])];
      const int kv = t[0] == v ? 0 : (t[1] == v ? 1 : 2);
      const Vec3 u = point(w.P, t[(kv + 1) % 3]), x = point(w.P, t[(kv + 2) % 3]);
      ok = dot(area_vector(target, u, x), area_vector(p, u, x)) > 0;
    }
    if (!ok) continue;
    for (int k = 0; k < 3; ++k) w.P[3 * size_t(v) + k] = float(target[k]);
    surface_face[v] = face;
    for (uint32_t i = vf_offsets[v]; i < vf_offsets[v + 1]; ++i) w.q[vf[i]] = face_quality(w, vf[i]);
    ++projected;
  }
  return projected;
}

// The relaxation sweeps (each followed by flips where vertices moved), then the projection of
// the moved vertices onto the surface (when there is one). Returns the vertices moved; adds the
// flips to `flips`.
uint64_t relax_and_project(Work& w, std::span<const uint8_t> movable, const MeshView* surface,
                           std::span<uint32_t> surface_face, const MeshOptimizeOptions& options,
                           std::vector<uint32_t>& stack, std::vector<uint8_t>& queued, uint64_t& flips) {
  const double deg = std::numbers::pi / 180;
  const size_t V = w.P.size() / 3;
  const std::span<const float> positions = w.P;
  const std::span<const uint32_t> triangles = w.T;
  const std::vector<uint8_t> free =
      free_vertices(w, movable, surface_face, surface != nullptr, std::cos(options.feature_angle_deg * deg));
  std::vector<uint32_t> order;
  for (uint32_t v = 0; v < V; ++v)
    if (free[v]) order.push_back(v);
  // By surface face (the input's faces are in spatial order): the projection walks then visit
  // the input surface in a cache-friendly order.
  if (surface)
    std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) { return surface_face[a] < surface_face[b]; });
  std::vector<Vec3> original(V);
  for (uint32_t v : order) original[v] = point(positions, v);
  std::vector<uint8_t> active = free, moved(V, 0), ever_moved(V, 0);
  std::vector<uint32_t> vf_offsets, vf;
  const RelaxParams params{options.relax_step, std::cos(options.max_normal_change_deg * deg)};
  for (uint32_t it = 0; it < options.relax_iterations; ++it) {
    build_vertex_faces(triangles, V, vf_offsets, vf);
    std::fill(moved.begin(), moved.end(), 0);
    if (relax_sweep(w, vf_offsets, vf, order, active, params, moved) == 0) break;
    // Flips and the next sweep only where something moved: the faces around moved vertices.
    std::fill(active.begin(), active.end(), 0);
    for (size_t v = 0; v < V; ++v) {
      if (!moved[v]) continue;
      ever_moved[v] = 1;
      for (uint32_t i = vf_offsets[v]; i < vf_offsets[v + 1]; ++i)
        for (uint32_t h = 3 * vf[i]; h < 3 * vf[i] + 3; ++h) {
          active[triangles[h]] = free[triangles[h]];
          if (!queued[h]) stack.push_back(h), queued[h] = 1;
        }
    }
    flips += flip_pass(w, stack, queued);
  }
  uint64_t moves = 0;
  for (uint32_t v : order) moves += ever_moved[v];
  if (surface) project_moved(w, *surface, surface_face, order, ever_moved, original, options.keep_surface_offset);
  return moves;
}

}  // namespace

// A straight walk in the surface (Devillers et al. 2002, "Walking in a triangulation") towards
// the face whose plane projection of p has non-negative barycentric coordinates, crossing the
// edge opposite the most negative one.
uint32_t closest_point_walk(const MeshView& s, uint32_t face, const std::array<double, 3>& p, std::array<double, 3>& q) {
  auto corner = [&](uint32_t f, int k) { return point(s.positions, s.triangles[3 * size_t(f) + k]); };
  uint32_t previous = UINT32_MAX;
  for (int step = 0; step < 32; ++step) {
    const uint32_t* t = &s.triangles[3 * size_t(face)];
    const Vec3 a = point(s.positions, t[0]), b = point(s.positions, t[1]), c = point(s.positions, t[2]);
    const Vec3 n = area_vector(a, b, c);
    const double nn = dot(n, n);
    if (nn <= 0) break;
    // Unnormalized barycentric coordinates of p's projection on the face's plane.
    const double w[3] = {dot(cross(sub(c, b), sub(p, b)), n), dot(cross(sub(a, c), sub(p, c)), n),
                         dot(cross(sub(b, a), sub(p, a)), n)};
    if (w[0] >= 0 && w[1] >= 0 && w[2] >= 0) {
      q = sub(p, scale(n, dot(sub(p, a), n) / nn));
      return face;
    }
    const int k = w[0] <= w[1] && w[0] <= w[2] ? 0 : (w[1] <= w[2] ? 1 : 2);
    const uint32_t u = t[(k + 1) % 3], v = t[(k + 2) % 3];
    // The face across edge u-v: the other face in both (ascending) face lists.
    uint32_t next = UINT32_MAX;
    const auto fu = s.faces_of(u), fv = s.faces_of(v);
    for (size_t i = 0, j = 0; i < fu.size() && j < fv.size();) {
      if (fu[i] < fv[j]) ++i;
      else if (fv[j] < fu[i]) ++j;
      else if (fu[i] == face) ++i, ++j;
      else {
        next = fu[i];
        break;
      }
    }
    if (next == UINT32_MAX || next == previous) break;
    previous = face;
    face = next;
  }
  // Stopped on a boundary, a crease or a degenerate face: the closer of the last two faces.
  q = closest_point_on_triangle(p, corner(face, 0), corner(face, 1), corner(face, 2));
  if (previous != UINT32_MAX) {
    const Vec3 r = closest_point_on_triangle(p, corner(previous, 0), corner(previous, 1), corner(previous, 2));
    if (dot(sub(r, p), sub(r, p)) < dot(sub(q, p), sub(q, p))) {
      q = r;
      return previous;
    }
  }
  return face;
}


double average_triangle_quality(std::span<const float> positions, std::span<const uint32_t> triangles) {
  const size_t F = triangles.size() / 3;
  if (F == 0) return 0;
  double sum = 0;
  for (size_t f = 0; f < F; ++f)
    sum += triangle_quality(point(positions, triangles[3 * f]), point(positions, triangles[3 * f + 1]),
                   point(positions, triangles[3 * f + 2]));
  return sum / double(F);
}

namespace {

// The connectivity and face qualities the passes maintain. O(F · valence), in parallel. Throws
// InputError for a triangle index ≥ V (`caller` names the function in the message).
Work make_work(std::span<float> positions, std::span<uint32_t> triangles, const MeshOptimizeOptions& options,
               const char* caller) {
  const size_t V = positions.size() / 3, F = triangles.size() / 3;
  for (uint32_t v : triangles)
    if (v >= V)
      throw InputError(std::string(caller) + ": a triangle uses vertex " + std::to_string(v) + " of " + std::to_string(V));
  Work w{positions, triangles, build_twins(triangles, V), std::vector<uint32_t>(V, 0), std::vector<double>(F),
         std::cos(options.flip_max_dihedral_deg * std::numbers::pi / 180)};
  tbb::parallel_for(tbb::blocked_range<size_t>(0, F, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t f = r.begin(); f != r.end(); ++f) w.q[f] = face_quality(w, f);
  });
  for (uint32_t v : triangles) ++w.face_count[v];
  return w;
}

}  // namespace

uint64_t flip_edges_near(std::span<float> positions, std::span<uint32_t> triangles, std::span<const uint8_t> near,
                         const MeshOptimizeOptions& options) {
  if (near.size() != positions.size() / 3) throw InputError("flip_edges_near: near needs one entry per vertex");
  Work w = make_work(positions, triangles, options, "flip_edges_near");
  std::vector<uint32_t> stack;
  std::vector<uint8_t> queued(triangles.size(), 0);
  for (size_t h = triangles.size(); h-- > 0;)
    if (w.twin[h] > int64_t(h) && (near[triangles[h]] || near[triangles[next_in_face(uint32_t(h))]]))
      stack.push_back(uint32_t(h)), queued[h] = 1;
  return flip_pass(w, stack, queued);
}

MeshOptimizeReport optimize_mesh_quality(std::span<float> positions, std::span<uint32_t> triangles,
                                         std::span<const uint8_t> movable, const MeshView* surface,
                                         std::span<uint32_t> surface_face, const MeshOptimizeOptions& options) {
  MeshOptimizeReport report;
  const size_t V = positions.size() / 3, F = triangles.size() / 3;
  if (movable.size() != V || (surface && surface_face.size() != V) || triangles.size() != 3 * F)
    throw InputError("optimize_mesh_quality: movable and surface_face need one entry per vertex");
  Work w = make_work(positions, triangles, options, "optimize_mesh_quality");
  double q_sum = 0;
  for (size_t f = 0; f < F; ++f) q_sum += w.q[f];
  report.q_avg_before = F ? q_sum / double(F) : 0;

  std::vector<uint32_t> stack;
  std::vector<uint8_t> queued(triangles.size(), 0);
  for (size_t h = triangles.size(); h-- > 0;)
    if (w.twin[h] > int64_t(h)) stack.push_back(uint32_t(h)), queued[h] = 1;
  report.flips += flip_pass(w, stack, queued);

  if (options.relax_iterations > 0) report.moves = relax_and_project(w, movable, surface, surface_face, options, stack, queued, report.flips);
  q_sum = 0;
  for (size_t f = 0; f < F; ++f) q_sum += w.q[f];
  report.q_avg_after = F ? q_sum / double(F) : 0;
  return report;
}

}  // namespace streamcvd
