// Per-vertex metric fields for the clustering (paper §V-C, §VI-H): the gradation density of
// eq. 20 (metric I(γ)), the anisotropic tensors of eqs. 21-22 (metrics A, AQ) and the
// truncated-eigen QEM solve of the metrics IQ, AQ (the per-vertex quadrics are item data,
// core/clustering/item_data.h, filled in the same pass as the dual cells). Pure functions
// of the mesh and its curvature (core/fields/curvature.h); the clustering energy lives elsewhere.
//
// Robustness choices, shared by the density and the tensors:
//  - Curvature statistics are area-weighted (|P_j| = a third of the incident triangle areas) over
//    vertices whose jet fit succeeded; a fallback vertex (Curvature::fallback) is given the
//    reference magnitude s, i.e. treated as "typical", neither flat nor a spike.
//  - The magnitude c = √(k1² + k2²) is clamped to [lo, hi] with
//      lo = max(P_low, min_ratio · s),  hi = max(lo, min(P_high, max_ratio · s)),
//    P_* area-weighted percentiles, s = area-weighted median of c (the area-weighted mean when
//    more than half the area is flat, so a plane-plus-sphere still has a reference). Hence
//    lo / s ≥ min_ratio and hi / s ≤ max(1, max_ratio): a single spike cannot starve the rest.
//  - A flat mesh (s · √area < flat_threshold) gets the uniform field: density 1, tensor I.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "streamcvd/core/fields/curvature.h"
#include "streamcvd/core/mesh/large_array.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

struct MetricFieldOptions {
  double percentile_low = 0.02;   ///< lower clamp of c: area-weighted percentile (P2)
  double percentile_high = 0.98;  ///< upper clamp of c: area-weighted percentile (P98)
  double min_ratio = 0.1;         ///< lower clamp ≥ min_ratio · s (floor relative to the median)
  double max_ratio = 10.0;        ///< upper clamp ≤ max_ratio · s (ceiling relative to the median)
  double isotropic_blend = 0.25;  ///< κ0 = blend · area-weighted mean of (|k1| + |k2|) / 2
  double max_anisotropy = 100.0;  ///< cap on λmax / λmin of each tensor (elongation ≤ √ of it)
  double flat_threshold = 1e-2;   ///< s · √(total area) below this: the mesh is flat (median radius
                                  ///< of curvature ≥ 100 × its size); what the fit measures there is
                                  ///< float rounding (a tilted plane 100 sizes from the origin: ~1e-4)
};

/// The clamp applied to the curvature magnitude, as computed from a mesh (for reporting).
struct CurvatureRange {
  double reference = 0;  ///< s: area-weighted median of c (mean when the median is 0), 1/length;
                         ///< 0 when the mesh is flat (see flat_threshold)
  double low = 0;        ///< lo, see the file comment; 0 only when reference is 0
  double high = 0;       ///< hi ≥ lo
};

/// The clamp [lo, hi] of c = √(k1² + k2²) for `mesh` and its `curvature` (file comment).
/// Throws InputError when sizes disagree or options are out of range (percentiles in [0, 1],
/// low ≤ high, 0 < min_ratio ≤ 1 ≤ max_ratio). O(V log V) (one sort); TBB-parallel. Thread-safe.
CurvatureRange curvature_range(const MeshView& mesh, const Curvature& curvature, const MetricFieldOptions& options = {});

/// Per-vertex density multiplier ρ_j / |P_j| = c_j^γ of eq. 20 (c clamped to the range above),
/// scaled so its area-weighted mean is 1: pass it as RemeshOptions::density, which
/// compute_item_data multiplies into M_j = ρ_j·|P_j|. γ = 0 gives exact ones; a flat mesh gives
/// ones. Bound: max/min ≤ (hi/lo)^|γ| ≤ (max_ratio/min_ratio)^|γ| (10^(2|γ|) by default), every
/// value finite and > 0. Throws InputError on size mismatch, bad options, or γ not in [-8, 8]
/// (beyond, float32 would under/overflow). Scale-invariant. O(V log V); TBB-parallel; thread-safe.
std::vector<float> gradation_density(const MeshView& mesh, const Curvature& curvature, double gamma,
                                     const MetricFieldOptions& options = {});

/// Anisotropic metric of eqs. 21-22 with an isotropic blend, so that every tensor is positive
/// definite (the reference implementation's tensor is zero on flat regions):
///   K_j = ( a1' D1 D1ᵀ + a2' D2 D2ᵀ + κ0 n nᵀ ) / N,   a' = a + κ0,   n = D1 × D2,
/// a_i = |k_i| scaled down by min(1, hi / c) (the magnitude clamp; it keeps the ratio k1:k2),
/// then capped at (max_anisotropy − 1)·κ0; κ0 = isotropic_blend · area-weighted mean of
/// (a1 + a2)/2 before the cap. Bound: λmax/λmin ≤ min(max_anisotropy, 1 + hi/κ0); a cylinder
/// (k1 = 1/r, k2 = 0) gets λ_around/λ_axis = 1 + 2/blend = 9 by default, elongation 3.
/// N = area-weighted mean of (a1' + a2')/2 makes the mean tangential half-trace 1 — the scale
/// of the isotropic metric I (ρ = 1), so energies and thresholds stay comparable across metrics
/// and mesh units; a flat region then gets K = (κ0/N)·I (= blend/(1+blend)·I on a mostly flat
/// mesh). A flat mesh gets K = I.
struct AnisotropicField {
  std::vector<float> tensors;  ///< 6 per vertex: K_xx, K_xy, K_xz, K_yy, K_yz, K_zz (dimensionless)
  std::vector<float> density;  ///< √(λ1 λ2) of the tangential part, (a1'·a2')^½ / N: the metric's
                               ///< area factor; initial sampling with this density gives clusters
                               ///< of Euclidean area ∝ 1 / √(λ1 λ2)
  double kappa0 = 0;           ///< κ0 in 1/length (1 on a flat mesh)
  double scale = 1;            ///< N in 1/length
  double max_ratio = 1;        ///< the bound on λmax/λmin above
};

/// The field above for every vertex. A vertex whose D1, D2 are not usable (zero, non-finite,
/// parallel) gets the isotropic tensor ((a1' + a2')/2N)·I. Throws InputError like
/// gradation_density. O(V log V); TBB-parallel, deterministic; thread-safe.
AnisotropicField anisotropic_field(const MeshView& mesh, const Curvature& curvature,
                                   const MetricFieldOptions& options = {});
/// Just the tensors of anisotropic_field (6 floats per vertex, same order).
std::vector<float> anisotropic_tensors(const MeshView& mesh, const Curvature& curvature,
                                       const MetricFieldOptions& options = {});

/// Minimiser of Q(x) = xᵀAx + 2bᵀx + c, solved around `centroid` with a truncated pseudo-inverse:
/// x = centroid + Σ_{λ_k > t·λmax} u_k u_kᵀ (−b − A·centroid) / λ_k (eigen-decomposition of the
/// symmetric A, Eigen computeDirect), t = relative_threshold (1e-3 is a sound default). Along a
/// flat cluster's plane the point stays at the centroid (projected on the plane); a crease keeps
/// its position along the crease; a corner is found exactly. A = xx,xy,xz,yy,yz,zz as above.
/// Returns the rank kept (0 → out = centroid, also for non-finite input). O(1), no allocation.
int qem_point(const double A[6], const double b[3], const double centroid[3], double relative_threshold,
              double out[3]);

/// Q(x) for a quadric stored as 10 values in the order of ItemData::quadric. O(1).
double quadric_value(const double q[10], const double x[3]);

}  // namespace streamcvd
