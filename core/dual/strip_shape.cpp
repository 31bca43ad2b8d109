// Strip shaping (core/dual/strip_shape.h): slides strip vertices along the input boundary and
// moves the cluster vertices around them to lower Σ 1/Q over their fans.
#include "streamcvd/core/dual/strip_shape.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <vector>

#include "streamcvd/core/dual/mesh_optimize.h"
#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/mesh/triangle_quality.h"
#include "streamcvd/core/mesh/vec3.h"
#include "streamcvd/core/mesh/vertex_faces.h"

namespace streamcvd {

namespace {

using namespace vec3;  // Vec3, sub, add, scale, dot, cross, norm, unit, point
// What the output will hold: the candidate rounded to float32, so the Q judged is the Q written.
Vec3 as_float(const Vec3& p) { return {double(float(p[0])), double(float(p[1])), double(float(p[2]))}; }

// Distance from q to the segment a-b.
double segment_distance(const Vec3& q, const Vec3& a, const Vec3& b) {
  const Vec3 ab = sub(b, a), aq = sub(q, a);
  const double l2 = dot(ab, ab);
  const double t = l2 > 0 ? std::clamp(dot(aq, ab) / l2, 0.0, 1.0) : 0.0;
  return norm(sub(aq, scale(ab, t)));
}

// A point of an input boundary loop: edge floor(s) of the loop, at fraction s − floor(s).
struct LoopPlace {
  uint32_t loop = UINT32_MAX;
  double s = 0;
};

// One face of v's fan as it is before a move: the other two corners, the unit normal and
// whether the face is a sliver (then its normal says nothing) or on the strip.
struct FanFace {
  Vec3 u, x, unit_normal;
  bool sliver = false, strip = false;
};

struct Strip {
  const MeshView& in;
  const BoundaryLoops& loops;
  std::span<float> P;
  std::span<const uint32_t> T;
  std::vector<uint32_t> vf_offsets, vf;        // output vertex → faces
  std::vector<std::array<uint32_t, 2>> bnbr;   // the two boundary neighbours of a strip vertex
  std::vector<LoopPlace> place;                // slidable strip vertices (loop UINT32_MAX: not)
  std::vector<uint8_t> strip_face;             // faces with a corner at a strip vertex

  uint32_t loop_size(uint32_t l) const { return loops.offsets[l + 1] - loops.offsets[l]; }
  uint32_t loop_vertex(uint32_t l, uint64_t k) const { return loops.vertices[loops.offsets[l] + k % loop_size(l)]; }
  Vec3 at(uint32_t l, double s) const {
    const double k = std::floor(s), t = s - k;
    const Vec3 a = point(in.positions, loop_vertex(l, uint64_t(k))), b = point(in.positions, loop_vertex(l, uint64_t(k) + 1));
    return add(scale(a, 1 - t), scale(b, t));
  }
  std::span<const uint32_t> faces(uint32_t v) const { return {vf.data() + vf_offsets[v], vf_offsets[v + 1] - vf_offsets[v]}; }
};

// v's faces with v at p: smallest Q, Q sum and Σ 1/Q — the score a move must lower (it weighs
// every face, and a sliver most; max-min alone stalls wherever the worst face cannot improve).
// q_min = −1 when a face would fold: a well-shaped face turning past `cos_turn`
// (`cos_turn_strip` on the strip), a sliver pointing away from the surface normal n (a sliver's
// own normal is noise).
struct FanScore {
  double q_min = -1, q_sum = 0, inv_sum = 0;
  bool better_than(const FanScore& o) const {
    if (o.q_min < 0) return q_min >= 0;
    return q_min >= 0 && inv_sum < o.inv_sum * (1 - 1e-9);
  }
};

// v's fan at its current position, for the fan_score of every candidate place (a move
// evaluates dozens; the fan does not change meanwhile). O(fan size).
void take_fan(const Strip& st, uint32_t v, std::vector<FanFace>& fan) {
  fan.clear();
  const Vec3 old = point(st.P, v);
  for (uint32_t f : st.faces(v)) {
    const uint32_t* t = &st.T[3 * size_t(f)];
    const int kv = t[0] == v ? 0 : (t[1] == v ? 1 : 2);
    FanFace& ff = fan.emplace_back();
    ff.u = point(st.P, t[(kv + 1) % 3]), ff.x = point(st.P, t[(kv + 2) % 3]);
    ff.unit_normal = unit(cross(sub(ff.u, old), sub(ff.x, old)));
    ff.sliver = triangle_quality(old, ff.u, ff.x) < kSliverQuality;
    ff.strip = st.strip_face[f] != 0;
  }
}

FanScore fan_score(std::span<const FanFace> fan, const Vec3& p, const Vec3& n, double cos_turn, double cos_turn_strip) {
  FanScore score{1, 0};
  for (const FanFace& ff : fan) {
    const Vec3& u = ff.u;
    const Vec3& x = ff.x;
    const Vec3 n_new = cross(sub(u, p), sub(x, p));
    if (!ff.sliver) {
      if (dot(unit(n_new), ff.unit_normal) < (ff.strip ? cos_turn_strip : cos_turn)) return {};
    } else if (dot(n_new, n) <= 0) {
      return {};
    }
    const double q = triangle_quality(p, u, x);
    score.q_min = std::min(score.q_min, q);
    score.q_sum += q;
    score.inv_sum += 1 / std::max(q, 1e-6);
  }
  return score;
}

// Slides strip vertex v along its loop between its boundary neighbours to the place of the best
// FanScore among a sampling of the stretch (by arc length, refined twice around the best).
// Refused places are those where the boundary between v and a neighbour would leave the chord
// by more than max_deviation of its length. Returns true when v moved.
bool slide_strip_vertex(Strip& st, uint32_t v, double max_deviation, double min_allowed, double cos_turn,
                        std::vector<FanFace>& fan) {
  const LoopPlace here = st.place[v];
  const LoopPlace a = st.place[st.bnbr[v][0]], b = st.place[st.bnbr[v][1]];
  if (a.loop != here.loop || b.loop != here.loop) return false;
  const double n = st.loop_size(here.loop);
  auto forward = [&](double from, double to) { return std::fmod(to - from + 2 * n, n); };
  // prev → v → next in loop order: the neighbour reached first going forward is next.
  const bool a_next = forward(here.s, a.s) < forward(here.s, b.s);
  const double s_prev = a_next ? b.s : a.s, span = forward(s_prev, a_next ? a.s : b.s);
  if (!(span > 0) || forward(s_prev, here.s) >= span) return false;
  // The stretch as a polyline: its end points and the input vertices strictly inside.
  std::vector<double> param = {s_prev};
  for (double k = std::floor(s_prev) + 1; k < s_prev + span; k += 1) param.push_back(k);
  param.push_back(s_prev + span);
  std::vector<Vec3> pts(param.size());
  std::vector<double> arc(param.size(), 0);
  for (size_t i = 0; i < param.size(); ++i) {
    pts[i] = st.at(here.loop, std::fmod(param[i], n));
    if (i > 0) arc[i] = arc[i - 1] + norm(sub(pts[i], pts[i - 1]));
  }
  if (!(arc.back() > 0)) return false;
  // Deviation of the boundary from the chords prev → q and q → next, q at arc length `x`
  // (segment i): both within max_deviation of their chord lengths.
  auto chords_ok = [&](const Vec3& q, size_t i) {
    const Vec3& p0 = pts.front();
    const Vec3& p1 = pts.back();
    const double l0 = norm(sub(q, p0)), l1 = norm(sub(p1, q));
    for (size_t j = 1; j <= i; ++j)
      if (segment_distance(pts[j], p0, q) > std::max(max_deviation * l0, min_allowed)) return false;
    for (size_t j = i + 1; j + 1 < pts.size(); ++j)
      if (segment_distance(pts[j], q, p1) > std::max(max_deviation * l1, min_allowed)) return false;
    return true;
  };
  auto place_at = [&](double x, double& s, size_t& seg) {
    seg = size_t(std::upper_bound(arc.begin(), arc.end(), x) - arc.begin());
    seg = std::clamp<size_t>(seg, 1, arc.size() - 1) - 1;  // x in [arc[seg], arc[seg+1]]
    const double len = arc[seg + 1] - arc[seg], f = len > 0 ? (x - arc[seg]) / len : 0;
    s = param[seg] + f * (param[seg + 1] - param[seg]);
    return as_float(add(scale(pts[seg], 1 - f), scale(pts[seg + 1], f)));
  };
  // The surface normal at v: the input face of the boundary edge it lies on.
  const uint32_t e0 = st.loop_vertex(here.loop, uint64_t(here.s)), e1 = st.loop_vertex(here.loop, uint64_t(here.s) + 1);
  Vec3 normal{0, 0, 0};
  for (uint32_t f : st.in.faces_of(e0)) {
    const uint32_t* t = &st.in.triangles[3 * size_t(f)];
    if (t[0] != e1 && t[1] != e1 && t[2] != e1) continue;
    normal = cross(sub(point(st.in.positions, t[1]), point(st.in.positions, t[0])),
                   sub(point(st.in.positions, t[2]), point(st.in.positions, t[0])));
  }
  take_fan(st, v, fan);
  const FanScore current = fan_score(fan, point(st.P, v), normal, cos_turn, 0.0);
  FanScore best = current;
  double best_x = -1, best_s = here.s;
  const double total = arc.back();
  double lo = 0, hi = total;
  for (int round = 0; round < 3; ++round) {
    const int samples = 16;
    for (int i = 1; i < samples; ++i) {
      const double x = lo + (hi - lo) * i / samples;
      if (x <= 1e-6 * total || x >= (1 - 1e-6) * total) continue;
      double s;
      size_t seg;
      const Vec3 q = place_at(x, s, seg);
      if (!chords_ok(q, seg)) continue;
      const FanScore score = fan_score(fan, q, normal, cos_turn, 0.0);
      if (score.q_min > 0 && score.better_than(best)) best = score, best_x = x, best_s = s;
    }
    if (best_x < 0) break;
    const double step = (hi - lo) / 16;
    lo = std::max(0.0, best_x - step), hi = std::min(total, best_x + step);
  }
  if (best_x < 0) return false;
  double s;
  size_t seg;
  const Vec3 q = place_at(best_x, s, seg);
  for (int k = 0; k < 3; ++k) st.P[3 * size_t(v) + k] = float(q[k]);
  st.place[v].s = std::fmod(best_s, n);
  return true;
}

// Moves cluster vertex v on the surface to the best FanScore among: the mean of its neighbours,
// the apex that makes its worst face equilateral, the mean of those apexes over all its faces;
// each at 1, 1/2 and 1/4 of the way. Returns true when v moved.
bool move_cluster_vertex(Strip& st, uint32_t v, uint32_t& surface_face, const Vec3& offset, double cos_turn,
                         std::vector<FanFace>& fan) {
  const MeshView& s = st.in;
  const uint32_t* sf = &s.triangles[3 * size_t(surface_face)];
  const Vec3 normal = unit(cross(sub(point(s.positions, sf[1]), point(s.positions, sf[0])),
                                 sub(point(s.positions, sf[2]), point(s.positions, sf[0]))));
  const Vec3 p = point(st.P, v);
  take_fan(st, v, fan);
  const FanScore current = fan_score(fan, p, normal, cos_turn, 0.0);
  if (current.q_min < 0) return false;
  Vec3 mean{0, 0, 0}, apex_mean{0, 0, 0}, worst_apex = p;
  double worst = 2;
  const auto ring = st.faces(v);
  for (uint32_t f : ring) {
    const uint32_t* t = &st.T[3 * size_t(f)];
    const int kv = t[0] == v ? 0 : (t[1] == v ? 1 : 2);
    const Vec3 u = point(st.P, t[(kv + 1) % 3]), x = point(st.P, t[(kv + 2) % 3]);
    mean = add(mean, scale(add(u, x), 0.5));  // each neighbour of an interior vertex is in two faces
    // (v, u, x) turns around the normal, so v's side of u → x is normal × (x − u).
    const Vec3 apex = add(scale(add(u, x), 0.5), scale(unit(cross(normal, sub(x, u))), std::sqrt(3.0) / 2 * norm(sub(x, u))));
    apex_mean = add(apex_mean, apex);
    const double q = triangle_quality(p, u, x);
    if (q < worst) worst = q, worst_apex = apex;
  }
  mean = scale(mean, 1.0 / double(ring.size()));
  apex_mean = scale(apex_mean, 1.0 / double(ring.size()));
  FanScore best = current;
  Vec3 best_p = p;
  uint32_t best_face = surface_face;
  auto consider = [&](const Vec3& target) {
    const Vec3 c = sub(target, scale(normal, dot(sub(target, best_p), normal)));  // tangential: the walk puts it back on the surface
    Vec3 on;
    const uint32_t face = closest_point_walk(s, best_face, sub(c, offset), on);
    const Vec3 q = as_float(add(on, offset));
    const FanScore score = fan_score(fan, q, normal, cos_turn, 0.0);
    if (score.q_min > 0 && score.better_than(best)) {
      best = score, best_p = q, best_face = face;
      return true;
    }
    return false;
  };
  for (const Vec3& target : {apex_mean, worst_apex, mean})
    for (double step : {1.0, 0.5, 0.25}) consider(add(p, scale(sub(target, p), step)));
  // Then a compass search in the tangent plane (8 directions, step halved when none helps).
  Vec3 e1 = unit(cross(normal, std::abs(normal[0]) < 0.9 ? Vec3{1, 0, 0} : Vec3{0, 1, 0}));
  Vec3 e2 = cross(normal, e1);
  double step = 0;
  for (uint32_t f : ring) {
    const uint32_t* t = &st.T[3 * size_t(f)];
    const int kv = t[0] == v ? 0 : (t[1] == v ? 1 : 2);
    step += norm(sub(point(st.P, t[(kv + 1) % 3]), p));
  }
  step *= 0.25 / double(ring.size());
  for (int round = 0; round < 8; ++round) {
    bool improved = false;
    for (int d = 0; d < 8; ++d) {
      const double a = d * std::numbers::pi / 4;
      improved |= consider(add(best_p, add(scale(e1, step * std::cos(a)), scale(e2, step * std::sin(a)))));
    }
    if (!improved) step *= 0.5;
  }
  if (best_p == p) return false;
  for (int k = 0; k < 3; ++k) st.P[3 * size_t(v) + k] = float(best_p[k]);
  surface_face = best_face;
  return true;
}

}  // namespace

StripQuality strip_face_quality(std::span<const float> positions, std::span<const uint32_t> triangles,
                                std::span<const int32_t> cluster_of_output_vertex) {
  StripQuality r;
  double strip_sum = 0, other_sum = 0;
  r.strip_q_min = 1;
  const size_t F = triangles.size() / 3;
  for (size_t f = 0; f < F; ++f) {
    const uint32_t* t = &triangles[3 * f];
    const double q = triangle_quality(point(positions, t[0]), point(positions, t[1]), point(positions, t[2]));
    if (cluster_of_output_vertex[t[0]] < 0 || cluster_of_output_vertex[t[1]] < 0 || cluster_of_output_vertex[t[2]] < 0) {
      ++r.strip_faces;
      strip_sum += q;
      r.strip_q_min = std::min(r.strip_q_min, q);
    } else {
      other_sum += q;
    }
  }
  if (r.strip_faces == 0) r.strip_q_min = 0;
  if (r.strip_faces > 0) r.strip_q_avg = strip_sum / double(r.strip_faces);
  if (F > r.strip_faces) r.other_q_avg = other_sum / double(F - r.strip_faces);
  return r;
}

namespace {

// The boundary edges (used by exactly one face, counted as half-edges) of each of `vertices`:
// their number, capped at 3, and the first two other ends in ascending order. Per vertex from
// its faces (vf: the vertex → face CSR), in parallel; O(Σ valence² of `vertices`) — only the
// strips' neighbourhood, not the whole output (dragon ×9 → 300,000: 17 ms a round for all).
void boundary_neighbours(std::span<const uint32_t> T, std::span<const uint32_t> vf_offsets, std::span<const uint32_t> vf,
                         std::span<const uint32_t> vertices, std::span<uint8_t> count,
                         std::span<std::array<uint32_t, 2>> bnbr) {
  tbb::enumerable_thread_specific<std::vector<uint32_t>> scratch;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, vertices.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
    std::vector<uint32_t>& ends = scratch.local();
    for (size_t at = r.begin(); at != r.end(); ++at) {
      const uint32_t v = vertices[at];
      ends.clear();
      for (uint32_t i = vf_offsets[v]; i < vf_offsets[v + 1]; ++i) {
        const uint32_t f = vf[i];
        if (i > vf_offsets[v] && f == vf[i - 1]) continue;  // listed once per corner at v
        for (uint32_t k = 0; k < 3; ++k) {
          const uint32_t a = T[3 * size_t(f) + k], b = T[3 * size_t(f) + (k + 1) % 3];
          if (a == v && b == v) ends.push_back(uint32_t(v)), ends.push_back(uint32_t(v));  // both ends are v
          else if (a == v) ends.push_back(b);
          else if (b == v) ends.push_back(a);
        }
      }
      std::sort(ends.begin(), ends.end());
      uint8_t n = 0;
      for (size_t i = 0, j; i < ends.size(); i = j) {
        for (j = i + 1; j < ends.size() && ends[j] == ends[i]; ++j) {
        }
        const bool self = ends[i] == v;  // an edge (v, v) lists v twice per use, and counts twice
        if (j - i != (self ? 2u : 1u)) continue;
        if (n < 2) bnbr[v][n] = ends[i];
        n = uint8_t(std::min(n + (self ? 2 : 1), 3));
      }
      count[v] = n;
    }
  });
}

// Gauss-Seidel sweeps (at most options.sweeps, until one moves nothing): the strip vertices
// slide, then the cluster vertices move, each set by colour classes (no two vertices of a class
// on one face: a class moves in parallel, the same for any thread count). A vertex's move
// depends only on its own place and its fan's corners: one that did not move when last tried,
// with no fan corner moved since, would not move now and is not tried. Marks slid strip vertices.
void sweep_vertices(Strip& st, std::span<const uint32_t> strip_order, std::span<const uint32_t> cluster_order,
                    std::span<uint32_t> surface_face, std::span<const Vec3> offset, const StripShapeOptions& options,
                    double cos_turn, std::vector<uint8_t>& slid, StripShapeReport& report) {
  const uint32_t V = uint32_t(st.vf_offsets.size() - 1);
  const std::span<const uint32_t> T = st.T;
  const std::vector<uint8_t> all(V, 1);
  std::vector<uint32_t> strip_begin, cluster_begin;
  const std::vector<uint32_t> strip_classes = colour_classes(T, st.vf_offsets, st.vf, strip_order, all, strip_begin);
  const std::vector<uint32_t> cluster_classes = colour_classes(T, st.vf_offsets, st.vf, cluster_order, all, cluster_begin);
  std::vector<uint8_t> stale(V, 1), moved(V, 0);
  tbb::enumerable_thread_specific<std::vector<FanFace>> fans;
  // Tries the stale vertices of one class with `move`, in parallel; returns the moves, whose
  // fans are then stale.
  auto run_class = [&](std::span<const uint32_t> members, auto&& move) {
    auto one = [&](uint32_t v, std::vector<FanFace>& fan) {
      if (!stale[v]) return;
      stale[v] = 0;
      moved[v] = move(v, fan);
    };
    if (members.size() > 1)
      tbb::parallel_for(tbb::blocked_range<size_t>(0, members.size(), 16), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) one(members[i], fans.local());
      });
    else
      for (uint32_t v : members) one(v, fans.local());
    uint64_t moves = 0;
    for (uint32_t v : members) {
      if (!moved[v]) continue;
      ++moves;
      moved[v] = 0;
      for (uint32_t f : st.faces(v))
        for (int k = 0; k < 3; ++k) stale[T[3 * size_t(f) + k]] = 1;
    }
    return moves;
  };
  auto run_classes = [&](const std::vector<uint32_t>& classes, const std::vector<uint32_t>& begin, auto&& move) {
    uint64_t moves = 0;
    for (uint32_t k = 0; k <= kSerialColour; ++k) {
      const std::span<const uint32_t> members(classes.data() + begin[k], begin[k + 1] - begin[k]);
      if (k < kSerialColour) {
        moves += run_class(members, move);
      } else {
        for (uint32_t v : members) moves += run_class({&v, 1}, move);  // one at a time
      }
    }
    return moves;
  };
  const double min_allowed = options.max_spacing_deviation * options.strip_spacing;
  for (uint32_t sweep = 0; sweep < options.sweeps; ++sweep) {
    const uint64_t slides = run_classes(strip_classes, strip_begin, [&](uint32_t v, std::vector<FanFace>& fan) {
      const bool m = slide_strip_vertex(st, v, options.max_chord_deviation, min_allowed, cos_turn, fan);
      if (m) slid[v] = 1;
      return m;
    });
    const uint64_t shifts = run_classes(cluster_classes, cluster_begin, [&](uint32_t v, std::vector<FanFace>& fan) {
      return move_cluster_vertex(st, v, surface_face[v], offset[v], cos_turn, fan);
    });
    report.strip_moves += slides;
    report.cluster_moves += shifts;
    if (slides + shifts == 0) break;
  }
}

// One round of shape_boundary_strips on the current connectivity: set-up, then the sweeps.
// `near` gets the strip vertices and the cluster vertices within options.rings of them.
void shape_round(DualMesh& dual, const MeshView& surface, const BoundaryLoops& loops, std::span<const uint8_t> movable,
                 std::span<uint32_t> surface_face, const StripShapeOptions& options, StripShapeReport& report,
                 std::vector<uint8_t>& near) {
  MeshBuffers& mesh = dual.mesh;
  const uint32_t V = mesh.vertex_count();
  Strip st{surface, loops, mesh.positions, mesh.triangles};
  const std::span<const uint32_t> T = mesh.triangles;
  const size_t F = T.size() / 3;
  build_vertex_faces(T, V, st.vf_offsets, st.vf);
  std::vector<uint8_t> is_strip(V, 0);
  for (uint32_t v = 0; v < V; ++v) is_strip[v] = dual.cluster_of_output_vertex[v] < 0;
  // The strip vertices and the cluster vertices within options.rings rings of them: all that
  // may move.
  near = is_strip;
  for (uint32_t ring = 0; ring < options.rings; ++ring) {
    std::vector<uint8_t> grown = near;
    for (size_t f = 0; f < F; ++f)
      if (near[T[3 * f]] | near[T[3 * f + 1]] | near[T[3 * f + 2]]) grown[T[3 * f]] = grown[T[3 * f + 1]] = grown[T[3 * f + 2]] = 1;
    near.swap(grown);
  }
  // Their output boundary edges (used by one face) and boundary neighbours.
  std::vector<uint32_t> near_list;
  for (uint32_t v = 0; v < V; ++v)
    if (near[v]) near_list.push_back(v);
  std::vector<uint8_t> boundary_count(V, 0);
  st.bnbr.assign(V, {UINT32_MAX, UINT32_MAX});
  boundary_neighbours(T, st.vf_offsets, st.vf, near_list, boundary_count, st.bnbr);
  // Where each strip vertex lies on the input loops, from its sources.
  std::vector<std::array<uint32_t, 3>> at_loop;  // (input vertex, loop, position), sorted
  for (uint32_t l = 0; l + 1 < loops.offsets.size(); ++l)
    for (uint32_t k = loops.offsets[l]; k < loops.offsets[l + 1]; ++k)
      at_loop.push_back({loops.vertices[k], l, k - loops.offsets[l]});
  std::sort(at_loop.begin(), at_loop.end());
  auto find = [&](uint32_t u) -> const std::array<uint32_t, 3>* {
    auto it = std::lower_bound(at_loop.begin(), at_loop.end(), std::array<uint32_t, 3>{u, 0, 0});
    return it != at_loop.end() && (*it)[0] == u ? &*it : nullptr;
  };
  st.place.assign(V, {});
  for (uint32_t v = 0; v < V; ++v) {
    if (!is_strip[v]) continue;
    const VertexSource src = dual.source_of_output_vertex[v];
    if (boundary_count[v] != 2 || src.count < 1 || src.count > 2) continue;
    const auto* a = find(dual.source_vertices[src.begin]);
    if (!a) continue;
    if (src.count == 1) {
      st.place[v] = {(*a)[1], double((*a)[2])};
      continue;
    }
    const auto* b = find(dual.source_vertices[src.begin + 1]);
    if (!b || (*b)[1] != (*a)[1]) continue;
    const uint32_t n = st.loop_size((*a)[1]);
    if ((*a)[2] + 1 == (*b)[2] || ((*a)[2] == n - 1 && (*b)[2] == 0)) st.place[v] = {(*a)[1], (*a)[2] + 0.5};
    else if ((*b)[2] + 1 == (*a)[2] || ((*b)[2] == n - 1 && (*a)[2] == 0)) st.place[v] = {(*a)[1], (*b)[2] + 0.5};
  }
  st.strip_face.assign(F, 0);
  for (size_t f = 0; f < F; ++f) st.strip_face[f] = is_strip[T[3 * f]] | is_strip[T[3 * f + 1]] | is_strip[T[3 * f + 2]];
  // Cluster vertices that may move: interior, within options.rings rings of a strip vertex.
  std::vector<uint32_t> strip_order, cluster_order;
  for (uint32_t v = 0; v < V; ++v)
    if (st.place[v].loop != UINT32_MAX) strip_order.push_back(v);
  std::vector<Vec3> offset(V, Vec3{0, 0, 0});
  for (uint32_t v : near_list) {
    if (is_strip[v] || !movable[v] || surface_face[v] == UINT32_MAX || boundary_count[v] != 0) continue;
    cluster_order.push_back(v);
    if (options.keep_surface_offset) {
      Vec3 on;
      surface_face[v] = closest_point_walk(surface, surface_face[v], point(mesh.positions, v), on);
      offset[v] = sub(point(mesh.positions, v), on);
    }
  }
  const double cos_turn = std::cos(options.max_normal_change_deg * std::numbers::pi / 180);
  std::vector<uint8_t> slid(V, 0);
  sweep_vertices(st, strip_order, cluster_order, surface_face, offset, options, cos_turn, slid, report);
  // A slid vertex now lies on input edge floor(s) (or at its first vertex): its sources follow.
  for (uint32_t v : strip_order) {
    if (!slid[v]) continue;
    const LoopPlace pl = st.place[v];
    const double k = std::floor(pl.s);
    const uint32_t ends[2] = {st.loop_vertex(pl.loop, uint64_t(k)), st.loop_vertex(pl.loop, uint64_t(k) + 1)};
    const uint32_t count = pl.s - k > 0 ? 2 : 1;
    VertexSource& src = dual.source_of_output_vertex[v];
    if (src.count < count) {
      src.begin = uint32_t(dual.source_vertices.size());
      dual.source_vertices.insert(dual.source_vertices.end(), ends, ends + count);
    } else {
      std::copy(ends, ends + count, dual.source_vertices.begin() + src.begin);
    }
    src.count = count;
    src.t = float(pl.s - k);
  }
}

}  // namespace

StripShapeReport shape_boundary_strips(DualMesh& dual, const MeshView& surface, const BoundaryLoops& loops,
                                       std::span<const uint8_t> movable, std::span<uint32_t> surface_face,
                                       const StripShapeOptions& options) {
  const uint32_t V = dual.mesh.vertex_count();
  if (movable.size() != V || surface_face.size() != V || dual.cluster_of_output_vertex.size() != V)
    throw InputError("shape_boundary_strips: movable and surface_face need one entry per output vertex");
  StripShapeReport report;
  std::vector<uint8_t> near;
  shape_round(dual, surface, loops, movable, surface_face, options, report, near);
  if (options.flips) {
    // The moved strips admit max-min flips the first pass refused; they in turn let the fans move
    // further (on the dragon → 20k: strip Qav 0.538 after one round, 0.551 after two). Only
    // the edges around what the round could move are tried: the rest is as the quality pass
    // left it.
    report.flips = flip_edges_near(dual.mesh.positions, dual.mesh.triangles, near);
    if (report.flips > 0) shape_round(dual, surface, loops, movable, surface_face, options, report, near);
  }
  return report;
}

}  // namespace streamcvd
