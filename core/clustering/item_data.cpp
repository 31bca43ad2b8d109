#include "streamcvd/core/clustering/item_data.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <utility>

#include <cmath>

namespace streamcvd {

ItemData compute_item_data(const MeshView& mesh, std::span<const float> density, ArrayStorage& storage,
                           ItemQuadrics quadrics) {
  const uint32_t V = mesh.vertex_count();
  ItemData items;
  if (V > 0) {
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (uint32_t v = 0; v < V; ++v)
      for (int c = 0; c < 3; ++c) {
        lo[c] = std::min(lo[c], double(mesh.positions[3 * v + c]));
        hi[c] = std::max(hi[c], double(mesh.positions[3 * v + c]));
      }
    for (int c = 0; c < 3; ++c) items.origin[c] = 0.5 * (lo[c] + hi[c]);
  }
  items.weight = LargeArray<double>(V, storage, "item weights");
  LargeArray<double> area(V, storage, "item areas");
  items.centroid = LargeArray<float>(size_t(3) * V, storage, "item centroids");
  const bool with_quadrics = quadrics == ItemQuadrics::per_vertex;
  if (with_quadrics) items.quadric = LargeArray<float>(size_t(10) * V, storage, "vertex quadrics");
  const float* P = mesh.positions.data();
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, V, 4096), [&](const tbb::blocked_range<uint32_t>& r) {
    const RangeVisit visit(mesh, "items", {r.begin(), r.end()}, kReadsPositions | kReadsTriangles | kReadsVertexFaces);
    for (uint32_t v = r.begin(); v != r.end(); ++v) {
      double w = 0, g[3] = {0, 0, 0}, pv[3] = {0, 0, 0}, q[10] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
      for_each_dual_cell_part(mesh, v, items.origin,
                              [&](double cell, const double* p, const double* pa, const double* pb, const double* x) {
                                w += cell;
                                for (int c = 0; c < 3; ++c) g[c] += cell * (22.0 * p[c] + 7.0 * pa[c] + 7.0 * pb[c]) / 36.0;
                                if (with_quadrics) add_face_quadric(cell, x, p, q);
                              });
      if (with_quadrics)
        for (int k = 0; k < 10; ++k) items.quadric[10 * size_t(v) + k] = float(q[k]);
      for (int c = 0; c < 3; ++c) pv[c] = P[3 * size_t(v) + c] - items.origin[c];
      double rho = density.empty() ? 1.0 : double(density[v]);
      for (int c = 0; c < 3; ++c) items.centroid[3 * v + c] = float(w > 0 ? g[c] / w : pv[c]);
      items.weight[v] = rho * w;
      area[v] = w;
    }
  });
  // Fixed-order sums so the totals do not depend on the thread count.
  for (uint32_t v = 0; v < V; ++v) {
    double w = items.weight[v];
    const float* g = &items.centroid[3 * v];
    items.total_weight += w;
    items.total_area += area[v];
    items.sum_weighted_norm2 += w * (double(g[0]) * g[0] + double(g[1]) * g[1] + double(g[2]) * g[2]);
  }
  return items;
}

void attach_tensors(ItemData& items, LargeArray<float> tensors) {
  items.tensor = std::move(tensors);
  items.sum_tensor_norm2 = 0;
  for (size_t v = 0; v < items.weight.size(); ++v) {
    const float* T = &items.tensor[6 * v];
    const float* g = &items.centroid[3 * v];
    double q = double(T[0]) * g[0] * g[0] + double(T[3]) * g[1] * g[1] + double(T[5]) * g[2] * g[2] +
               2.0 * (double(T[1]) * g[0] * g[1] + double(T[2]) * g[0] * g[2] + double(T[4]) * g[1] * g[2]);
    items.sum_tensor_norm2 += items.weight[v] * q;
  }
}

}  // namespace streamcvd
