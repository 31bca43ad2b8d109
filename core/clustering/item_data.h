// Per-vertex clustering items (paper §V): the weight M_j and centroid γ_j of each vertex's dual
// cell, with the density ρ as a per-vertex factor (eq. 10, 11; eq. 20 once curvature is known).
#pragma once

#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include "streamcvd/core/mesh/large_array.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

struct ItemData {
  /// Frame origin: γ and cluster sums are stored relative to it (the bbox centre) so that
  /// float32 centroids and double sums keep their precision far from the origin.
  double origin[3] = {0, 0, 0};
  LargeArray<double> weight;   ///< M_j = ρ_j · |P_j|, |P_j| = a third of the incident triangle areas
  LargeArray<float> centroid;  ///< γ_j − origin, 3 per vertex: centroid of the barycentric dual cell
  double total_weight = 0;      ///< Σ M_j
  double total_area = 0;        ///< Σ |P_j|: the surface area (ρ not applied)
  double sum_weighted_norm2 = 0;  ///< Σ M_j ‖γ_j‖² (the constant of eq. 13, for reporting E)
  /// Metrics A/AQ: per-vertex tensor T_j (xx, xy, xz, yy, yz, zz); the item tensor of eq. 16
  /// is K_j = M_j·T_j, so the anisotropic energy is area-weighted like the isotropic one.
  LargeArray<float> tensor;
  double sum_tensor_norm2 = 0;  ///< Σ γ_jᵀK_jγ_j (the constant of eq. 17, for reporting E)
  /// Metrics IQ/AQ: per-vertex Garland-Heckbert quadric (paper §V-C, ref [28]), the sum over
  /// the vertex's faces of (area/3)·(nᵀ(x − p))², x relative to `origin`: 10 floats, A_xx, A_xy,
  /// A_xz, A_yy, A_yz, A_zz (length²), b_x, b_y, b_z (length³), c (length⁴), with
  /// Q(x) = xᵀAx + 2bᵀx + c. Zero-area faces and isolated vertices contribute zeros.
  LargeArray<float> quadric;
};

/// Visits the barycentric dual cell of vertex v face by face: fn(cell, pv, pa, pb, x) for each
/// face (v, a, b) of v in its orientation, with cell = a third of the face's area, the corners in
/// double relative to `origin` and x = (pa − pv) × (pb − pv), the face's normal of length
/// 2·area. O(deg v), no allocation. The one definition of |P_j| (eq. 10): the item weights, the
/// vertex quadrics and the area-weighted attribute means (core/mesh/vertex_attributes.h) use it.
template <class Fn>
inline void for_each_dual_cell_part(const MeshView& mesh, uint32_t v, const double origin[3], const Fn& fn) {
  const float* P = mesh.positions.data();
  const uint32_t* T = mesh.triangles.data();
  const double pv[3] = {P[3 * size_t(v)] - origin[0], P[3 * size_t(v) + 1] - origin[1], P[3 * size_t(v) + 2] - origin[2]};
  for (uint32_t f : mesh.faces_of(v)) {
    const uint32_t i0 = T[3 * size_t(f)], i1 = T[3 * size_t(f) + 1], i2 = T[3 * size_t(f) + 2];
    uint32_t a = i0 == v ? i1 : i0, b = i2 == v ? i1 : i2;
    if (i1 == v) {
      a = i2;
      b = i0;
    }
    double pa[3], pb[3];
    for (int c = 0; c < 3; ++c) {
      pa[c] = P[3 * size_t(a) + c] - origin[c];
      pb[c] = P[3 * size_t(b) + c] - origin[c];
    }
    const double e1[3] = {pa[0] - pv[0], pa[1] - pv[1], pa[2] - pv[2]};
    const double e2[3] = {pb[0] - pv[0], pb[1] - pv[1], pb[2] - pv[2]};
    const double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2], cz = e1[0] * e2[1] - e1[1] * e2[0];
    const double x[3] = {cx, cy, cz};
    fn(std::sqrt(cx * cx + cy * cy + cz * cz) / 6.0, pv, pa, pb, x);
  }
}

/// Adds `cell` · the plane quadric of a face to q (the order of ItemData::quadric): x is the
/// face's normal (any length), p a point of the face, both relative to the items' origin. A face
/// without a plane (zero or non-finite normal) adds nothing. O(1).
inline void add_face_quadric(double cell, const double x[3], const double p[3], double q[10]) {
  const double len = std::sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]);
  if (!(len > 0) || !std::isfinite(len)) return;
  const double n[3] = {x[0] / len, x[1] / len, x[2] / len};
  const double d = -(n[0] * p[0] + n[1] * p[1] + n[2] * p[2]);
  q[0] += cell * n[0] * n[0];
  q[1] += cell * n[0] * n[1];
  q[2] += cell * n[0] * n[2];
  q[3] += cell * n[1] * n[1];
  q[4] += cell * n[1] * n[2];
  q[5] += cell * n[2] * n[2];
  q[6] += cell * d * n[0];
  q[7] += cell * d * n[1];
  q[8] += cell * d * n[2];
  q[9] += cell * d * d;
}

/// What compute_item_data fills besides M_j and γ_j.
enum class ItemQuadrics : uint8_t { none, per_vertex };

/// Computes M_j and γ_j for every vertex. The barycentric dual cell of vertex v in triangle
/// (v, a, b) has area A/3 and centroid (22v + 7a + 7b)/36. `density` (size V, or empty for
/// ρ = 1) multiplies each weight. Isolated vertices get weight 0 and γ = their position.
/// With ItemQuadrics::per_vertex it also fills ItemData::quadric (metrics IQ/AQ) in the same
/// pass over the faces. O(F) time; TBB-parallel over vertices (chunk order), deterministic. The
/// arrays (20 bytes per vertex, 60 with quadrics) come from `storage`.
ItemData compute_item_data(const MeshView& mesh, std::span<const float> density = {},
                           ArrayStorage& storage = ram_storage(), ItemQuadrics quadrics = ItemQuadrics::none);

/// Sets items.tensor (6 floats per vertex) and the constant Σ γ_jᵀK_jγ_j. O(V), fixed order.
void attach_tensors(ItemData& items, LargeArray<float> tensors);

}  // namespace streamcvd
