// The edits of the repair loop (core/dual/repair.cpp): split_cluster (cluster_split.cpp), and
// ClusterRepair, one round of splits, island and lens dissolutions and compensating merges or
// splits over the clusters the defect tracker (core/dual/defect_tracker.h) reports. Every label
// goes through the LabelEditor (core/dual/repair_state.h). Internal to core/dual.
#pragma once

#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

#include "streamcvd/core/clustering/item_data.h"
#include "streamcvd/core/dual/dual_mesh.h"
#include "streamcvd/core/dual/dual_topology.h"
#include "streamcvd/core/dual/repair_state.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd::detail {

struct RepairRoundStats {
  uint32_t splits = 0, dissolved_islands = 0, merges = 0;
};

/// Scratch of split_cluster, reused across splits: stamps indexed by member position (sized by
/// the cluster, never by V) and the BFS queue.
struct SplitScratch {
  std::vector<uint32_t> stamp, queue;
  uint32_t next_mark = 1;
};

/// Splits the cluster whose vertices are `members` (all of them, ascending) into up to
/// new_labels.size() + 1 connected parts grown by BFS from farthest-point seeds; part k > 0
/// takes new_labels[k − 1]. With `at_defect`, a cluster that meets one neighbour along two
/// arcs is instead cut in two parts grown from those arcs, and a band (its frontier in two
/// parts) in new_labels.size() + 1 parts grown from as many paths across it (arcs are tried
/// first only with one new label; more are asked for a ring, whose frontier parts are then
/// its members next to either side of `ring`); a part under a quarter of the mean part size is
/// regrown with the others, balanced by size. A cluster in pieces (its
/// members not connected) instead gives new_labels[0] to the piece of the first member its
/// first piece leaves out: one piece parted per call. With a `hole_loop` (the vertices of a
/// boundary loop the cluster meets in two stretches or more, in loop order) and one new label,
/// the parts grow from the two longest stretches instead, so that each holds one.
/// Returns the number of new labels used (0: the cluster could not be split).
/// O(cluster size · parts · log cluster size + loop size); reads only the members and their 1-rings.
uint32_t split_cluster(const MeshView& mesh, std::span<int32_t> labels, std::span<const uint32_t> members,
                       std::span<const int32_t> new_labels, SplitScratch& scratch, bool at_defect = false,
                       const Ring* ring = nullptr, std::span<const uint32_t> hole_loop = {});

/// True when the members of the cluster `members` (all, ascending) that touch another cluster
/// form one connected part: a disc-like cluster, not a band round a thin feature.
/// O(Σ degree · log) over the members.
bool frontier_in_one_part(const MeshView& mesh, std::span<const int32_t> labels, std::span<const uint32_t> members,
                          SplitScratch& scratch);

/// True when each cluster of `parts` has dual faces (corners with three distinct labels) around
/// the vertices `members`, and they form one fan that dual::fan_defective accepts (no edge in
/// more than two faces or twice one way, no two faces on one vertex set). `members` must hold
/// every vertex of the parts (e.g. a cluster just split into them), which must not touch the
/// boundary (strip faces are not built here). O(faces of the members · log); thread-safe.
bool parts_are_discs(const MeshView& mesh, std::span<const int32_t> labels, std::span<const uint32_t> members,
                     std::span<const int32_t> parts, dual::FanScratch& scratch);

/// One repair round at a time with state that persists across rounds: per-cluster weights and
/// boundary contact (refreshed for the clusters whose members changed), and K-sized flag arrays
/// cleared through their lists. Memory O(K) plus the members of the clusters a round reads.
/// Not thread-safe (its refresh runs TBB-parallel inside).
class ClusterRepair {
 public:
  /// Weighs every cluster once: O(V) reads, parallel over the clusters.
  ClusterRepair(const MeshView& mesh, const ItemData& items, LabelEditor& labels, uint32_t K,
                std::span<const uint8_t> adjustable, const BoundaryLoops& loops);

  /// Splits in two and dissolves the clusters of `defect_clusters` (sorted, unique), splits in
  /// three those of them in `rings` (sorted by cluster; DefectTracker::rings), and changes
  /// the number of non-empty clusters by `count_change` with compensating merges or splits (0:
  /// the count stays). A cluster of `open_holes` (sorted; DefectTracker::open_holes) is cut
  /// between its two longest stretches along the hole's loop. With `keep_strips` those
  /// compensations only touch clusters off the boundary, so the strip vertices of the dual stay
  /// as they are. Returns the clusters changed
  /// (sorted, unique). O(vertices of the clusters it reads and their 1-rings) + a few O(K) scans.
  std::vector<int32_t> round(std::span<const int32_t> defect_clusters, std::span<const Ring> rings,
                             std::span<const OpenHole> open_holes, int64_t count_change, bool keep_strips,
                             RepairRoundStats& stats);

  /// Changes the number of non-empty clusters by `count_change` with merges or splits off the
  /// boundary, away from `keep_off` (sorted) and its neighbours: a round's second compensation,
  /// once its splits have changed the strips. Returns the clusters changed, as round.
  std::vector<int32_t> compensate(int64_t count_change, std::span<const int32_t> keep_off, RepairRoundStats& stats);

 private:
  void refresh(std::span<const int32_t> clusters);
  std::span<const uint32_t> members_of(int32_t c);
  void neighbour_clusters(int32_t c, std::vector<int32_t>& out);
  std::span<const int32_t> neighbours_now(int32_t c, std::vector<int32_t>& fresh);
  uint32_t size_of(int32_t c);
  void merge_tips(std::span<const Ring> rings, std::vector<int32_t>& free_ids, std::vector<int32_t>& touched,
                  RepairRoundStats& stats);

  const MeshView& mesh_;
  const BoundaryLoops& loops_;
  const ItemData& items_;
  LabelEditor& labels_;
  const uint32_t K_;
  std::span<const uint8_t> adjustable_;
  std::vector<double> weight_;
  std::vector<uint8_t> touches_boundary_;
  std::vector<uint8_t> repaired_;  // clusters on a defect in an earlier round: no compensation there
  ClusterSet is_defect_, near_, used_, beside_merge_, spared_;
  std::vector<int32_t> partner_;
  std::unordered_map<int32_t, std::vector<uint32_t>> round_members_;
  std::unordered_map<int32_t, std::vector<int32_t>> round_neighbours_;  // merge candidates' lists
  SplitScratch scratch_;
  dual::FanScratch fan_scratch_;
};

}  // namespace streamcvd::detail
