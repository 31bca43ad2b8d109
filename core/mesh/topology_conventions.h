// The conventions of TopologyStats (core/measure/mesh_stats.h) that both implementations apply face by
// face: the soup version (core/measure/mesh_stats.cpp) and the store version (core/measure/store_stats.cpp).
// One definition each, so the two cannot drift apart: tests compare their results field by field.
// Internal to those two files.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>

#include "streamcvd/core/measure/mesh_stats.h"

namespace streamcvd::topology {

/// Bounding box in double with the soup version's semantics, which `std::min`/`std::max` over
/// the vertices in order give: a NaN coordinate is skipped, except at vertex 0, which then makes
/// that axis NaN. Accumulated with add() in any order and merged, then finish(vertex 0): the same
/// box as the sequential loop, bit for bit, so the zero-area threshold is the same too.
struct Box {
  double lo[3] = {std::numeric_limits<double>::infinity(), std::numeric_limits<double>::infinity(),
                  std::numeric_limits<double>::infinity()};
  double hi[3] = {-std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(),
                  -std::numeric_limits<double>::infinity()};
  void add(const float* p) {
    for (int i = 0; i < 3; ++i) {
      if (double(p[i]) < lo[i]) lo[i] = p[i];  // false for NaN: skipped
      if (double(p[i]) > hi[i]) hi[i] = p[i];
    }
  }
  void merge(const Box& o) {
    for (int i = 0; i < 3; ++i) lo[i] = std::min(lo[i], o.lo[i]), hi[i] = std::max(hi[i], o.hi[i]);
  }
  /// `first` = vertex 0's coordinates, or null for an empty mesh (box [0,0]³).
  void finish(const float* first) {
    for (int i = 0; i < 3; ++i) {
      if (!first) lo[i] = hi[i] = 0;
      else if (std::isnan(first[i])) lo[i] = hi[i] = first[i];
    }
  }
  double diagonal2() const {
    double d2 = 0;
    for (int i = 0; i < 3; ++i) d2 += (hi[i] - lo[i]) * (hi[i] - lo[i]);
    return d2;
  }
};

/// Area at or below which a face counts as degenerate: 1e-12 · (bounding-box diagonal)².
inline double zero_area(const Box& box) { return 1e-12 * box.diagonal2(); }

/// Twice the area of triangle (a, b, c), in double, edges taken from corner a.
inline double double_area(std::span<const float> positions, uint32_t a, uint32_t b, uint32_t c) {
  const float* p0 = &positions[3 * size_t(a)];
  const float* p1 = &positions[3 * size_t(b)];
  const float* p2 = &positions[3 * size_t(c)];
  double e1[3], e2[3];
  for (int i = 0; i < 3; ++i) {
    e1[i] = double(p1[i]) - p0[i];
    e2[i] = double(p2[i]) - p0[i];
  }
  const double x[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
  return std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
}

inline bool repeated_index(uint32_t a, uint32_t b, uint32_t c) { return a == b || b == c || a == c; }

/// The corner after `v` in face `t` (3 vertex ids holding v): the end of the edge v → next
/// that the face runs. Two faces with the same next corner after v run an edge the same way.
inline uint32_t next_corner(const uint32_t* t, uint32_t v) { return t[0] == v ? t[1] : t[1] == v ? t[2] : t[0]; }

/// Degenerate face: a repeated index, or an area ≤ zero_area (a NaN area is not ≤ anything).
inline bool degenerate(std::span<const float> positions, uint32_t a, uint32_t b, uint32_t c, double zero) {
  return repeated_index(a, b, c) || 0.5 * double_area(positions, a, b, c) <= zero;
}

/// The vertex set of a face as a sorted triple, the key of duplicate faces: (a,b,c) = (c,b,a) =
/// (b,c,a); {a,a,b} and {a,b,b} are the same set {a,b}, written (a,b,b). Its first entry is the
/// face's owner (smallest vertex).
inline std::array<uint32_t, 3> vertex_set(uint32_t a, uint32_t b, uint32_t c) {
  std::array<uint32_t, 3> s = {a, b, c};
  if (s[0] > s[1]) std::swap(s[0], s[1]);
  if (s[1] > s[2]) std::swap(s[1], s[2]);
  if (s[0] > s[1]) std::swap(s[0], s[1]);
  if (s[0] == s[1]) s = {s[0], s[2], s[2]};
  return s;
}

/// The fields derived from the counts: Euler characteristic over the `referenced` vertices,
/// closed_manifold, and genus for a closed manifold with one component and even χ (an odd χ can
/// only be a non-orientable surface). Needs faces, edges, boundary_edges, nonmanifold_* and
/// components set.
inline void derive_figures(TopologyStats& s, uint64_t referenced) {
  s.euler_characteristic = int64_t(referenced) - int64_t(s.edges) + int64_t(s.faces);
  s.closed_manifold = s.faces > 0 && s.boundary_edges == 0 && s.nonmanifold_edges == 0 && s.nonmanifold_vertices == 0;
  s.genus = -1;
  if (s.closed_manifold && s.components == 1 && s.euler_characteristic % 2 == 0)
    s.genus = (2 - s.euler_characteristic) / 2;
}

}  // namespace streamcvd::topology
