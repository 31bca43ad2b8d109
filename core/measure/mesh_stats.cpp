// Topology and quality figures of a triangle soup (conventions: shared/data/README.md,
// core/measure/mesh_stats.h; quality measure: DESIGN.md §9).
//
// Everything is derived from one sorted array of edge uses (min, max, face, corner): runs of
// equal keys are the distinct undirected edges, the run length is the number of faces using the
// edge. No hash maps: the array is bucketed by its min vertex (a counting sort), O(F + V).
//
// Choices the header leaves open, fixed here:
// - A face is degenerate when two of its indices are equal or its area (computed in double) is
//   ≤ 1e-12 · (bounding-box diagonal)², which includes exactly 0.
// - Self-loop edges (a face (a,a,b) has one) are not edges; the face's other two edge uses count,
//   so such a face uses edge {a,b} twice: an edge's "number of faces" is its number of uses.
// - A face's vertex *set* decides duplicates: (a,b,c) = (c,b,a) = (b,c,a); (a,a,b) = (a,b,b).
// - Non-manifold vertex: on an edge used by > 2 faces, or whose incident faces split into more
//   than one class when faces are joined across the 2-face edges at that vertex (a bowtie).
// - genus is reported for a closed manifold with one component and even χ (an odd χ can only be
//   a non-orientable surface); −1 otherwise.
// - Quality of a degenerate triangle: Q = 0 and angles (0°, 0°, 180°).
// - Bounding box: NaN coordinates are skipped, unless vertex 0 has one (then that axis is NaN).
// The per-face rules (area, degeneracy, vertex sets, box, derived figures) live in
// core/mesh/topology_conventions.h, shared with the store version (core/measure/store_stats.cpp), which must
// give the same TopologyStats from the store's adjacency in bounded memory.
#include "streamcvd/core/measure/mesh_stats.h"

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/mesh/topology_conventions.h"
#include "streamcvd/core/mesh/union_find.h"
#include "streamcvd/core/mesh/triangle_quality.h"

#include <oneapi/tbb/blocked_range.h>
#include <oneapi/tbb/parallel_for.h>
#include <oneapi/tbb/parallel_invoke.h>
#include <oneapi/tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

namespace streamcvd {
namespace {

/// One use of an undirected edge by a face. key = min << 32 | max; info = face · 4 + k, the edge
/// running from corner k to corner (k + 1) % 3 of that face.
struct EdgeUse {
  uint64_t key;
  uint64_t info;
  bool operator<(const EdgeUse& o) const { return key != o.key ? key < o.key : info < o.info; }
};

uint32_t key_min(uint64_t key) { return uint32_t(key >> 32); }
uint32_t key_max(uint64_t key) { return uint32_t(key & 0xffffffffu); }

/// All edge uses except self-loops, sorted by (key, info). A counting sort on the min vertex
/// (count, prefix sum, scatter: O(F + V)) leaves only each vertex's handful of uses to sort, in
/// parallel: several times faster than a comparison sort of the whole array, same order.
std::vector<EdgeUse> sorted_edge_uses(std::span<const uint32_t> tri, uint32_t vertices) {
  const uint64_t faces = tri.size() / 3;
  auto for_each_use = [&](auto&& visit) {
    for (uint64_t f = 0; f < faces; ++f)
      for (uint64_t k = 0; k < 3; ++k) {
        const uint32_t a = tri[3 * f + k], b = tri[3 * f + (k + 1) % 3];
        if (a != b) visit(EdgeUse{uint64_t(std::min(a, b)) << 32 | std::max(a, b), 4 * f + k});
      }
  };
  std::vector<uint64_t> begin(uint64_t(vertices) + 1, 0);
  for_each_use([&](const EdgeUse& u) { ++begin[key_min(u.key) + 1]; });
  for (uint32_t v = 0; v < vertices; ++v) begin[v + 1] += begin[v];
  std::vector<EdgeUse> uses(begin[vertices]);
  {
    std::vector<uint64_t> next(begin.begin(), begin.end() - 1);
    for_each_use([&](const EdgeUse& u) { uses[next[key_min(u.key)]++] = u; });
  }
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, vertices, 1 << 12), [&](const tbb::blocked_range<uint32_t>& r) {
    for (uint32_t v = r.begin(); v != r.end(); ++v)
      std::sort(uses.begin() + long(begin[v]), uses.begin() + long(begin[v + 1]));
  });
  return uses;
}

/// Throws InputError unless every index is < V and the index count is a multiple of 3: a bad
/// soup would otherwise read out of bounds. One parallel pass, negligible next to the rest.
void check_soup(const TriangleSoupView& m, const char* caller) {
  if (m.triangles.size() % 3 != 0)
    throw InputError(error_at(caller, std::to_string(m.triangles.size()) + " indices, not a multiple of 3"));
  const uint32_t nv = m.vertex_count();
  const uint64_t bad = tbb::parallel_reduce(
      tbb::blocked_range<uint64_t>(0, m.triangles.size(), 1 << 16), std::numeric_limits<uint64_t>::max(),
      [&](const tbb::blocked_range<uint64_t>& r, uint64_t first) {
        for (uint64_t i = r.begin(); i != r.end() && i < first; ++i)
          if (m.triangles[i] >= nv) return i;
        return first;
      },
      [](uint64_t a, uint64_t b) { return std::min(a, b); });
  if (bad != std::numeric_limits<uint64_t>::max())
    throw InputError(error_at(caller, "face " + std::to_string(bad / 3) + " uses vertex " +
                                          std::to_string(m.triangles[bad]) + " of " + std::to_string(nv)));
}

using topology::Box;
using topology::zero_area;

Box bounding_box(std::span<const float> pos) {
  Box b;
  for (size_t v = 0; v + 2 < pos.size(); v += 3) b.add(&pos[v]);
  b.finish(pos.size() >= 3 ? pos.data() : nullptr);
  return b;
}

/// Twice the area of face f, in double.
double double_area(const TriangleSoupView& m, uint64_t f) {
  return topology::double_area(m.positions, m.triangles[3 * f], m.triangles[3 * f + 1], m.triangles[3 * f + 2]);
}

bool repeated_index(std::span<const uint32_t> tri, uint64_t f) {
  return topology::repeated_index(tri[3 * f], tri[3 * f + 1], tri[3 * f + 2]);
}

/// Faces whose vertex set repeats an earlier face's. A face with distinct vertices a < b < c
/// has exactly one use whose third vertex exceeds both ends, that of edge (a, b); two such faces
/// repeat a set iff they meet in the run of (a, b) with the same third vertex. Faces with a
/// repeated index, whose sets have fewer than three vertices, are rare: a plain sort settles them.
uint64_t count_duplicate_faces(std::span<const uint32_t> tri, std::span<const EdgeUse> uses) {
  uint64_t duplicates = 0;
  std::vector<uint32_t> thirds;
  for (size_t i = 0, j; i < uses.size(); i = j) {
    for (j = i + 1; j < uses.size() && uses[j].key == uses[i].key; ++j) {
    }
    if (j - i < 2) continue;
    thirds.clear();
    for (size_t u = i; u < j; ++u) {
      const uint32_t c = tri[3 * (uses[u].info >> 2) + ((uses[u].info & 3) + 2) % 3];
      if (c > key_max(uses[u].key)) thirds.push_back(c);
    }
    std::sort(thirds.begin(), thirds.end());
    for (size_t k = 1; k < thirds.size(); ++k) duplicates += thirds[k] == thirds[k - 1];
  }
  std::vector<std::array<uint32_t, 3>> small_sets;
  for (uint64_t f = 0; f < tri.size() / 3; ++f) {
    if (!repeated_index(tri, f)) continue;
    small_sets.push_back(topology::vertex_set(tri[3 * f], tri[3 * f + 1], tri[3 * f + 2]));
  }
  std::sort(small_sets.begin(), small_sets.end());
  for (size_t k = 1; k < small_sets.size(); ++k) duplicates += small_sets[k] == small_sets[k - 1];
  return duplicates;
}

enum : uint8_t { kReferenced = 1, kOnBoundary = 2, kOnNonManifold = 4 };

/// Per-vertex kReferenced / kOnBoundary / kOnNonManifold bits from the sorted edge uses.
std::vector<uint8_t> vertex_marks(std::span<const uint32_t> tri, uint32_t vertices, std::span<const EdgeUse> uses) {
  std::vector<uint8_t> mark(vertices, 0);
  for (uint32_t v : tri) mark[v] = kReferenced;
  for (size_t i = 0, j; i < uses.size(); i = j) {
    for (j = i + 1; j < uses.size() && uses[j].key == uses[i].key; ++j) {
    }
    const uint8_t bit = j - i == 1 ? kOnBoundary : j - i > 2 ? kOnNonManifold : 0;
    mark[key_min(uses[i].key)] |= bit;
    mark[key_max(uses[i].key)] |= bit;
  }
  return mark;
}

/// Corner (face f, slot 0..2) of edge use `u` that holds vertex v.
uint64_t corner_of(std::span<const uint32_t> tri, const EdgeUse& u, uint32_t v) {
  const uint64_t f = u.info >> 2, k = u.info & 3;
  return tri[3 * f + k] == v ? 3 * f + k : 3 * f + (k + 1) % 3;
}

/// Vertices whose corners fall into more than one fan: corners of the same vertex are joined
/// across every edge used by exactly two faces; a manifold vertex ends with one class.
template <class Index>
std::vector<uint8_t> bowtie_vertices(std::span<const uint32_t> tri, uint32_t vertices, std::span<const EdgeUse> uses) {
  DisjointSets<Index> corners(tri.size());
  for (size_t i = 0, j; i < uses.size(); i = j) {
    for (j = i + 1; j < uses.size() && uses[j].key == uses[i].key; ++j) {
    }
    if (j - i != 2) continue;
    for (uint32_t v : {key_min(uses[i].key), key_max(uses[i].key)})
      corners.unite(Index(corner_of(tri, uses[i], v)), Index(corner_of(tri, uses[i + 1], v)));
  }
  // Each class's root is one of its own corners, so classes per vertex = root corners per vertex.
  std::vector<uint8_t> bowtie(vertices, 0);  // 0: no class seen yet, 1: one class, 2: several
  for (uint64_t c = 0; c < tri.size(); ++c)
    if (corners.find(Index(c)) == Index(c)) bowtie[tri[c]] = bowtie[tri[c]] == 0 ? 1 : 2;
  for (uint8_t& b : bowtie) b = b == 2;
  return bowtie;
}

// What the topology and the quality figures both start from: the box, the sorted edge uses and
// the vertex marks.
struct EdgeTable {
  Box box;
  std::vector<EdgeUse> uses;
  std::vector<uint8_t> mark;
};

EdgeTable edge_table(const TriangleSoupView& mesh) {
  EdgeTable t;
  t.box = bounding_box(mesh.positions);
  t.uses = sorted_edge_uses(mesh.triangles, mesh.vertex_count());
  t.mark = vertex_marks(mesh.triangles, mesh.vertex_count(), t.uses);
  return t;
}

TopologyStats topology_of(const TriangleSoupView& mesh, const EdgeTable& table) {
  TopologyStats s;
  const auto tri = mesh.triangles;
  const uint32_t nv = mesh.vertex_count();
  const uint64_t nf = mesh.face_count();
  s.vertices = nv;
  s.faces = nf;
  const Box& box = table.box;
  for (int i = 0; i < 3; ++i) s.bbox_min[i] = float(box.lo[i]), s.bbox_max[i] = float(box.hi[i]);

  const double eps = zero_area(box);
  s.degenerate_faces = tbb::parallel_reduce(
      tbb::blocked_range<uint64_t>(0, nf, 1 << 14), uint64_t(0),
      [&](const tbb::blocked_range<uint64_t>& r, uint64_t n) {
        for (uint64_t f = r.begin(); f != r.end(); ++f) n += repeated_index(tri, f) || 0.5 * double_area(mesh, f) <= eps;
        return n;
      },
      std::plus<>());

  const std::vector<EdgeUse>& uses = table.uses;
  s.duplicate_faces = count_duplicate_faces(tri, uses);
  const std::vector<uint8_t>& mark = table.mark;
  bool oriented = true;
  DisjointSets<uint32_t> loops(nv);  // vertices joined by boundary edges
  for (size_t i = 0, j; i < uses.size(); i = j) {
    for (j = i + 1; j < uses.size() && uses[j].key == uses[i].key; ++j) {
    }
    ++s.edges;
    if (j - i == 1) {
      ++s.boundary_edges;
      loops.unite(key_min(uses[i].key), key_max(uses[i].key));
    } else if (j - i > 2) {
      ++s.nonmanifold_edges;
    } else {
      // Two faces: one must run min→max and the other max→min.
      auto forward = [&](const EdgeUse& u) { return tri[3 * (u.info >> 2) + (u.info & 3)] == key_min(u.key); };
      oriented = oriented && forward(uses[i]) != forward(uses[i + 1]);
    }
  }

  DisjointSets<uint32_t> parts(nv);  // vertices joined by faces
  for (uint64_t f = 0; f < nf; ++f) {
    parts.unite(tri[3 * f], tri[3 * f + 1]);
    parts.unite(tri[3 * f], tri[3 * f + 2]);
  }
  const std::vector<uint8_t> bowtie = 3 * nf <= std::numeric_limits<uint32_t>::max()
                                          ? bowtie_vertices<uint32_t>(tri, nv, uses)
                                          : bowtie_vertices<uint64_t>(tri, nv, uses);
  uint64_t referenced = 0;
  for (uint32_t v = 0; v < nv; ++v) {
    if (!(mark[v] & kReferenced)) continue;
    ++referenced;
    s.components += parts.find(v) == v;
    s.boundary_loops += (mark[v] & kOnBoundary) && loops.find(v) == v;
    s.nonmanifold_vertices += (mark[v] & kOnNonManifold) || bowtie[v];
  }
  s.isolated_vertices = nv - referenced;
  s.consistently_oriented = oriented;
  topology::derive_figures(s, referenced);
  return s;
}

constexpr int kQBins = 20, kAngleBins = 12;

struct QualityAccumulator {
  uint64_t triangles = 0, angles_below_30 = 0, triangles_below_30 = 0;
  double q_sum = 0, q_min = std::numeric_limits<double>::infinity();
  double min_angle_sum = 0, min_angle_min = std::numeric_limits<double>::infinity(), max_angle_max = 0;
  std::array<uint64_t, kQBins> q_hist{};
  std::array<uint64_t, kAngleBins> angle_hist{};
  uint64_t boundary_triangles = 0;  // with a corner on a boundary edge
  double q_boundary = 0, q_rest = 0, q_min_boundary = std::numeric_limits<double>::infinity();

  void add(double q, const double (&angle)[3], bool on_boundary) {
    const double lo = std::min({angle[0], angle[1], angle[2]}), hi = std::max({angle[0], angle[1], angle[2]});
    ++triangles;
    if (on_boundary) {
      ++boundary_triangles;
      q_boundary += q;
      q_min_boundary = std::min(q_min_boundary, q);
    } else {
      q_rest += q;
    }
    q_sum += q;
    q_min = std::min(q_min, q);
    min_angle_sum += lo;
    min_angle_min = std::min(min_angle_min, lo);
    max_angle_max = std::max(max_angle_max, hi);
    for (double a : angle) angles_below_30 += a < 30.0;
    triangles_below_30 += lo < 30.0;
    ++q_hist[std::clamp(int(q * kQBins), 0, kQBins - 1)];
    ++angle_hist[std::clamp(int(lo / 5.0), 0, kAngleBins - 1)];
  }
  QualityAccumulator& merge(const QualityAccumulator& o) {
    triangles += o.triangles;
    angles_below_30 += o.angles_below_30;
    triangles_below_30 += o.triangles_below_30;
    q_sum += o.q_sum;
    q_min = std::min(q_min, o.q_min);
    min_angle_sum += o.min_angle_sum;
    min_angle_min = std::min(min_angle_min, o.min_angle_min);
    max_angle_max = std::max(max_angle_max, o.max_angle_max);
    for (int i = 0; i < kQBins; ++i) q_hist[i] += o.q_hist[i];
    for (int i = 0; i < kAngleBins; ++i) angle_hist[i] += o.angle_hist[i];
    boundary_triangles += o.boundary_triangles;
    q_boundary += o.q_boundary;
    q_rest += o.q_rest;
    q_min_boundary = std::min(q_min_boundary, o.q_min_boundary);
    return *this;
  }
};

/// Q and the three angles (degrees) of face f; a degenerate face gives Q = 0, (0°, 0°, 180°).
void face_quality(const TriangleSoupView& m, uint64_t f, double eps, double& q, double (&angle)[3]) {
  double p[3][3];
  for (int k = 0; k < 3; ++k)
    for (int i = 0; i < 3; ++i) p[k][i] = m.positions[3 * size_t(m.triangles[3 * f + k]) + i];
  const double area2 = double_area(m, f);
  if (repeated_index(m.triangles, f) || 0.5 * area2 <= eps) {
    q = 0;
    angle[0] = angle[1] = 0;
    angle[2] = 180;
    return;
  }
  double len[3];  // len[k] = |p[k+1] − p[k]|
  double dot[3];  // dot[k] = (p[k+1] − p[k]) · (p[k+2] − p[k]), for the angle at corner k
  for (int k = 0; k < 3; ++k) {
    const double* a = p[k];
    const double* b = p[(k + 1) % 3];
    const double* c = p[(k + 2) % 3];
    double l2 = 0, d = 0;
    for (int i = 0; i < 3; ++i) {
      l2 += (b[i] - a[i]) * (b[i] - a[i]);
      d += (b[i] - a[i]) * (c[i] - a[i]);
    }
    len[k] = std::sqrt(l2);
    dot[k] = d;
  }
  // |e1 × e2| = 2·area at every corner, so atan2(2·area, dot) is the angle, accurate even
  // for needles where acos of a normalised dot would lose it.
  for (int k = 0; k < 2; ++k) angle[k] = std::atan2(area2, dot[k]) * (180.0 / M_PI);
  angle[2] = std::max(0.0, 180.0 - angle[0] - angle[1]);
  // Unguarded: degenerate faces left above (a NaN corner gives NaN, not 0).
  q = quality_from(0.5 * area2, quality_denominator(len[0], len[1], len[2]));
}

QualityStats quality_of(const TriangleSoupView& mesh, const EdgeTable& table) {
  QualityStats s;
  const auto tri = mesh.triangles;
  const uint32_t nv = mesh.vertex_count();
  const uint64_t nf = mesh.face_count();
  const double eps = zero_area(table.box);
  // Distinct edges (lengths, valences) and which vertices are on a boundary edge.
  const std::vector<EdgeUse>& uses = table.uses;
  const std::vector<uint8_t>& mark = table.mark;

  // Deterministic reduce: fixed split/join tree, so the double sums (and Qav) are bit-identical
  // from run to run and for any thread count (benchmarks compare reruns exactly).
  const QualityAccumulator acc = tbb::parallel_deterministic_reduce(
      tbb::blocked_range<uint64_t>(0, nf, 1 << 13), QualityAccumulator{},
      [&](const tbb::blocked_range<uint64_t>& r, QualityAccumulator a) {
        for (uint64_t f = r.begin(); f != r.end(); ++f) {
          double q, angle[3];
          face_quality(mesh, f, eps, q, angle);
          a.add(q, angle, ((mark[tri[3 * f]] | mark[tri[3 * f + 1]] | mark[tri[3 * f + 2]]) & kOnBoundary) != 0);
        }
        return a;
      },
      [](QualityAccumulator a, const QualityAccumulator& b) { return a.merge(b); });
  s.triangles = acc.triangles;
  s.q_histogram.assign(acc.q_hist.begin(), acc.q_hist.end());
  s.min_angle_histogram.assign(acc.angle_hist.begin(), acc.angle_hist.end());
  if (acc.triangles > 0) {
    const double n = double(acc.triangles);
    s.q_min = acc.q_min;
    s.q_avg = acc.q_sum / n;
    s.min_angle_min = acc.min_angle_min;
    s.min_angle_avg = acc.min_angle_sum / n;
    s.max_angle_max = acc.max_angle_max;
    s.percent_angles_below_30 = 100.0 * double(acc.angles_below_30) / (3.0 * n);
    s.percent_triangles_below_30 = 100.0 * double(acc.triangles_below_30) / n;
  }

  // Edge lengths, and the valence (distinct neighbours) of every vertex.
  std::vector<uint32_t> valence(nv, 0);
  // Lengths are accumulated relative to the first edge's so the variance does not cancel out.
  double shift = -1, length_sum = 0, length_sum2 = 0;
  uint64_t edges = 0;
  for (size_t i = 0, j; i < uses.size(); i = j) {
    for (j = i + 1; j < uses.size() && uses[j].key == uses[i].key; ++j) {
    }
    const uint32_t a = key_min(uses[i].key), b = key_max(uses[i].key);
    ++valence[a];
    ++valence[b];
    double l2 = 0;
    for (int k = 0; k < 3; ++k) {
      const double d = double(mesh.positions[3 * size_t(a) + k]) - mesh.positions[3 * size_t(b) + k];
      l2 += d * d;
    }
    if (shift < 0) shift = std::sqrt(l2);
    const double d = std::sqrt(l2) - shift;
    length_sum += d;
    length_sum2 += d * d;
    ++edges;
  }
  if (edges > 0) {
    const double n = double(edges), mean_shifted = length_sum / n;
    s.edge_length_mean = shift + mean_shifted;
    const double variance = std::max(0.0, length_sum2 / n - mean_shifted * mean_shifted);
    s.edge_length_cv = s.edge_length_mean > 0 ? std::sqrt(variance) / s.edge_length_mean : 0;
  }
  uint64_t interior = 0, regular = 0;
  for (uint32_t v = 0; v < nv; ++v)
    if (mark[v] == kReferenced) {  // referenced, on no boundary or non-manifold edge
      ++interior;
      regular += valence[v] == 6;
    }
  if (interior > 0) s.percent_valence6 = 100.0 * double(regular) / double(interior);
  // Boundary faces apart (summed in the deterministic reduce: the same on every run).
  s.boundary_triangles = acc.boundary_triangles;
  if (s.boundary_triangles > 0) {
    s.q_min_boundary = acc.q_min_boundary;
    s.q_avg_boundary = acc.q_boundary / double(s.boundary_triangles);
  }
  if (s.triangles > s.boundary_triangles)
    s.q_avg_off_boundary = acc.q_rest / double(s.triangles - s.boundary_triangles);
  return s;
}

}  // namespace

TopologyStats compute_topology_stats(const TriangleSoupView& mesh) {
  check_soup(mesh, "compute_topology_stats");
  return topology_of(mesh, edge_table(mesh));
}

QualityStats compute_quality(const TriangleSoupView& mesh) {
  check_soup(mesh, "compute_quality");
  return quality_of(mesh, edge_table(mesh));
}

MeshFigures compute_mesh_figures(const TriangleSoupView& mesh) {
  check_soup(mesh, "compute_mesh_figures");
  const EdgeTable table = edge_table(mesh);
  MeshFigures figures;
  tbb::parallel_invoke([&] { figures.topology = topology_of(mesh, table); },
                       [&] { figures.quality = quality_of(mesh, table); });
  return figures;
}

}  // namespace streamcvd
