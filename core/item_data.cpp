#include "core/item_data.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <utility>

#include <cmath>

namespace streamcvd {

ItemData compute_item_data(const MeshView& mesh, std::span<const float> density, ArrayStorage& storage) {
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
  const float* P = mesh.positions.data();
  const uint32_t* T = mesh.triangles.data();
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, V, 4096), [&](const tbb::blocked_range<uint32_t>& r) {
    const RangeVisit visit(mesh, "items", {r.begin(), r.end()}, kReadsPositions | kReadsTriangles | kReadsVertexFaces);
    for (uint32_t v = r.begin(); v != r.end(); ++v) {
      double w = 0, g[3] = {0, 0, 0};
      const double pv[3] = {P[3 * v] - items.origin[0], P[3 * v + 1] - items.origin[1], P[3 * v + 2] - items.origin[2]};
      for (uint32_t f : mesh.faces_of(v)) {
        uint32_t i0 = T[3 * f], i1 = T[3 * f + 1], i2 = T[3 * f + 2];
        uint32_t a = i0 == v ? i1 : i0, b = i2 == v ? i1 : i2;
        if (i1 == v) { a = i2; b = i0; }
        double pa[3], pb[3];
        for (int c = 0; c < 3; ++c) {
          pa[c] = P[3 * a + c] - items.origin[c];
          pb[c] = P[3 * b + c] - items.origin[c];
        }
        double e1[3] = {pa[0] - pv[0], pa[1] - pv[1], pa[2] - pv[2]};
        double e2[3] = {pb[0] - pv[0], pb[1] - pv[1], pb[2] - pv[2]};
        double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2], cz = e1[0] * e2[1] - e1[1] * e2[0];
        double cell = std::sqrt(cx * cx + cy * cy + cz * cz) / 6.0;  // a third of the triangle area
        w += cell;
        for (int c = 0; c < 3; ++c) g[c] += cell * (22.0 * pv[c] + 7.0 * pa[c] + 7.0 * pb[c]) / 36.0;
      }
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
