#include "streamcvd/core/dual/flat_faces.h"
#include "streamcvd/core/mesh/vertex_faces.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

namespace streamcvd {

namespace {

using Vec3 = std::array<double, 3>;

Vec3 point(std::span<const float> P, uint32_t v) {
  return {double(P[3 * size_t(v)]), double(P[3 * size_t(v) + 1]), double(P[3 * size_t(v) + 2])};
}

Vec3 area_vector(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 u = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  return {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
}

double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

double distance2(const Vec3& a, const Vec3& b) {
  const Vec3 d = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  return dot(d, d);
}

// Twice the area of face (a, b, c), in double from the float positions.
double double_area(std::span<const float> P, uint32_t a, uint32_t b, uint32_t c) {
  const Vec3 n = area_vector(point(P, a), point(P, b), point(P, c));
  return std::sqrt(dot(n, n));
}

constexpr uint32_t kRemoved = UINT32_MAX;

// Faces around each vertex (CSR), removed faces left out.
struct VertexFaces {
  std::vector<uint32_t> offsets, faces;

  VertexFaces(std::span<const uint32_t> T, size_t V) { build_vertex_faces(T, V, offsets, faces, kRemoved); }
  std::span<const uint32_t> of(uint32_t v) const { return {faces.data() + offsets[v], offsets[v + 1] - offsets[v]}; }
};

bool holds(std::span<const uint32_t> T, uint32_t f, uint32_t v) {
  return T[3 * size_t(f)] == v || T[3 * size_t(f) + 1] == v || T[3 * size_t(f) + 2] == v;
}

// Faces holding both u and v (at most `out.size()` recorded); returns their number.
uint32_t faces_on_edge(std::span<const uint32_t> T, const VertexFaces& vf, uint32_t u, uint32_t v,
                       std::array<uint32_t, 3>& out) {
  uint32_t n = 0;
  for (uint32_t f : vf.of(u))
    if (holds(T, f, v)) {
      if (n < out.size()) out[n] = f;
      ++n;
    }
  return n;
}

// Every edge around m has two faces: m is an interior manifold vertex, so dropping one of its
// faces opens its fan into a single boundary fan (no bowtie).
bool interior_vertex(std::span<const uint32_t> T, const VertexFaces& vf, uint32_t m) {
  std::array<uint32_t, 3> scratch;
  for (uint32_t f : vf.of(m))
    for (int i = 0; i < 3; ++i) {
      const uint32_t y = T[3 * size_t(f) + i];
      if (y != m && faces_on_edge(T, vf, m, y, scratch) != 2) return false;
    }
  return true;
}

// Moves m off the line u–v by the least distance giving face (u, v, m) an area of 4·zero2/2,
// towards the mean of m's other neighbours (inside the surface), if none of m's faces becomes
// flat or turns over. The move is a few float ulps: the surface does not change visibly.
bool nudge(std::span<float> P, std::span<const uint32_t> T, const VertexFaces& vf, uint32_t u, uint32_t v,
           uint32_t m, double zero2) {
  const Vec3 a = point(P, u), b = point(P, v), p = point(P, m);
  const Vec3 e = {b[0] - a[0], b[1] - a[1], b[2] - a[2]};
  const double L2 = dot(e, e);
  if (!(L2 > 0)) return false;
  Vec3 mean = {0, 0, 0};
  uint32_t count = 0;
  for (uint32_t f : vf.of(m))
    for (int i = 0; i < 3; ++i) {
      const uint32_t y = T[3 * size_t(f) + i];
      if (y == m || y == u || y == v) continue;
      const Vec3 q = point(P, y);
      for (int k = 0; k < 3; ++k) mean[k] += q[k];
      ++count;
    }
  if (count == 0) return false;
  Vec3 d;
  for (int k = 0; k < 3; ++k) d[k] = mean[k] / count - p[k];
  const double along = dot(d, e) / L2;
  for (int k = 0; k < 3; ++k) d[k] -= along * e[k];
  const double len = std::sqrt(dot(d, d));
  if (!(len > 0)) return false;
  std::vector<Vec3> before;
  for (uint32_t f : vf.of(m)) {
    const uint32_t* t = &T[3 * size_t(f)];
    before.push_back(area_vector(point(P, t[0]), point(P, t[1]), point(P, t[2])));
  }
  const float old[3] = {P[3 * size_t(m)], P[3 * size_t(m) + 1], P[3 * size_t(m) + 2]};
  for (double h = 4 * zero2 / std::sqrt(L2); h < 1e3 * zero2 / std::sqrt(L2); h *= 2) {
    for (int k = 0; k < 3; ++k) P[3 * size_t(m) + k] = float(p[k] + h * d[k] / len);
    bool ok = true;
    size_t i = 0;
    for (uint32_t f : vf.of(m)) {
      const uint32_t* t = &T[3 * size_t(f)];
      const Vec3 n = area_vector(point(P, t[0]), point(P, t[1]), point(P, t[2]));
      const double n_before = std::sqrt(dot(before[i], before[i]));
      ok &= std::sqrt(dot(n, n)) > zero2 && (n_before <= zero2 || dot(n, before[i]) > 0);
      ++i;
    }
    if (ok) return true;
  }
  for (int k = 0; k < 3; ++k) P[3 * size_t(m) + k] = old[k];
  return false;
}

// Last resort when no nudge off the line works: m is one end of an edge far shorter than its
// faces (two flat faces share it), typically on a debris piece a hundredth of an output edge
// wide, where a move of a few ulps cannot give both faces an area. Tries m at steps of 1/2 …
// 1/4096 of its mean edge length towards and away from each neighbour, and keeps the position
// whose worst face is best: each face of m must keep its facing (a flat one: m's normal, the
// sum of its faces with area) and reach an area of 4·zero2/2. O(degree² · 24).
bool relocate(std::span<float> P, std::span<const uint32_t> T, const VertexFaces& vf, uint32_t m, double zero2) {
  const Vec3 p = point(P, m);
  std::vector<Vec3> reference;
  Vec3 normal = {0, 0, 0};
  for (uint32_t f : vf.of(m)) {
    const uint32_t* t = &T[3 * size_t(f)];
    reference.push_back(area_vector(point(P, t[0]), point(P, t[1]), point(P, t[2])));
    if (std::sqrt(dot(reference.back(), reference.back())) > zero2)
      for (int k = 0; k < 3; ++k) normal[k] += reference.back()[k];
  }
  for (Vec3& r : reference)
    if (std::sqrt(dot(r, r)) <= zero2) r = normal;
  std::vector<Vec3> neighbours;
  double mean_length = 0;
  for (uint32_t f : vf.of(m))
    for (int i = 0; i < 3; ++i)
      if (const uint32_t y = T[3 * size_t(f) + i]; y != m) {
        neighbours.push_back(point(P, y));
        mean_length += std::sqrt(distance2(p, neighbours.back()));
      }
  if (neighbours.empty() || !(mean_length > 0) || !(dot(normal, normal) > 0)) return false;
  mean_length /= double(neighbours.size());
  // Worst face of m at the position m has now: its area if it faces as its reference, else minus it.
  auto worst_face = [&] {
    double worst = std::numeric_limits<double>::infinity();
    size_t i = 0;
    for (uint32_t f : vf.of(m)) {
      const uint32_t* t = &T[3 * size_t(f)];
      const Vec3 n = area_vector(point(P, t[0]), point(P, t[1]), point(P, t[2]));
      const double area = std::sqrt(dot(n, n));
      worst = std::min(worst, dot(n, reference[i++]) > 0 ? area : -area);
    }
    return worst;
  };
  const float old[3] = {P[3 * size_t(m)], P[3 * size_t(m) + 1], P[3 * size_t(m) + 2]};
  float best[3] = {old[0], old[1], old[2]};
  double best_worst = worst_face();
  // Unit directions: to each neighbour, and along m's normal.
  std::vector<Vec3> directions;
  for (const Vec3& q : neighbours)
    if (const double d = std::sqrt(distance2(p, q)); d > 0) directions.push_back({(q[0] - p[0]) / d, (q[1] - p[1]) / d, (q[2] - p[2]) / d});
  const double n = std::sqrt(dot(normal, normal));
  directions.push_back({normal[0] / n, normal[1] / n, normal[2] / n});
  for (const Vec3& e : directions) {
    for (double sign : {-1.0, 1.0})
      for (double step = mean_length; step > mean_length / 4096; step /= 2) {
        for (int k = 0; k < 3; ++k) P[3 * size_t(m) + k] = float(p[k] + sign * step * e[k]);
        if (const double w = worst_face(); w > best_worst) {
          best_worst = w;
          for (int k = 0; k < 3; ++k) best[k] = P[3 * size_t(m) + k];
        }
      }
  }
  const bool clear = best_worst > zero2;
  for (int k = 0; k < 3; ++k) P[3 * size_t(m) + k] = clear ? best[k] : old[k];
  return clear;
}

bool flat(std::span<const float> P, std::span<const uint32_t> T, size_t f, double zero2) {
  const uint32_t a = T[3 * f], b = T[3 * f + 1], c = T[3 * f + 2];
  if (a == kRemoved || a == b || b == c || a == c) return false;  // repeated indices: not ours
  return double_area(P, a, b, c) <= zero2;
}

}  // namespace

double flat_face_area(std::span<const float> positions) {
  if (positions.size() < 3) return 0;
  double lo[3], hi[3];
  for (int i = 0; i < 3; ++i) lo[i] = hi[i] = positions[i];
  for (size_t v = 0; v + 2 < positions.size(); v += 3)
    for (int i = 0; i < 3; ++i) {
      lo[i] = std::min(lo[i], double(positions[v + i]));
      hi[i] = std::max(hi[i], double(positions[v + i]));
    }
  double d2 = 0;
  for (int i = 0; i < 3; ++i) d2 += (hi[i] - lo[i]) * (hi[i] - lo[i]);
  return 1e-12 * d2;
}

FlatFaceRepair repair_flat_faces(std::span<float> positions, std::vector<uint32_t>& triangles) {
  FlatFaceRepair report;
  const size_t V = positions.size() / 3;
  // Twice the area threshold: faces up to 1.25× it are flat (rounding differences with
  // mesh_stats); edited faces must reach 4× it, so they stay clear of the threshold.
  const double flat2 = 2.5 * flat_face_area(positions), zero2 = 8 * flat_face_area(positions);
  std::span<float> P = positions;
  std::vector<uint32_t>& T = triangles;
  std::vector<size_t> pending;
  for (int pass = 0; pass < 8; ++pass) {
    pending.clear();
    for (size_t f = 0; f < T.size() / 3; ++f)
      if (flat(P, T, f, flat2)) pending.push_back(f);
    if (pending.empty()) break;
    const VertexFaces vf(T, V);
    // An edit changes faces around its vertices: other edits there wait for the next pass
    // (the adjacency is rebuilt then).
    std::vector<uint8_t> dirty(V, 0);
    bool edited = false;
    for (size_t f : pending) {
      uint32_t* t = &T[3 * f];
      if (dirty[t[0]] || dirty[t[1]] || dirty[t[2]]) continue;
      // The longest edge u → v (as oriented in f); the middle vertex m lies between its ends.
      int longest = 0;
      double best = -1;
      for (int i = 0; i < 3; ++i) {
        const double d2 = distance2(point(P, t[i]), point(P, t[(i + 1) % 3]));
        if (d2 > best) best = d2, longest = i;
      }
      const uint32_t u = t[longest], v = t[(longest + 1) % 3], m = t[(longest + 2) % 3];
      std::array<uint32_t, 3> on_edge;
      const uint32_t n = faces_on_edge(T, vf, u, v, on_edge);
      auto try_nudge = [&] {
        uint32_t moved = m;
        if (!nudge(P, T, vf, u, v, m, zero2)) {
          if (relocate(P, T, vf, m, zero2)) moved = m;
          else if (relocate(P, T, vf, u, zero2)) moved = u;
          else if (relocate(P, T, vf, v, zero2)) moved = v;
          else return;
        }
        for (uint32_t h : vf.of(moved))
          for (int i = 0; i < 3; ++i) dirty[T[3 * size_t(h) + i]] = 1;
        ++report.nudges;
        edited = true;
      };
      if (n == 1) {
        if (!interior_vertex(T, vf, m)) {
          try_nudge();
          continue;
        }
        t[0] = t[1] = t[2] = kRemoved;  // m now lies on the boundary, as it does in space
        dirty[u] = dirty[v] = dirty[m] = 1;
        ++report.faces_removed;
        edited = true;
        continue;
      }
      if (n != 2) {
        try_nudge();
        continue;
      }
      const uint32_t g = on_edge[0] == f ? on_edge[1] : on_edge[0];
      uint32_t* s = &T[3 * size_t(g)];
      int k = 0;  // g must hold v → u (consistent orientation); x is its third vertex
      while (k < 3 && !(s[k] == v && s[(k + 1) % 3] == u)) ++k;
      if (k == 3) {
        try_nudge();
        continue;
      }
      const uint32_t x = s[(k + 2) % 3];
      if (dirty[x]) continue;
      if (x == m) {
        try_nudge();
        continue;
      }
      bool edge_exists = false;
      for (uint32_t h : vf.of(m)) edge_exists |= holds(T, h, x);
      if (edge_exists) {  // the flip would duplicate edge m–x
        try_nudge();
        continue;
      }
      // New faces (m, u, x) and (x, v, m) split g at m: both must have area and face as g did.
      const Vec3 ng = area_vector(point(P, v), point(P, u), point(P, x));
      const Vec3 n1 = area_vector(point(P, m), point(P, u), point(P, x));
      const Vec3 n2 = area_vector(point(P, x), point(P, v), point(P, m));
      if (std::sqrt(dot(n1, n1)) <= zero2 || std::sqrt(dot(n2, n2)) <= zero2 || dot(n1, ng) <= 0 || dot(n2, ng) <= 0) {
        try_nudge();
        continue;
      }
      t[0] = m, t[1] = u, t[2] = x;
      s[0] = x, s[1] = v, s[2] = m;
      dirty[u] = dirty[v] = dirty[m] = dirty[x] = 1;
      ++report.flips;
      edited = true;
    }
    if (report.faces_removed > 0) {
      size_t kept = 0;
      for (size_t f = 0; f < T.size(); f += 3) {
        if (T[f] == kRemoved) continue;
        for (int i = 0; i < 3; ++i) T[kept + i] = T[f + i];
        kept += 3;
      }
      T.resize(kept);
    }
    if (!edited) break;
  }
  for (size_t f = 0; f < T.size() / 3; ++f) report.remaining += flat(P, T, f, flat2);
  return report;
}

}  // namespace streamcvd
