// Topological repair of a clustering whose dual mesh has defects (non-manifold edges or
// vertices, isolated vertices, duplicate faces). Defects come from features thinner than a
// cluster: a cluster enclosed by one other (an island), wrapping a tube or a hole (fewer than
// three neighbours), meeting a neighbour along two separate frontiers, or ringing a group of
// clusters at a thin neck (a frontier that meets no third cluster: no dual edge, so the output
// would come apart there although the dual stays manifold). The repair splits such clusters in
// two and dissolves islands into their surrounding cluster, and keeps the cluster count N exact
// by merging the lightest adjacent pairs far from any defect (or splitting the heaviest
// clusters). Constrained clustering then relaxes the touched region. Its parts: the defect
// check (core/dual/defect_tracker.h), the edits (core/dual/cluster_repair.h), the shared label
// state (core/dual/repair_state.h); core/dual/repair.cpp runs the loop.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "streamcvd/core/clustering/clustering.h"
#include "streamcvd/core/dual/dual_mesh.h"
#include "streamcvd/core/clustering/item_data.h"
#include "streamcvd/core/mesh/large_array.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

struct DefectRepairOptions {
  uint32_t max_rounds = 40;     ///< repair rounds at most (RemeshOptions::repair_rounds)
  DualMeshOptions dual;         ///< the dual as it will be built (strips, closed holes)
  bool relax = true;            ///< relax the repaired clustering once at the end (kept only if valid)
  /// Output vertices wanted (non-empty clusters + strip vertices of the dual); 0 = keep the
  /// number of non-empty clusters. Reached by merging or splitting clusters off the boundary
  /// (so the strips stay), in the same rounds as the defect repair.
  uint32_t target_vertices = 0;
  /// Energy and loop settings of the relaxation (metric, QEM threshold, threads, ...); its
  /// on_loop and near_convergence are not used.
  ClusteringOptions clustering;
};

struct DefectRepairResult {
  uint32_t rounds = 0;                  ///< repair rounds run
  uint32_t count_rounds = 0;            ///< of them, rounds that only merged or split for the vertex target
  uint64_t repaired_clusters = 0;       ///< Σ over rounds of the clusters each round changed
  uint64_t splits = 0, merges = 0, islands = 0;
  /// Clusters on a defect found by the first check, then after each round (rounds + 1 entries
  /// once the loop ran; the last is 0 when the repair converged): how fast it converges.
  std::vector<uint32_t> defects_per_round;
  bool relaxed = false;                 ///< a relaxation of the repaired region was kept
  uint64_t defect_vertices = 0;         ///< dual vertices still on a defect at the end
  /// Input-adjacent cluster pairs still without a dual edge at the end (the output would come
  /// apart along their frontier; see dual::unjoined_pairs).
  uint64_t unjoined_pairs = 0;
  std::vector<uint8_t> touched;         ///< per cluster: 1 when the repair changed it
  /// The dual faces of the final labels (strips not included), kept up to date by the checks:
  /// build_dual_mesh takes them instead of reading the mesh again. D-sized (about 2K faces).
  dual::Triples dual_faces;
  double check_seconds = 0, repair_seconds = 0;
};

/// The repair loop: finds the clusters on dual-mesh defects (same defects as
/// find_manifold_defects on the built dual, strips included, plus input-adjacent cluster pairs
/// with no dual edge, dual::unjoined_pairs), repairs them (splits in two, islands dissolved,
/// the cluster count kept by merging light pairs far from any defect or splitting heavy
/// clusters), and re-checks only the dual around the vertices whose label
/// changed, until no defect is left or max_rounds. Then relaxes the repaired clusters
/// (constrained pass), keeping the relaxation only if the dual stays defect-free. Labels only:
/// the dual's topology does not depend on vertex positions.
///
/// Memory: a cluster → vertices index (4 bytes per vertex) and, for the relaxation, a copy of
/// the labels (4 bytes per vertex), both from `storage`; the rest is sized by K, the boundary
/// and the touched region. Time: the first check and the index O(V + F), chunk-parallel; each
/// round O(vertices and faces of the clusters it touches) plus O(K) byte scans and O(boundary);
/// the relaxation runs the clustering loops once (O(V)). Deterministic: the same labels for any
/// thread count and any storage. Appends the relaxation loops to `report`.
DefectRepairResult repair_dual_defects(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                                       uint32_t cluster_count, std::span<const uint8_t> adjustable,
                                       const BoundaryLoops& loops, const DefectRepairOptions& options,
                                       ClusteringReport& report, ArrayStorage& storage);

}  // namespace streamcvd
