// Triangle-quality post-pass on a remeshed surface: edge flips between nearly coplanar
// triangles (a Delaunay-like improvement of the smaller quality of each flipped pair; Lawson's
// flip algorithm with Q = 6/√3·area/(half-perimeter·longest edge) as criterion) and tangential
// relaxation of free vertices towards the mean of their neighbours (tangential smoothing as in
// Botsch & Kobbelt 2004, "A remeshing approach to multiresolution modeling"), kept only where
// the ring's Q improves, then projected back onto the input surface. Connectivity changes
// only by flips: vertex and face counts, boundary, manifoldness and genus are unchanged.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "streamcvd/core/clustering/clustering.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

struct MeshOptimizeOptions {
  /// Edge flips only between two triangles whose normals differ by less than this (degrees):
  /// flipping across a bend would move the surface by up to edge·sin(angle)/2.
  double flip_max_dihedral_deg = 10;
  /// Vertices with an incident edge bent more than this (degrees) between two non-sliver
  /// triangles are on a feature: never moved.
  double feature_angle_deg = 45;
  /// The feature angle remesh() uses instead for the Q metrics (IQ, AQ): their vertices are QEM
  /// points, off the surface wherever the ring bends; only nearly flat rings move.
  double qem_feature_angle_deg = 20;
  /// Moved vertices keep their offset from the surface (position − closest surface point):
  /// for QEM points, which lie off the surface where it bends. false = vertices are taken to be
  /// on the surface (projected centroids) and land on it.
  bool keep_surface_offset = false;
  uint32_t relax_iterations = 2;  ///< relaxation sweeps (each followed by flips where vertices moved); 0 = flips only
  double relax_step = 1.0;        ///< fraction of the way to the neighbours' mean moved per sweep
  /// A move is rejected when an incident triangle's normal turns by more than this (degrees);
  /// slivers (Q < 0.2) may turn further, but not over.
  double max_normal_change_deg = 15;
};

struct MeshOptimizeReport {
  uint64_t flips = 0;  ///< edges flipped (all passes)
  uint64_t moves = 0;  ///< vertices moved
  double q_avg_before = 0, q_avg_after = 0;
};

/// Improves the triangle quality of `positions` (3 floats per vertex) and `triangles` (3
/// indices per face) in place. Boundary edges, non-manifold edges and edges bent more than
/// flip_max_dihedral_deg are never flipped; a flip never creates an existing edge, a fold or a
/// zero-area face. Only vertices with movable[v] ≠ 0 move, and only if they are interior and
/// off features. With a `surface`, moved vertices end on it (plus their offset from it when
/// keep_surface_offset): closest point found by walking its faces from surface_face[v], an
/// input face near v (updated; UINT32_MAX = v does not move); without one they move in their
/// tangent plane. movable (and surface_face with a surface) hold one entry per vertex; throws
/// InputError otherwise or for a triangle index ≥ V. O(F) per pass plus short walks.
/// Deterministic. Not thread-safe on the arrays.
MeshOptimizeReport optimize_mesh_quality(std::span<float> positions, std::span<uint32_t> triangles,
                                         std::span<const uint8_t> movable, const MeshView* surface,
                                         std::span<uint32_t> surface_face, const MeshOptimizeOptions& options = {});

/// The flips of optimize_mesh_quality (same rules, no moves) from the edges with an end flagged
/// in `near` (one entry per vertex), spreading to the edges around each flip: a pass after a
/// local change. Returns the flips. O(F · valence) to set up (in parallel), then O(edges
/// queued). Throws InputError when near.size() ≠ V or a triangle index ≥ V. Deterministic.
uint64_t flip_edges_near(std::span<float> positions, std::span<uint32_t> triangles, std::span<const uint8_t> near,
                         const MeshOptimizeOptions& options = {});

/// Closest point q of the surface `s` to p, near input face `face`: a walk of at most 32 faces
/// towards the face p projects into (moves of the quality passes are a fraction of an output
/// edge, so the walk is a few faces long). On a boundary, or when the walk turns back (across a
/// crease), the closer of the last two faces is kept. Returns the face q lies on.
uint32_t closest_point_walk(const MeshView& s, uint32_t face, const std::array<double, 3>& p, std::array<double, 3>& q);

/// Average triangle quality Q (1 = equilateral, 0 = degenerate) of a triangle soup. O(F).
double average_triangle_quality(std::span<const float> positions, std::span<const uint32_t> triangles);

}  // namespace streamcvd
