// The topology cleaning (streaming/store/store_clean.h): a plan computed fan by fan over the store's
// chunk ranges, then the cleaned soup streamed from the store and the plan.
//
// Every decision is a pure function of the store: whether a face is dropped (its own corners and
// the faces of its owner, where any face with the same vertex set is listed), how the faces of an
// edge pair up (the edge's kept faces, taken in the canonical direction min → max) and hence the
// fans of a vertex. Both ends of an edge therefore agree on its pairs without talking to each
// other, each range is planned independently, and the plan is the same for any thread count or
// memory limit. Only vertices that need it are looked at closely: those the build flagged
// non-manifold, and those with a dropped face.
#include "streamcvd/streaming/store/store_clean.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <numeric>
#include <utility>

#include "streamcvd/core/mesh/chunked_components.h"
#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/mesh/topology_conventions.h"
#include "streamcvd/core/mesh/vec3.h"

namespace streamcvd {
namespace {

constexpr uint32_t kNone = UINT32_MAX;
constexpr double kPi = 3.14159265358979323846;
constexpr uint32_t kBlock = 1u << 16;

struct EdgeFace {
  double angle;    // about the axis a → b, [0, 2π), 0 for the first face
  uint32_t index;  // into the edge's face list
  bool forward;    // the face runs a → b
  bool layer;      // paired as a double layer (pair_edge)
  uint32_t apex;   // the face's third vertex
};

// Two faces of an edge, of opposite direction, are taken for a face and its copy when their
// angle about the edge is below kLayerAngle (radians) and their apexes are closer than
// kLayerApex times the longer of their edges. genbig's jitter (2 % of a sub-edge per axis)
// leaves angles up to ~0.15 rad and apexes ~7 % of an edge apart; two closed surfaces touching
// along an edge have their faces that close in angle but their apexes an edge or more apart.
constexpr double kLayerAngle = 0.2;
constexpr double kLayerApex = 0.25;

struct Faces;
void pair_edge(const Faces& fs, uint32_t a, uint32_t b, std::span<const uint32_t> faces, std::vector<EdgeFace>& s,
               std::span<uint32_t> partner);

// The view and the rule for dropped faces.
struct Faces {
  const MeshView& m;
  double zero;
  bool drop_unpaired = false;  // later rounds: faces a cut left unpaired go (see plan_topology_cleaning)
  std::span<const uint32_t> seam;  // vertices looked at as if flagged (misoriented edges to cut)
  const uint32_t* tri(uint64_t f) const { return &m.triangles[3 * f]; }
  // A repeated index always; zero area only at a non-manifold vertex, where its angle about an
  // edge would mean nothing. Elsewhere a zero-area face is harmless (it weighs nothing) and
  // dropping it would open a slit in the surface (the dragon's 367 would make 303 holes).
  bool degenerate(uint64_t f) const {
    const uint32_t* t = tri(f);
    if (topology::repeated_index(t[0], t[1], t[2])) return true;
    const auto& flags = m.vertex_flags;
    if (!((flags[t[0]] | flags[t[1]] | flags[t[2]]) & kVertexNonManifold)) return false;
    return topology::degenerate(m.positions, t[0], t[1], t[2], zero);
  }
  // What the same-vertex-set rule does with f: kKept, or dropped as a kDuplicate (one face of
  // its group is kept) or with its whole kDoubleLayer. Every face of such a group is in the face
  // list of the set's smallest vertex. One face of a group is kept: the first of the orientation
  // that agrees with more of the faces around it (a face and its reverse are a folded double
  // layer, and the first of the two may run against its neighbours), the first of all on a tie.
  // A group with both orientations whose edges each hold an even number of other faces is
  // dropped whole: the two sides of a wall collapsed onto one layer (a vertex-clustered
  // decimation), where the surfaces on either side already close each edge in pairs. Keeping
  // one face would leave each of its edges with an odd count, a face without a partner, and the
  // cut a hole (crude dragon, 120 cells: 795 boundary loops and 601 pieces after the cleaning
  // of a closed input, 18 and 10 with double layers dropped whole; bun_zipper_res2: 74 loops
  // and 58 pieces, 5 and 1 as its scan has). A face repeated on a closed surface (its edges
  // hold an odd count besides) keeps one copy.
  enum DuplicateRule { kKept, kDuplicate, kDoubleLayer };
  DuplicateRule duplicate_rule(uint64_t f) const {
    const uint32_t* t = tri(f);
    const auto set = topology::vertex_set(t[0], t[1], t[2]);
    uint32_t group[2] = {kNone, kNone};  // first face of each orientation: f's own, the reverse
    bool other_earlier = false;          // a face of the other orientation comes before f
    bool same_earlier = false;           // an earlier face of f's orientation
    for (uint32_t g : m.faces_of(set[0])) {
      if (g == f) continue;
      const uint32_t* u = tri(g);
      if (topology::vertex_set(u[0], u[1], u[2]) != set) continue;
      const int side = same_orientation(t, u) ? 0 : 1;
      same_earlier |= g < f && side == 0;
      if (group[side] == kNone || g < group[side]) group[side] = g;
      other_earlier |= side == 1 && g < f;
    }
    if (group[1] != kNone && !repeated(t) && edges_paired_without(set)) return kDoubleLayer;
    if (same_earlier) return kDuplicate;  // an earlier face of the same orientation is kept first
    if (group[1] == kNone || repeated(t)) return kKept;  // one orientation (or degenerate: dropped anyway)
    const int64_t mine = agreement(f, set), theirs = agreement(group[1], set);
    if (mine != theirs) return mine < theirs ? kDuplicate : kKept;
    // A tie: its neighbours are doubled too (a double-layer flap). The side its normal faces
    // decides, the same for every face of a nearly flat flap, so their choices agree.
    const double side = facing(f);
    return (side != 0 ? side < 0 : other_earlier) ? kDuplicate : kKept;
  }
  bool duplicate(uint64_t f) const { return duplicate_rule(f) != kKept; }
  // True when each edge of the vertex set `set` holds an even number of faces outside its group
  // (degenerate ones left out). O(faces of the set's vertices).
  bool edges_paired_without(const std::array<uint32_t, 3>& set) const {
    for (uint32_t k = 0; k < 3; ++k) {
      const uint32_t x = set[k], y = set[(k + 1) % 3];
      uint64_t others = 0;
      uint32_t last = kNone;
      for (uint32_t g : m.faces_of(x)) {
        if (g == last) continue;  // listed once per corner holding x
        last = g;
        const uint32_t* u = tri(g);
        if (u[0] != y && u[1] != y && u[2] != y) continue;
        if (topology::vertex_set(u[0], u[1], u[2]) != set && !degenerate(g)) ++others;
      }
      if (others % 2) return false;
    }
    return true;
  }
  // Normal of f against a fixed direction (any direction off the axes would do).
  double facing(uint64_t f) const {
    const uint32_t* t = tri(f);
    const float* p0 = &m.positions[3 * size_t(t[0])];
    const float* p1 = &m.positions[3 * size_t(t[1])];
    const float* p2 = &m.positions[3 * size_t(t[2])];
    double e1[3], e2[3];
    for (int i = 0; i < 3; ++i) e1[i] = double(p1[i]) - p0[i], e2[i] = double(p2[i]) - p0[i];
    const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    return 0.6 * n[0] + 0.64 * n[1] + 0.48 * n[2];
  }
  static bool repeated(const uint32_t* t) { return topology::repeated_index(t[0], t[1], t[2]); }
  // Same cyclic order of three distinct corners.
  static bool same_orientation(const uint32_t* t, const uint32_t* u) {
    const uint32_t k = u[0] == t[0] ? 0 : u[1] == t[0] ? 1 : 2;
    return u[(k + 1) % 3] == t[1];
  }
  // Faces outside the group (`set`) across f's edges running against f (a consistent
  // orientation) minus those running with it.
  int64_t agreement(uint64_t f, const std::array<uint32_t, 3>& set) const {
    const uint32_t* t = tri(f);
    int64_t score = 0;
    for (uint32_t k = 0; k < 3; ++k) {
      const uint32_t x = t[k], y = t[(k + 1) % 3];
      for (uint32_t g : m.faces_of(x)) {
        const uint32_t* u = tri(g);
        if (topology::vertex_set(u[0], u[1], u[2]) == set) continue;
        for (uint32_t j = 0; j < 3; ++j) {
          if (u[j] == y && u[(j + 1) % 3] == x) ++score;
          if (u[j] == x && u[(j + 1) % 3] == y) --score;
        }
      }
    }
    return score;
  }
  bool dropped(uint64_t f) const { return degenerate(f) || duplicate(f) || (drop_unpaired && unpaired(f)); }
  // f has an edge with more than two kept faces where the pairing leaves f alone or, the edge
  // having two pairs or more, puts f in a pair other than the first (counted as unpaired too).
  bool unpaired(uint64_t f) const {
    const uint32_t* t = tri(f);
    for (uint32_t k = 0; k < 3; ++k) {
      const uint32_t x = std::min(t[k], t[(k + 1) % 3]), y = std::max(t[k], t[(k + 1) % 3]);
      if (!(m.vertex_flags[x] & kVertexNonManifold) || !(m.vertex_flags[y] & kVertexNonManifold)) continue;
      std::vector<uint32_t> faces;  // rare: flagged vertices of a later round only
      uint32_t self = kNone;
      for (uint32_t g : m.faces_of(x)) {
        if (!faces.empty() && faces.back() == g) continue;
        const uint32_t* u = tri(g);
        if ((u[0] != y && u[1] != y && u[2] != y) || degenerate(g) || duplicate(g)) continue;
        if (g == f) self = uint32_t(faces.size());
        faces.push_back(g);
      }
      if (faces.size() < 3 || self == kNone) continue;
      std::vector<EdgeFace> scratch;
      std::vector<uint32_t> partner(faces.size());
      pair_edge(*this, x, y, faces, scratch, partner);
      if (partner[self] == kNone) return true;
      // A later round's edge with two pairs or more: its sheets did not come apart (joined
      // round both ends), so only the pair of its first face that has a partner stays (a
      // vertex clustering of the dragon to 32k vertices kept 8 such edges through every
      // round, and the repair looped on them to its cap).
      const auto first = std::find_if(partner.begin(), partner.end(), [](uint32_t q) { return q != kNone; });
      const uint32_t kept = uint32_t(first - partner.begin());
      if (self != kept && partner[self] != kept) return true;
    }
    return false;
  }
  // Slot of v in face f (a kept face holds each vertex once).
  uint32_t slot(uint64_t f, uint32_t v) const {
    const uint32_t* t = tri(f);
    return t[0] == v ? 0 : t[1] == v ? 1 : 2;
  }
};

// True when apexes p and q of two faces on edge {a, b} are closer than kLayerApex times the
// longest edge of the two faces.
bool apexes_close(const Faces& fs, uint32_t a, uint32_t b, uint32_t p, uint32_t q) {
  auto d2 = [&](uint32_t x, uint32_t y) {
    const vec3::Vec3 d = vec3::sub(vec3::point(fs.m.positions, x), vec3::point(fs.m.positions, y));
    return vec3::dot(d, d);
  };
  const double longest = std::max({d2(a, b), d2(a, p), d2(b, p), d2(a, q), d2(b, q)});
  return d2(p, q) < kLayerApex * kLayerApex * longest;
}

// The better chirality of `s` (faces of one edge sorted by angle) under pair_edge's rule, its
// number of pairs and its deviation from flat.
struct Chirality {
  int best;
  uint32_t pairs;
  double deviation;
};
Chirality best_chirality(std::span<const EdgeFace> s) {
  const size_t k = s.size();
  uint32_t pairs[2] = {0, 0};
  double deviation[2] = {0, 0};
  for (int chirality = 0; chirality < 2; ++chirality)
    for (size_t j = 0; j < k; ++j) {
      const size_t n = (j + 1) % k;
      if (s[j].forward == (chirality == 0) || s[n].forward == s[j].forward) continue;
      ++pairs[chirality];
      const double wedge = s[n].angle - s[j].angle + (n == 0 ? 2 * kPi : 0);
      deviation[chirality] += std::abs(kPi - wedge);
    }
  const int best = pairs[1] > pairs[0] || (pairs[1] == pairs[0] && deviation[1] < deviation[0]) ? 1 : 0;
  return {best, pairs[best], deviation[best]};
}

// Pairs neighbours of `s` by the better chirality into `partner`; returns the number of pairs.
uint32_t chirality_pairs(std::span<const EdgeFace> s, std::span<uint32_t> partner) {
  const size_t k = s.size();
  const Chirality c = best_chirality(s);
  for (size_t j = 0; j < k; ++j) {
    const size_t n = (j + 1) % k;
    if (s[j].forward == (c.best == 0) || s[n].forward == s[j].forward) continue;
    partner[s[j].index] = s[n].index;
    partner[s[n].index] = s[j].index;
  }
  return c.pairs;
}

// Partner of each face of edge {a, b} (a < b; `faces`: its kept faces, ascending) as an index
// into `faces`, kNone for none. A face running a → b has its normal towards increasing angles;
// sorted by angle, the pairs of one "chirality" are the neighbours (backward, next forward) —
// the wedge between them lies behind both normals, the inside of an outward-oriented closed
// surface — and those of the other the neighbours (forward, next backward). Each set is disjoint.
// The one with more pairs wins (fewer boundary edges), then the flatter (Σ |π − wedge|: faces
// that continue each other), then the first.
void pair_edge(const Faces& fs, uint32_t a, uint32_t b, std::span<const uint32_t> faces, std::vector<EdgeFace>& s,
               std::span<uint32_t> partner) {
  std::fill(partner.begin(), partner.end(), kNone);
  const float* pa = &fs.m.positions[3 * size_t(a)];
  const float* pb = &fs.m.positions[3 * size_t(b)];
  double d[3], len2 = 0;
  for (int i = 0; i < 3; ++i) d[i] = double(pb[i]) - pa[i], len2 += d[i] * d[i];
  if (!(len2 > 0)) return;  // a zero-length edge has no angles: every face keeps its own boundary
  const double len = std::sqrt(len2);
  for (double& x : d) x /= len;
  double u0[3] = {0, 0, 0}, v0[3] = {0, 0, 0};
  bool have_reference = false;
  s.clear();
  for (uint32_t i = 0; i < faces.size(); ++i) {
    const uint32_t* t = fs.tri(faces[i]);
    const uint32_t ka = fs.slot(faces[i], a);
    const bool forward = t[(ka + 1) % 3] == b;
    const uint32_t c = t[(ka + (forward ? 2 : 1)) % 3];
    const float* pc = &fs.m.positions[3 * size_t(c)];
    double w[3], along = 0;
    for (int k = 0; k < 3; ++k) w[k] = double(pc[k]) - pa[k], along += w[k] * d[k];
    double w2 = 0;
    for (int k = 0; k < 3; ++k) w[k] -= along * d[k], w2 += w[k] * w[k];
    double angle = 0;
    if (!have_reference) {
      if (w2 > 0) {
        const double n = std::sqrt(w2);
        for (int k = 0; k < 3; ++k) u0[k] = w[k] / n;
        v0[0] = d[1] * u0[2] - d[2] * u0[1], v0[1] = d[2] * u0[0] - d[0] * u0[2], v0[2] = d[0] * u0[1] - d[1] * u0[0];
        have_reference = true;
      }
    } else {
      angle = std::atan2(w[0] * v0[0] + w[1] * v0[1] + w[2] * v0[2], w[0] * u0[0] + w[1] * u0[1] + w[2] * u0[2]);
      if (angle < 0) angle += 2 * kPi;
    }
    s.push_back({angle, i, forward, false, c});
  }
  std::sort(s.begin(), s.end(), [](const EdgeFace& x, const EdgeFace& y) {
    return x.angle != y.angle ? x.angle < y.angle : x.index < y.index;
  });
  const size_t k = s.size();
  // Double layers first: two faces of opposite direction within kLayerAngle of each other about
  // the edge, apexes close (apexes_close), are a face and its copy (a subdivided or jittered
  // double layer), whose order about the edge is noise. Paired with the chirality rule, that
  // order would choose, edge by edge, which copy continues the surface, and a copy attached
  // along some of its edges and not others opens a hole at each change (crude dragon
  // subdivided 10×10: 2,384 boundary loops after the cleaning, 18 for the crude mesh itself).
  // Paired with each other (the closest first) they become a thin closed piece of their own, as
  // the double-layer rule drops a face and its exact reverse whole; this holds when the other
  // faces then pair up completely, else the edge is paired as a whole.
  bool layered = false;
  for (;;) {
    size_t best = k;
    double best_gap = kLayerAngle;
    for (size_t j = 0; j < k; ++j) {
      const size_t n = (j + 1) % k;
      if (s[j].layer || s[n].layer || s[j].forward == s[n].forward || n == j) continue;
      const double gap = s[n].angle - s[j].angle + (n == 0 ? 2 * kPi : 0);
      if (gap < best_gap && apexes_close(fs, a, b, s[j].apex, s[n].apex)) best_gap = gap, best = j;
    }
    if (best == k) break;
    EdgeFace &x = s[best], &y = s[(best + 1) % k];
    x.layer = y.layer = true;
    partner[x.index] = y.index, partner[y.index] = x.index;
    layered = true;
  }
  if (layered) {
    for (size_t j = 0; j < k; ++j)
      if (!s[j].layer) s.push_back(s[j]);  // the other faces, in angle order, after the k
    const std::span<const EdgeFace> rest(s.data() + k, s.size() - k);
    if (2 * size_t(chirality_pairs(rest, partner)) == rest.size()) return;
    std::fill(partner.begin(), partner.end(), kNone);
  }
  chirality_pairs(std::span<const EdgeFace>(s.data(), k), partner);
}

// Counters of one range (integers: summed in range order).
struct Counts {
  uint64_t duplicates = 0, double_layer = 0, degenerate = 0, edges_cut = 0, unpaired = 0, split = 0, unpaired_dropped = 0;
};

struct FanScratch {
  std::vector<uint32_t> faces;     // kept faces of v, ascending
  std::vector<uint64_t> uses;      // other end << 32 | local face << 1 | runs v → u, two per face
  std::vector<uint32_t> parent;    // union-find over the local faces
  std::vector<uint32_t> edge_faces, partner, class_of_root;
  std::vector<EdgeFace> edge;
  std::vector<uint32_t> fan;       // fan of each local face
};

uint32_t find(std::vector<uint32_t>& parent, uint32_t x) {
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

void unite(std::vector<uint32_t>& parent, uint32_t a, uint32_t b) {
  a = find(parent, a), b = find(parent, b);
  if (a != b) parent[std::max(a, b)] = std::min(a, b);  // the root is a class's smallest face
}

// Fans of v (its kept faces in s.faces) into s.fan, numbered by their smallest face; returns
// their count. Faces are joined across each edge {v, u}: when two faces use it in opposite
// directions (a consistent orientation), by the pairs of pair_edge when more do (counted from the
// edge's smaller end). Only vertices next to a defect get here: elsewhere an inconsistently
// oriented edge is left as it is.
uint32_t vertex_fans(const Faces& fs, uint32_t v, FanScratch& s, Counts& c) {
  const uint32_t n = uint32_t(s.faces.size());
  s.uses.clear();
  for (uint32_t lf = 0; lf < n; ++lf) {
    const uint32_t* t = fs.tri(s.faces[lf]);
    const uint32_t k = fs.slot(s.faces[lf], v);
    s.uses.push_back(uint64_t(t[(k + 1) % 3]) << 32 | lf << 1 | 1);  // runs v → u
    s.uses.push_back(uint64_t(t[(k + 2) % 3]) << 32 | lf << 1);      // runs u → v
  }
  std::sort(s.uses.begin(), s.uses.end());
  s.parent.resize(n);
  std::iota(s.parent.begin(), s.parent.end(), 0u);
  for (size_t i = 0, j; i < s.uses.size(); i = j) {
    const uint32_t u = uint32_t(s.uses[i] >> 32);
    for (j = i + 1; j < s.uses.size() && uint32_t(s.uses[j] >> 32) == u; ++j) {
    }
    auto face = [&](size_t q) { return uint32_t(s.uses[q]) >> 1; };
    // Two faces running the same way along the edge do not continue each other's surface.
    if (j - i == 2 && (s.uses[i] & 1) != (s.uses[i + 1] & 1)) unite(s.parent, face(i), face(i + 1));
    if (j - i <= 2) continue;
    s.edge_faces.clear();
    for (size_t q = i; q < j; ++q) s.edge_faces.push_back(s.faces[face(q)]);  // ascending
    s.partner.resize(j - i);
    pair_edge(fs, std::min(v, u), std::max(v, u), s.edge_faces, s.edge, s.partner);
    for (size_t q = 0; q < j - i; ++q)
      if (s.partner[q] != kNone) unite(s.parent, face(i + q), face(i + s.partner[q]));
    if (u > v) {
      ++c.edges_cut;
      c.unpaired += uint64_t(std::count(s.partner.begin(), s.partner.end(), kNone));
    }
  }
  s.fan.resize(n);
  s.class_of_root.assign(n, kNone);
  uint32_t fans = 0;
  for (uint32_t lf = 0; lf < n; ++lf) {
    const uint32_t root = find(s.parent, lf);  // ≤ lf: numbered already when smaller
    if (s.class_of_root[root] == kNone) s.class_of_root[root] = fans++;
    s.fan[lf] = s.class_of_root[root];
  }
  return fans;
}

// The plan of one range: copies in vertex order, corners moved to them (local copy indices).
struct RangePlan {
  std::vector<uint32_t> copy_source;
  std::vector<std::pair<uint64_t, uint32_t>> moves;  // face << 2 | slot, local copy
  Counts counts;
};

void plan_range(const Faces& fs, VertexRange r, FanScratch& s, RangePlan& p) {
  const MeshView& m = fs.m;
  for (uint32_t v = r.begin; v != r.end; ++v) {
    const std::span<const uint32_t> fan = m.faces_of(v);
    bool look = (m.vertex_flags[v] & kVertexNonManifold) != 0 || std::binary_search(fs.seam.begin(), fs.seam.end(), v);
    s.faces.clear();
    for (size_t i = 0; i < fan.size(); ++i) {
      const uint32_t f = fan[i];
      if (i > 0 && f == fan[i - 1]) continue;  // listed once per corner holding v
      const uint32_t* t = fs.tri(f);
      const bool owned = std::min({t[0], t[1], t[2]}) == v;
      const bool degenerate = fs.degenerate(f);
      const auto rule = degenerate ? Faces::kKept : fs.duplicate_rule(f);
      const bool duplicate = rule != Faces::kKept;
      const bool unpaired = !degenerate && !duplicate && fs.drop_unpaired && fs.unpaired(f);
      const bool drop = degenerate || duplicate || unpaired;
      if (owned) {
        p.counts.degenerate += degenerate, p.counts.duplicates += duplicate, p.counts.unpaired_dropped += unpaired;
        p.counts.double_layer += rule == Faces::kDoubleLayer;
      }
      if (drop) {
        look = true;
        continue;
      }
      s.faces.push_back(f);
    }
    if (!look || s.faces.size() < 2) continue;
    const uint32_t fans = vertex_fans(fs, v, s, p.counts);
    if (fans < 2) continue;
    ++p.counts.split;
    const uint32_t first = uint32_t(p.copy_source.size());
    p.copy_source.insert(p.copy_source.end(), fans - 1, v);
    for (uint32_t lf = 0; lf < s.faces.size(); ++lf)
      if (s.fan[lf] > 0)
        p.moves.push_back({uint64_t(s.faces[lf]) << 2 | fs.slot(s.faces[lf], v), first + s.fan[lf] - 1});
  }
}

}  // namespace

bool needs_topology_cleaning(const TopologyStats& s, const MeshView& mesh) {
  if (s.duplicate_faces > 0 || s.nonmanifold_edges > 0 || s.nonmanifold_vertices > 0) return true;
  if (s.degenerate_faces == 0) return false;
  // Zero-area faces of a manifold stay (Faces::degenerate); a repeated index does not.
  const auto tri = mesh.triangles;
  return tbb::parallel_reduce(
      tbb::blocked_range<uint64_t>(0, mesh.face_count(), 1 << 16), false,
      [&](const tbb::blocked_range<uint64_t>& r, bool found) {
        for (uint64_t f = r.begin(); f != r.end() && !found; ++f)
          found = topology::repeated_index(tri[3 * f], tri[3 * f + 1], tri[3 * f + 2]);
        return found;
      },
      [](bool a, bool b) { return a || b; });
}

CleaningPlan plan_topology_cleaning(const MeshView& mesh, TopologyCleaning& counts, bool drop_unpaired,
                                    std::span<const uint32_t> seam) {
  CleaningPlan plan;
  plan.drop_unpaired = drop_unpaired;
  plan.vertices = mesh.vertex_count();
  // The threshold of compute_topology_stats (from the chunks' boxes: the exact box for finite
  // coordinates), so that the faces dropped are those `info` counts as degenerate.
  topology::Box box;
  for (const Chunk& c : mesh.chunks) box.add(c.bbox_min), box.add(c.bbox_max);
  plan.zero_area = topology::zero_area(box);
  const Faces fs{mesh, plan.zero_area, drop_unpaired, seam};
  const std::vector<VertexRange> ranges = chunk_ranges(mesh.chunks);
  std::vector<RangePlan> parts(ranges.size());
  tbb::enumerable_thread_specific<FanScratch> scratch;
  tbb::parallel_for(
      tbb::blocked_range<size_t>(0, ranges.size(), 1),
      [&](const tbb::blocked_range<size_t>& rr) {
        for (size_t i = rr.begin(); i != rr.end(); ++i) {
          const RangeVisit visit(mesh, "clean", ranges[i], kReadsAllArrays);
          plan_range(fs, ranges[i], scratch.local(), parts[i]);
        }
      },
      tbb::simple_partitioner());
  // Copies numbered in range order (= vertex order); moved corners sorted by face and slot.
  std::vector<std::pair<uint64_t, uint32_t>> moves;
  for (RangePlan& p : parts) {
    const uint32_t base = plan.vertices + uint32_t(plan.copy_source.size());
    for (const auto& [corner, local] : p.moves) moves.push_back({corner, base + local});
    plan.copy_source.insert(plan.copy_source.end(), p.copy_source.begin(), p.copy_source.end());
    counts.duplicate_faces_dropped += p.counts.duplicates;
    counts.double_layer_faces_dropped += p.counts.double_layer;
    counts.degenerate_faces_dropped += p.counts.degenerate;
    counts.nonmanifold_edges_cut += p.counts.edges_cut;
    counts.unpaired_edge_faces += p.counts.unpaired;
    counts.vertices_split += p.counts.split;
    counts.unpaired_faces_dropped += p.counts.unpaired_dropped;
    RangePlan().copy_source.swap(p.copy_source);
  }
  std::sort(moves.begin(), moves.end());
  plan.moved_corners.reserve(moves.size());
  plan.moved_to.reserve(moves.size());
  for (const auto& [corner, to] : moves) plan.moved_corners.push_back(corner), plan.moved_to.push_back(to);
  counts.vertex_copies += plan.copy_source.size();
  plan.kept_faces = mesh.face_count();
  for (const RangePlan& p : parts) plan.kept_faces -= p.counts.duplicates + p.counts.degenerate + p.counts.unpaired_dropped;
  return plan;
}

void stream_cleaned_soup(const MeshStore& store, const CleaningPlan& plan, MeshSink& sink) {
  const MeshView m = store.view();
  const uint32_t A = store.header().attribute_count;
  const std::span<const float> attributes = store.vertex_attributes();
  const uint64_t V = m.vertex_count(), copies = plan.copy_source.size();
  MeshHeaderInfo header;
  header.vertices = V + copies;
  header.faces = plan.kept_faces;
  header.vertices_before_triangles = true;
  header.attributes = store.attributes();
  sink.begin(header);
  for (uint64_t v0 = 0; v0 < V; v0 += kBlock) {
    const uint64_t n = std::min<uint64_t>(kBlock, V - v0);
    sink.vertices(m.positions.subspan(3 * v0, 3 * n), A ? attributes.subspan(A * v0, A * n) : std::span<const float>());
  }
  std::vector<float> xyz, rows;
  for (uint64_t c0 = 0; c0 < copies; c0 += kBlock) {
    const uint64_t n = std::min<uint64_t>(kBlock, copies - c0);
    xyz.resize(3 * n);
    rows.resize(A * n);
    for (uint64_t i = 0; i < n; ++i) {
      const uint32_t v = plan.copy_source[c0 + i];
      std::copy_n(&m.positions[3 * size_t(v)], 3, &xyz[3 * i]);
      if (A) std::copy_n(&attributes[size_t(A) * v], A, &rows[A * i]);
    }
    sink.vertices(xyz, rows);
  }
  const Faces fs{m, plan.zero_area, plan.drop_unpaired};
  const uint64_t F = m.face_count();
  std::vector<uint8_t> keep;
  std::vector<uint32_t> out;
  size_t move = 0, flip = 0;
  uint64_t emitted = 0;
  for (uint64_t f0 = 0; f0 < F; f0 += kBlock) {
    const uint64_t n = std::min<uint64_t>(kBlock, F - f0);
    keep.resize(n);
    tbb::parallel_for(tbb::blocked_range<uint64_t>(0, n, 4096), [&](const tbb::blocked_range<uint64_t>& q) {
      for (uint64_t i = q.begin(); i != q.end(); ++i) keep[i] = !fs.dropped(f0 + i);
    });
    out.clear();
    for (uint64_t i = 0; i < n; ++i) {
      if (!keep[i]) continue;
      const uint64_t f = f0 + i;
      for (uint32_t k = 0; k < 3; ++k) {
        const uint64_t corner = f << 2 | k;
        while (move < plan.moved_corners.size() && plan.moved_corners[move] < corner) ++move;  // none: kept faces only
        const bool moved = move < plan.moved_corners.size() && plan.moved_corners[move] == corner;
        out.push_back(moved ? plan.moved_to[move] : m.triangles[3 * f + k]);
      }
      while (flip < plan.flipped_faces.size() && plan.flipped_faces[flip] < f) ++flip;
      if (flip < plan.flipped_faces.size() && plan.flipped_faces[flip] == f) std::swap(out[out.size() - 1], out[out.size() - 2]);
    }
    emitted += out.size() / 3;
    if (!out.empty()) sink.triangles(out);
  }
  ReadStats stats;
  stats.vertices = header.vertices;
  stats.triangles = emitted;
  sink.end(stats);
}

namespace {

// The integer fields of a cleaning record, by name.
template <typename Report>
auto record_fields(Report& r) {
  auto& in = r.input_topology;
  auto& c = r.cleaning;
  return std::array<std::pair<const char*, decltype(&in.vertices)>, 23>{{
      {"input_vertices", &in.vertices},
      {"input_faces", &in.faces},
      {"input_edges", &in.edges},
      {"input_boundary_edges", &in.boundary_edges},
      {"input_boundary_loops", &in.boundary_loops},
      {"input_nonmanifold_edges", &in.nonmanifold_edges},
      {"input_nonmanifold_vertices", &in.nonmanifold_vertices},
      {"input_duplicate_faces", &in.duplicate_faces},
      {"input_degenerate_faces", &in.degenerate_faces},
      {"input_isolated_vertices", &in.isolated_vertices},
      {"input_components", &in.components},
      {"duplicate_faces_dropped", &c.duplicate_faces_dropped},
      {"double_layer_faces_dropped", &c.double_layer_faces_dropped},
      {"degenerate_faces_dropped", &c.degenerate_faces_dropped},
      {"nonmanifold_edges_cut", &c.nonmanifold_edges_cut},
      {"unpaired_edge_faces", &c.unpaired_edge_faces},
      {"vertices_split", &c.vertices_split},
      {"vertex_copies", &c.vertex_copies},
      {"unpaired_faces_dropped", &c.unpaired_faces_dropped},
      {"faces_flipped", &c.faces_flipped},
      {"misoriented_edges_cut", &c.misoriented_edges_cut},
      {"misoriented_edges_left", &c.misoriented_edges_left},
      {"input_closed_manifold", nullptr},  // the rest: not uint64_t, handled by name
  }};
}

}  // namespace

std::string cleaning_record(const StoreBuildReport& r) {
  std::ostringstream out;
  StoreBuildReport copy = r;
  for (const auto& [name, field] : record_fields(copy))
    if (field) out << name << ' ' << *field << '\n';
  const TopologyStats& in = r.input_topology;
  out << "input_euler_characteristic " << in.euler_characteristic << '\n'
      << "input_genus " << in.genus << '\n'
      << "input_closed_manifold " << int(in.closed_manifold) << '\n'
      << "input_consistently_oriented " << int(in.consistently_oriented) << '\n'
      << "rounds " << r.cleaning.rounds << '\n';
  char box[160];
  std::snprintf(box, sizeof box, "input_bbox %.9g %.9g %.9g %.9g %.9g %.9g\n", in.bbox_min[0], in.bbox_min[1],
                in.bbox_min[2], in.bbox_max[0], in.bbox_max[1], in.bbox_max[2]);
  out << box;
  return out.str();
}

void parse_cleaning_record(const std::string& text, StoreBuildReport& r) {
  std::istringstream in(text);
  std::string line;
  auto fields = record_fields(r);
  TopologyStats& t = r.input_topology;
  for (int n = 1; std::getline(in, line); ++n) {
    std::istringstream words(line);
    std::string name;
    words >> name;
    bool ok = !name.empty();
    if (name == "input_bbox") {
      for (float& x : t.bbox_min) words >> x;
      for (float& x : t.bbox_max) words >> x;
    } else if (name == "input_euler_characteristic") {
      words >> t.euler_characteristic;
    } else if (name == "input_genus") {
      words >> t.genus;
    } else if (name == "input_closed_manifold" || name == "input_consistently_oriented") {
      int b = 0;
      words >> b;
      (name == "input_closed_manifold" ? t.closed_manifold : t.consistently_oriented) = b != 0;
    } else if (name == "rounds") {
      words >> r.cleaning.rounds;
    } else {
      ok = false;
      for (const auto& [key, field] : fields)
        if (field && name == key) words >> *field, ok = true;
    }
    if (!ok || words.fail()) throw InputError("line " + std::to_string(n) + ": cannot read '" + line + "'");
  }
  r.topology_checked = true;
  r.input_topology_known = true;
  r.cleaning.rebuilt = true;
}

}  // namespace streamcvd
