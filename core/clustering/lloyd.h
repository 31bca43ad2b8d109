// Lloyd relaxation on the mesh graph: the baseline that paper §VII (Fig. 9) compares Algorithm 1
// against, for the metrics I and IQ. Each iteration recomputes every site z_i from its cluster
// (centroid, or QEM point for IQ), then re-assigns every item by region growing from one seed
// vertex per cluster, so clusters stay connected. Same items, same initial sampling and the same
// energy definition (state_energy) as minimize_clustering: the two energy curves are comparable.
#pragma once

#include <cstdint>
#include <functional>
#include <span>

#include "streamcvd/core/clustering/cluster_energy.h"
#include "streamcvd/core/clustering/clustering.h"
#include "streamcvd/core/clustering/item_data.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

struct LloydOptions {
  Metric metric = Metric::I;         ///< I or IQ (A/AQ throw std::invalid_argument)
  uint32_t max_iterations = 100;     ///< Lloyd need not converge (paper §VII): a hard bound
  double time_limit_seconds = 0;     ///< stop after the iteration that exceeds it; 0 = no limit
  double qem_threshold = 1e-2;       ///< IQ: relative eigenvalue truncation (ClusterState)
  /// Keep the lowest-energy clustering met instead of the last one: the flooding is not
  /// monotone, and near a cycle the last iterate can be slightly worse than an earlier one.
  bool keep_best = true;
  /// Called after every iteration with (iteration number from 1, items that changed cluster).
  std::function<void(uint32_t, uint64_t)> on_iteration;
};

/// The Lloyd options matching a clustering configuration (metric, QEM threshold,
/// lloyd_max_iterations, lloyd_time_limit). O(1).
LloydOptions lloyd_options(const ClusteringOptions& options);

/// Discrete Lloyd relaxation from the clustering in `labels` (every cluster non-empty; −1 items
/// stay free). Iteration: sites from the clusters; seed of cluster i = its vertex nearest z_i;
/// priority flood from all seeds at once, an item joining the cluster whose push reaches it with
/// the smallest ‖γ_j − z_i‖² (clusters connected and non-empty by construction); stops when no
/// item changes, at max_iterations or at the time limit. The report holds per iteration the
/// items moved, the energy of the new clustering (state_energy, sites recomputed: the quantity
/// minimize_clustering reports) and the seconds since the start; unconstrained_loops = the
/// iterations run. O(iterations · E log E); single-threaded, deterministic.
ClusteringReport lloyd_clustering(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                                  uint32_t cluster_count, const LloydOptions& options = {});

}  // namespace streamcvd
