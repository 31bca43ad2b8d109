// Topological repair of a clustering whose dual mesh has defects (non-manifold edges or
// vertices, isolated vertices, duplicate faces). Defects come from features thinner than a
// cluster: a cluster enclosed by one other (an island), wrapping a tube or a hole (fewer than
// three neighbours), or meeting a neighbour along two separate frontiers. The repair splits
// such clusters in three and dissolves islands into their surrounding cluster, and keeps the
// cluster count N exact by merging the lightest adjacent pairs far from any defect (or
// splitting the heaviest clusters). Constrained clustering then relaxes the touched region.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/clustering.h"
#include "core/dual_mesh.h"
#include "core/item_data.h"
#include "core/mesh_view.h"

namespace streamcvd {

struct RepairRoundStats {
  uint32_t splits = 0, dissolved_islands = 0, merges = 0;
};

/// One repair round on `labels` (K clusters, all non-empty before and after). Every cluster
/// stays connected. Returns the clusters whose vertices changed (for the relaxation to start
/// from). `adjustable` (size K) marks the clusters that compensating merges and splits may
/// use (not those of small components copied as they are). O(V + E) per round. Deterministic.
std::vector<int32_t> repair_clusters(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                                     uint32_t cluster_count, std::span<const int32_t> defect_clusters,
                                     std::span<const uint8_t> adjustable, RepairRoundStats& stats);

/// Per-vertex visit stamps reused across splits (one allocation per repair round).
struct SplitScratch {
  std::vector<uint32_t> stamp;
  uint32_t next_mark = 1;
};

/// Splits the cluster holding `members` into up to new_labels.size() + 1 connected parts grown
/// by BFS from farthest-point seeds; part k > 0 takes new_labels[k − 1]. Returns the number of
/// new labels used (0: the cluster could not be split). O(cluster size · parts).
uint32_t split_cluster(const MeshView& mesh, std::span<int32_t> labels, std::span<const uint32_t> members,
                       std::span<const int32_t> new_labels, SplitScratch& scratch);

struct DefectRepairOptions {
  uint32_t max_rounds = 40;     ///< repair rounds at most (RemeshOptions::repair_rounds)
  DualMeshOptions dual;         ///< the dual as it will be built (strips, closed holes)
  bool relax = true;            ///< relax the repaired clustering once at the end (kept only if valid)
  /// Energy and loop settings of the relaxation (metric, QEM threshold, threads, ...); its
  /// on_loop and near_convergence are not used.
  ClusteringOptions clustering;
};

struct DefectRepairResult {
  uint32_t rounds = 0;                  ///< repair rounds run
  uint64_t repaired_clusters = 0;       ///< Σ over rounds of the clusters each round changed
  uint64_t splits = 0, merges = 0, islands = 0;
  bool relaxed = false;                 ///< a relaxation of the repaired region was kept
  uint64_t defect_vertices = 0;         ///< dual vertices still on a defect at the end
  std::vector<uint8_t> touched;         ///< per cluster: 1 when the repair changed it
  double check_seconds = 0, repair_seconds = 0;
};

/// The repair loop: finds the clusters on and around dual-mesh defects (same defects as
/// find_manifold_defects on the built dual, strips included), repairs them (repair_clusters),
/// and re-checks only the dual around the vertices whose label changed, until no defect is left
/// or max_rounds. Then relaxes the repaired clusters (constrained pass), keeping the relaxation
/// only if the dual stays defect-free. Labels only: the dual's topology does not depend on
/// vertex positions. First check O(V + F); each further round O(V) plus the changed region.
/// Deterministic. Appends the relaxation loops to `report`.
DefectRepairResult repair_dual_defects(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                                       uint32_t cluster_count, std::span<const uint8_t> adjustable,
                                       const BoundaryLoops& loops, const DefectRepairOptions& options,
                                       ClusteringReport& report);

}  // namespace streamcvd
