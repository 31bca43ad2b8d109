// Per-vertex principal curvatures and directions by local polynomial fitting: a degree-2 jet
// z = a x² + b xy + c y² + d x + e y (+ f) fitted by least squares over the vertex's k-ring in
// its tangent frame, in the manner of Cazals & Pouget 2005, "Estimating differential quantities
// using polynomial fitting of osculating jets" (paper §VI-H, ref [30]); the curvatures feed the
// anisotropic metric of the clustering (DESIGN.md).
#pragma once

#include <cstdint>
#include <vector>

#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

/// Per-vertex curvature, indexed like the mesh's vertices.
struct Curvature {
  std::vector<float> k1, k2;      ///< principal curvatures, k1 ≥ k2, in 1/length; > 0 where the
                                  ///< surface is convex w.r.t. its face orientation (outward normals)
  std::vector<float> d1, d2;      ///< principal directions, 3 floats per vertex, unit, d1 ⟂ d2
  std::vector<uint8_t> fallback;  ///< 1 where no fit was possible: k1 = k2 = 0, d1, d2 span the
                                  ///< estimated tangent plane (or the x, y axes without a normal)
  uint64_t fallback_count = 0;    ///< number of 1s in `fallback`
  uint32_t vertex_count() const { return static_cast<uint32_t>(k1.size()); }
};

struct CurvatureOptions {
  int rings = 3;                   ///< neighbourhood: vertices within this many edges (≥ 1)
  int max_rings = 5;               ///< grow the ring up to here while too few neighbours were found
  int min_neighbours = 6;          ///< fewer neighbours even at max_rings → fallback (raised to the
                                   ///< number of unknowns when smaller)
  uint32_t max_neighbours = 1024;  ///< stop growing once a ring reaches this many (hub vertices)
  bool fit_constant = true;        ///< fit f too: approximates instead of interpolating the vertex,
                                   ///< more robust on noisy scans
  bool gaussian_weights = false;   ///< weight point i by exp(-|p_i - p|² / h²), h = ring radius
  double min_rcond = 1e-10;        ///< normal matrices whose estimated reciprocal condition number
                                   ///< is below this (collinear or tiny neighbourhoods) → fallback
};

/// Principal curvatures and directions of every vertex of `mesh` (positions, triangles and both
/// CSR adjacencies are read; chunks schedule the work). Per vertex: k-ring by BFS (grown up to
/// max_rings if needed), normal from area-weighted face normals (PCA of the ring if they cancel),
/// a first fit whose linear terms correct the normal, a second fit in the corrected frame, and
/// the exact shape operator of the fitted graph at the origin. Throws InputError when the arrays
/// disagree in size or the chunks do not tile [0, V). O(V · n) with n ≈ ring size, ~33 B/vertex;
/// TBB-parallel over chunks and vertices, each vertex computed alone by one task, so the result
/// is bit-identical for any thread count. Thread-safe.
Curvature compute_curvature(const MeshView& mesh, const CurvatureOptions& options = {});

}  // namespace streamcvd
