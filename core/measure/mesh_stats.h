// Topology and quality figures of a mesh: what `streamcvd info` and `streamcvd quality` print,
// and what the remesher checks its output with.
#pragma once

#include <cstdint>
#include <vector>

#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

/// Conventions follow shared/data/README.md: boundary edges are used by exactly one face,
/// non-manifold edges by more than two; loops are closed boundary chains (holes touching at one
/// vertex count as one loop); components connect faces through shared vertices; duplicate
/// faces repeat an earlier face's vertex set; degenerate faces have a repeated index or zero area.
struct TopologyStats {
  uint64_t vertices = 0, faces = 0, edges = 0;
  float bbox_min[3] = {0, 0, 0}, bbox_max[3] = {0, 0, 0};
  uint64_t boundary_edges = 0, boundary_loops = 0;
  uint64_t nonmanifold_edges = 0, nonmanifold_vertices = 0;
  uint64_t duplicate_faces = 0, degenerate_faces = 0;
  uint64_t isolated_vertices = 0;   ///< referenced by no face
  uint64_t components = 0;          ///< face components (isolated vertices not counted)
  int64_t euler_characteristic = 0; ///< V − E + F over referenced vertices
  bool closed_manifold = false;     ///< no boundary, no non-manifold edge/vertex
  bool consistently_oriented = false;  ///< every interior edge used once in each direction
  int64_t genus = -1;               ///< for a closed manifold with one component: (2 − χ)/2
};

/// Computes every TopologyStats field from positions and triangles alone (no CSR needed).
/// O(F log F) time, O(F) memory. Thread-safe (pure). Throws InputError if an index is ≥ V.
/// For a store (MeshView) use the bounded-memory overload of core/measure/store_stats.h: same figures.
TopologyStats compute_topology_stats(const TriangleSoupView& mesh);

/// Triangle quality (DESIGN.md §9): Q = 6/√3 · area / (half-perimeter · longest edge), 1 for an
/// equilateral triangle. Angles in degrees.
struct QualityStats {
  uint64_t triangles = 0;
  double q_min = 0, q_avg = 0;
  double min_angle_min = 0, min_angle_avg = 0;  ///< smallest angle of each triangle
  double max_angle_max = 0;
  double percent_angles_below_30 = 0;     ///< counting all angles
  double percent_triangles_below_30 = 0;  ///< triangles whose smallest angle is < 30°
  double percent_valence6 = 0;            ///< of interior (non-boundary) referenced vertices
  double edge_length_mean = 0, edge_length_cv = 0;  ///< coefficient of variation = σ/mean
  std::vector<uint64_t> q_histogram;          ///< 20 bins over [0,1]
  std::vector<uint64_t> min_angle_histogram;  ///< 12 bins of 5° over [0,60]
  /// Faces with a corner on a boundary edge — in a remesh output, the §VI-D boundary strips —
  /// and the rest, apart: strip slivers hide in the overall Qav (few faces) but not here.
  uint64_t boundary_triangles = 0;
  double q_min_boundary = 0, q_avg_boundary = 0;  ///< over the boundary faces (0 when none)
  double q_avg_off_boundary = 0;                  ///< over the faces with no boundary corner
};

/// Computes QualityStats. O(F log F) time (edges by sorting). Thread-safe (pure).
/// Throws InputError if an index is ≥ V.
QualityStats compute_quality(const TriangleSoupView& mesh);

struct MeshFigures {
  TopologyStats topology;
  QualityStats quality;
};

/// compute_topology_stats and compute_quality together: the edge table they both start from
/// is built once, then the two run side by side (TBB). Same figures as the two calls.
MeshFigures compute_mesh_figures(const TriangleSoupView& mesh);

}  // namespace streamcvd
