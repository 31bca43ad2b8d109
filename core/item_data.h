// Per-vertex clustering items (paper §V): the weight M_j and centroid γ_j of each vertex's dual
// cell, with the density ρ as a per-vertex factor (eq. 10, 11; eq. 20 once curvature is known).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/large_array.h"
#include "core/mesh_view.h"

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
  /// Metrics IQ/AQ: per-vertex quadric, 10 floats (A 6, b 3, c), relative to `origin`.
  LargeArray<float> quadric;
};

/// Computes M_j and γ_j for every vertex. The barycentric dual cell of vertex v in triangle
/// (v, a, b) has area A/3 and centroid (22v + 7a + 7b)/36. `density` (size V, or empty for
/// ρ = 1) multiplies each weight. Isolated vertices get weight 0 and γ = their position.
/// O(F) time; TBB-parallel over vertices (chunk order), deterministic. The arrays (20 bytes per
/// vertex) come from `storage`.
ItemData compute_item_data(const MeshView& mesh, std::span<const float> density = {},
                           ArrayStorage& storage = ram_storage());

/// Sets items.tensor (6 floats per vertex) and the constant Σ γ_jᵀK_jγ_j. O(V), fixed order.
void attach_tensors(ItemData& items, LargeArray<float> tensors);

}  // namespace streamcvd
