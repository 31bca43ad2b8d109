// Lloyd relaxation on the mesh graph: the baseline that paper §VII (Fig. 9) compares Algorithm 1
// against, for the metrics I and IQ. Each iteration recomputes every site z_i from its cluster
// (centroid, or QEM point for IQ), then re-assigns every item by region growing from one seed
// vertex per cluster, so clusters stay connected. Same items, same initial sampling and the same
// energy definition (state_energy) as minimize_clustering: the two energy curves are comparable.
#pragma once

#include <cstdint>
#include <span>

#include "streamcvd/core/clustering/cluster_energy.h"
#include "streamcvd/core/clustering/clustering.h"
#include "streamcvd/core/clustering/item_data.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

/// Discrete Lloyd relaxation from the clustering in `labels` (every cluster non-empty; −1 items
/// stay free). Iteration: sites from the clusters; seed of cluster i = its vertex nearest z_i;
/// priority flood from all seeds at once, an item joining the cluster whose push reaches it with
/// the smallest ‖γ_j − z_i‖² (clusters connected and non-empty by construction); stops when no
/// item changes, at lloyd.max_iterations or at the time limit. The report holds per iteration the
/// items moved, the energy of the new clustering (state_energy, sites recomputed: the quantity
/// minimize_clustering reports) and the seconds since the start; unconstrained_loops = the
/// iterations run. Reads options.metric (I or IQ; A/AQ throw std::invalid_argument before any
/// change), qem_threshold, lloyd (LloydOptions) and loops.threads (site solves), loops.on_loop
/// (after each iteration). O(iterations · E log E); the flood is single-threaded; deterministic.
ClusteringReport lloyd_clustering(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                                  uint32_t cluster_count, const ClusteringOptions& options);

}  // namespace streamcvd
