// Shape of the §VI-D boundary strips. The dual puts a strip vertex at the middle of each input
// boundary edge where the cluster changes, and the cluster vertices next to the boundary sit
// where their clusters' centroids project — on a small scan hole, often on the rim itself — so
// strip triangles come out as slivers (Qav ~0.4 on the dragon against ~0.87 inside). This pass
// moves the vertices of the strips to lower Σ 1/Q over their fans (optimisation-based
// smoothing as in Freitag & Ollivier-Gooch 1997, "Tetrahedral mesh improvement using swapping
// and smoothing", with a barrier-like score instead of max-min): strip vertices slide along the
// input boundary polyline between their two boundary neighbours, so the boundary stays on the
// input; the cluster vertices around them move on the input surface. Connectivity changes only
// by max-min edge flips; the vertices, the boundary edges and the topology stay.
#pragma once

#include <cstdint>
#include <span>

#include "streamcvd/core/dual/dual_mesh.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

struct StripShapeOptions {
  uint32_t sweeps = 6;  ///< Gauss-Seidel sweeps over the strip vertices and their cluster neighbours
  /// A slid strip vertex keeps the boundary between it and its neighbours within this fraction of
  /// the chord (the 30 % of the strip's Douglas–Peucker corners): the boundary keeps its shape.
  double max_chord_deviation = 0.3;
  /// Typical output edge (DualMeshOptions::strip_spacing): the boundary may also leave a chord by
  /// up to max_spacing_deviation of it, as the strip's corners do — wiggles of a scan's boundary
  /// below the output resolution do not hold a strip vertex. 0 = chord-relative only.
  double strip_spacing = 0;
  double max_spacing_deviation = 0.2;
  /// Moved cluster vertices keep their offset from the surface (QEM points, as in
  /// MeshOptimizeOptions::keep_surface_offset); false = they land on the surface.
  bool keep_surface_offset = false;
  /// A move is refused when a well-shaped (Q ≥ 0.2) face off the strip turns by more than this
  /// (degrees): the interior next to a hole keeps its shape and its distance to the input.
  double max_normal_change_deg = 15;
  /// Cluster vertices within this many rings of a strip vertex move (1 = its neighbours; 2 lets
  /// the next row give way too: dragon → 20k strip Qav 0.551 with 1, 0.557 with 2, 0.559 with 3).
  uint32_t rings = 2;
  /// Then max-min edge flips (optimize_mesh_quality's, flips only) and a second round of moves.
  bool flips = true;
};

struct StripShapeReport {
  uint64_t strip_moves = 0;    ///< strip-vertex slides (all sweeps)
  uint64_t cluster_moves = 0;  ///< moves of cluster vertices next to a strip
  uint64_t flips = 0;          ///< edges flipped between the two rounds
};

/// Q of the faces with a corner at a strip vertex (cluster_of_output_vertex < 0) and of the
/// others, apart.
struct StripQuality {
  uint64_t strip_faces = 0;
  double strip_q_min = 0, strip_q_avg = 0;  ///< 0 when there is no strip face
  double other_q_avg = 0;
};

/// StripQuality of a dual mesh's positions and triangles. O(F). Deterministic.
StripQuality strip_face_quality(std::span<const float> positions, std::span<const uint32_t> triangles,
                                std::span<const int32_t> cluster_of_output_vertex);

/// Improves the shape of the boundary strips of `dual` in place. Strip vertices with one or two
/// sources on `loops` (an edge midpoint or a corner: VertexSource) and exactly two boundary
/// neighbours slide along their loop; their sources are updated to the input edge (or vertex)
/// they end on. Cluster vertices with movable[v] ≠ 0 that are interior and within options.rings
/// rings of a strip vertex move on `surface`, from the input face surface_face[v] (updated;
/// UINT32_MAX = does not move). A move is kept only when it lowers Σ 1/Q over the vertex's faces, folds none of
/// them against the surface normal and turns no well-shaped face off the strip more than the
/// limit. movable and surface_face hold one entry per output vertex; throws InputError
/// otherwise. O(strip size · sweeps · fan size) plus O(F) set-up. Deterministic (fixed order).
StripShapeReport shape_boundary_strips(DualMesh& dual, const MeshView& surface, const BoundaryLoops& loops,
                                       std::span<const uint8_t> movable, std::span<uint32_t> surface_face,
                                       const StripShapeOptions& options = {});

}  // namespace streamcvd
