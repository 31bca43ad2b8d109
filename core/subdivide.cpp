#include "core/subdivide.h"

#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>

namespace streamcvd {

MeshBuffers subdivide_linear(const TriangleSoupView& mesh) {
  const uint64_t F = mesh.face_count();
  const uint32_t V = mesh.vertex_count();
  const uint32_t* T = mesh.triangles.data();
  // Undirected edges (lo, hi, slot) sorted, so each distinct edge gets one midpoint id.
  struct Edge {
    uint32_t lo, hi;
    uint64_t slot;  // 3·face + corner
  };
  std::vector<Edge> edges;
  edges.reserve(3 * F);
  for (uint64_t f = 0; f < F; ++f)
    for (int i = 0; i < 3; ++i) {
      uint32_t u = T[3 * f + i], v = T[3 * f + (i + 1) % 3];
      edges.push_back({std::min(u, v), std::max(u, v), 3 * f + i});
    }
  tbb::parallel_sort(edges.begin(), edges.end(), [](const Edge& a, const Edge& b) {
    return a.lo != b.lo ? a.lo < b.lo : (a.hi != b.hi ? a.hi < b.hi : a.slot < b.slot);
  });
  MeshBuffers out;
  out.positions.assign(mesh.positions.begin(), mesh.positions.end());
  std::vector<uint32_t> midpoint_of_slot(3 * F);
  uint32_t next = V;
  for (size_t i = 0; i < edges.size();) {
    size_t j = i;
    while (j < edges.size() && edges[j].lo == edges[i].lo && edges[j].hi == edges[i].hi) ++j;
    for (int c = 0; c < 3; ++c)
      out.positions.push_back(0.5f * (mesh.positions[3 * size_t(edges[i].lo) + c] + mesh.positions[3 * size_t(edges[i].hi) + c]));
    for (size_t k = i; k < j; ++k) midpoint_of_slot[edges[k].slot] = next;
    ++next;
    i = j;
  }
  out.triangles.reserve(12 * F);
  for (uint64_t f = 0; f < F; ++f) {
    uint32_t a = T[3 * f], b = T[3 * f + 1], c = T[3 * f + 2];
    if (a == b || b == c || a == c) {
      out.triangles.insert(out.triangles.end(), {a, b, c});
      continue;
    }
    uint32_t ab = midpoint_of_slot[3 * f], bc = midpoint_of_slot[3 * f + 1], ca = midpoint_of_slot[3 * f + 2];
    out.triangles.insert(out.triangles.end(), {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca});
  }
  return out;
}

int subdivision_levels(uint64_t input_vertices, uint64_t clusters, int requested, double min_vertices_per_cluster) {
  if (requested >= 0) return requested;
  int levels = 0;
  double v = double(input_vertices);
  while (levels < 6 && clusters > 0 && v < min_vertices_per_cluster * double(clusters)) {
    v *= 4.0;
    ++levels;
  }
  return levels;
}

}  // namespace streamcvd
