// A compact bounding-volume hierarchy over triangles for closest-point queries (surface
// distances, projection onto a reference surface). Flat node array, float32 boxes, binned SAH
// build (Wald 2007, "On fast construction of SAH-based BVHs"), stack-based nearest-child-first
// traversal pruned by squared box distance; the point-triangle step is Ericson's
// ClosestPtPointTriangle (Real-Time Collision Detection, §5.1.5) evaluated in double.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

/// One BVH node: its box and either two children or a run of triangles.
/// count == 0: interior, children are nodes `index` and `index + 1` (allocated as a pair).
/// count > 0: leaf holding triangles [index, index + count) of TriangleBvh::corners/faces.
struct BvhNode {
  float lo[3] = {0, 0, 0};
  float hi[3] = {0, 0, 0};
  uint32_t index = 0;
  uint32_t count = 0;
};
static_assert(sizeof(BvhNode) == 32, "two nodes per cache line");

/// Closest-point BVH over a triangle soup. Owns a copy of the triangle corners in leaf order
/// (no reference to the source mesh is kept), so it can outlive the soup it was built from.
/// Memory: 32 bytes per node (≈ 0.6 nodes per face) + 40 bytes per face, about 60 bytes/face.
struct TriangleBvh {
  std::vector<BvhNode> nodes;   ///< root is nodes[0]; empty when the mesh has no faces
  std::vector<float> corners;   ///< 9 floats per triangle (a, b, c) in leaf order
  std::vector<uint32_t> faces;  ///< source face index of each triangle in leaf order
  uint32_t depth = 0;           ///< longest root-to-leaf path, in edges (≤ kBvhMaxDepth)

  uint64_t face_count() const { return faces.size(); }
  bool empty() const { return faces.empty(); }
  /// Bytes held by the three arrays (capacity, not size).
  uint64_t memory_bytes() const {
    return nodes.capacity() * sizeof(BvhNode) + corners.capacity() * sizeof(float) + faces.capacity() * sizeof(uint32_t);
  }
};

/// Upper bound on TriangleBvh::depth: past depth 64 the build switches to median splits, so the
/// depth stays below 64 + log2(F); queries use a fixed stack of this size.
inline constexpr uint32_t kBvhMaxDepth = 100;

/// Builds the BVH of every face of `mesh`, degenerate (zero-area) and duplicate faces included;
/// unreferenced vertices are ignored. Throws InputError when a face uses a vertex index ≥ V, a
/// referenced coordinate is not finite, or F ≥ 2^31. O(F log F) work, TBB-parallel; the tree is
/// identical for any thread count. Thread-safe (pure).
TriangleBvh build_triangle_bvh(const TriangleSoupView& mesh);

/// Result of a closest-point query. face == kNoFace (and distance_squared == the bound) when no
/// triangle lies closer than the bound given to closest_point().
struct ClosestHit {
  static constexpr uint32_t kNoFace = std::numeric_limits<uint32_t>::max();
  double distance_squared = std::numeric_limits<double>::infinity();
  std::array<double, 3> point = {0, 0, 0};  ///< closest point on the surface
  uint32_t face = kNoFace;                  ///< source face index of the closest triangle
};

/// Closest point of the BVH's surface to `p`, searching only for squared distances strictly
/// below `max_distance_squared` (pass a known upper bound to prune harder). Ties keep the first
/// triangle met in the (deterministic) traversal. O(log F) typical. Thread-safe (const reads).
ClosestHit closest_point(const TriangleBvh& bvh, std::array<double, 3> p,
                         double max_distance_squared = std::numeric_limits<double>::infinity());

/// Closest point to `p` on triangle (a, b, c), in double (Ericson §5.1.5, Voronoi regions of
/// the vertices, edges and face). Degenerate triangles (collinear or coincident corners) are
/// handled as the union of their three edges. O(1). Thread-safe.
std::array<double, 3> closest_point_on_triangle(const std::array<double, 3>& p, const std::array<double, 3>& a,
                                                const std::array<double, 3>& b, const std::array<double, 3>& c);

}  // namespace streamcvd
