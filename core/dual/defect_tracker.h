// The repair loop's defect check (core/dual/repair.cpp): the defects of find_manifold_defects on
// the dual that build_dual_mesh would build, strips included, found from the labels alone with
// the dual topology of core/dual/dual_topology.h (triples, strip faces, fan test, unjoined
// pairs), and kept up to date incrementally as labels change. Internal to core/dual.
#pragma once

#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "streamcvd/core/clustering/cluster_members.h"
#include "streamcvd/core/dual/dual_mesh.h"
#include "streamcvd/core/dual/dual_topology.h"
#include "streamcvd/core/dual/repair_state.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd::detail {

/// Labels-only defect finder on the dual of a clustering that changes a little at a time. A
/// dual vertex's defect status depends only on the faces around it, and a dual face changes only
/// when a corner of its input triangle changes label: after a change, only the clusters on the
/// changed vertices' 1-rings (and on boundary loops that changed) are re-checked. Memory O(K)
/// plus the boundary and the dual faces (12 bytes each, about 2K); `mesh`, `loops` and
/// `members` must outlive it. Not thread-safe (its checks run TBB-parallel inside).
class DefectTracker {
 public:
  DefectTracker(const MeshView& mesh, const BoundaryLoops& loops, uint32_t K, const DualMeshOptions& options,
                const ClusterMembers& members);

  /// Checks every cluster: O(V + F) reads, chunk-parallel. Returns the clusters on defects and
  /// those around a defective strip vertex (sorted, unique).
  std::vector<int32_t> check_all(std::span<const int32_t> labels);

  /// Re-checks the clusters whose faces may differ since the last check: `log` lists the label
  /// changes since then, in order (a vertex may appear several times). O(vertices and faces of
  /// the clusters around the changes) + O(boundary). Returns as check_all.
  std::vector<int32_t> check_changes(std::span<const int32_t> labels, std::vector<LabelChange> log);

  /// Dual vertices on a defect at the last check (fan defects and clusters on no dual face).
  uint64_t defect_vertices() const { return defect_vertices_; }
  /// Input-adjacent cluster pairs with no dual edge at the last check (dual::unjoined_pairs).
  uint64_t unjoined_pairs() const { return unjoined_pairs_; }
  /// Strip vertices the dual of the last checked labels adds (0 without strips).
  uint32_t strip_vertices() const { return strip_vertices_; }
  /// Strip vertices the dual of `labels` adds now (0 without strips), without a check: lets a
  /// repair round set the count after its splits changed the strips. O(boundary size).
  uint32_t strip_vertices_now(std::span<const int32_t> labels) const;
  /// The rings among the clusters on defects at the last check, sorted by cluster.
  const std::vector<Ring>& rings() const { return rings_; }
  /// Clusters that keep a hole below the output resolution open at the last check, with the
  /// hole's loop (each meets it in two stretches: boundary_strip_faces). Not defects: the dual
  /// is valid. Sorted, unique.
  const std::vector<OpenHole>& open_holes() const { return open_holes_; }
  /// The dual faces of the labels at the last check (strips not included), as collect_triples
  /// would give them: kept up to date by every check, so that the dual is built without
  /// reading the mesh again. Moved out: the tracker must not check after this. O(1).
  dual::Triples take_triples() { return std::move(triples_); }

 private:
  std::vector<int32_t> check(std::span<const int32_t> labels, bool all);
  // Marks c defective; true when it was not.
  bool mark_defective(int32_t c);
  void find_rings(std::span<const dual::Face> faces);

  const MeshView& mesh_;
  const BoundaryLoops& loops_;
  const uint32_t K_;
  const bool strips_;
  const DualMeshOptions options_;
  const ClusterMembers& members_;
  ClusterSet set_;
  std::vector<uint8_t> defective_, has_faces_;
  std::vector<int32_t> defective_list_;
  std::vector<std::pair<uint32_t, uint32_t>> loop_of_vertex_;  // {boundary loop vertex, loop}
  uint64_t defect_vertices_ = 0;
  uint64_t unjoined_pairs_ = 0;
  uint32_t strip_vertices_ = 0;
  std::vector<Ring> rings_;
  std::vector<OpenHole> open_holes_;
  dual::Triples triples_;  // faces and repeats of the last check (D-sized, no neighbour pairs)
};

}  // namespace streamcvd::detail
