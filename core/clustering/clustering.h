// Discrete centroidal Voronoi clustering of mesh vertices (paper §V-A, §VI-A, §VI-B); its start,
// the component budget and the initial sampling (§VI-G), is core/clustering/sampling.h.
// Labels live in one flat array `cluster_of_vertex` (−1 = free); per-cluster accumulators
// (ΣM, ΣMγ) make each boundary-edge test O(1) (eq. 15: only L_a + L_b change).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <vector>

#include "streamcvd/core/clustering/cluster_energy.h"
#include "streamcvd/core/clustering/item_data.h"
#include "streamcvd/core/clustering/sampling.h"
#include "streamcvd/core/mesh/large_array.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

struct ClusteringOptions {
  enum class Algorithm : uint8_t { Cvd, Lloyd };
  Algorithm algorithm = Algorithm::Cvd;  ///< Cvd: Algorithm 1; Lloyd: the §VII baseline (core/clustering/lloyd.h, I/IQ only)
  uint32_t lloyd_max_iterations = 100;   ///< Lloyd: iteration bound (it need not converge)
  double lloyd_time_limit = 0;           ///< Lloyd: seconds, 0 = no limit
  Metric metric = Metric::I;       ///< energy (items must carry tensors for A/AQ, quadrics for IQ/AQ)
  double near_convergence = 1e-3;  ///< stop the unconstrained pass when < this fraction of items moved
  uint32_t max_loops = 2000;       ///< safety bound on loops per pass
  bool skip_unchanged = true;      ///< the modified-clusters skip of §VI-A
  uint32_t offset_update_loops = 5;  ///< Q metrics: loops per pass after which the QEM sites freeze
  double qem_threshold = 1e-2;      ///< Q metrics: relative eigenvalue truncation (ClusterState)
  /// Clustering threads: 1 = the serial loop (reference output), 0 = all cores, T > 1 = the
  /// parallel loop of core/clustering/parallel_clustering.h (output may differ between runs).
  uint32_t threads = 1;
  bool deterministic = false;   ///< parallel loop whose output is the same for every thread count
  uint32_t region_vertices = 0; ///< parallel loop: target vertices per region (0 = automatic)
  /// Called after every loop with (constrained pass?, loop number, items moved); for progress.
  std::function<void(bool, uint32_t, uint64_t)> on_loop;
  /// Where the loops' arrays sized by V live (null = RAM; the out-of-core pipeline's WorkSpace).
  ArrayStorage* storage = nullptr;
};

struct ClusteringReport {
  std::vector<uint64_t> moves_per_loop;
  std::vector<double> energy_per_loop;  ///< E_iso − Σ A_j (eq. 12) after each loop
  std::vector<double> seconds_per_loop; ///< wall time at the end of each loop, from the pass start
  uint32_t unconstrained_loops = 0, constrained_loops = 0;
  uint64_t cleaned_vertices = 0;        ///< vertices reset by the cleaning step
  uint32_t disconnected_clusters = 0;   ///< clusters found in several pieces by the cleaning step
  Metric metric = Metric::I;            ///< metric actually used (A/AQ fall back to I/IQ without tensors)
  double final_energy = 0;              ///< energy of the final clustering under that metric
};

/// One pass of Algorithm 1 (see run_clustering_loops).
struct LoopOptions {
  bool constrained = false;       ///< every move keeps the source cluster connected (§VI-B)
  double stop_fraction = 0.0;     ///< stop when fewer than this fraction of V items moved in a loop
  uint32_t max_loops = 2000;
  bool skip_unchanged = true;
  uint32_t offset_update_loops = 5;  ///< Q metrics: re-solve the sites of changed clusters until then
  /// Clustering threads: 1 = the serial loop (reference output), 0 = all cores, T > 1 = the
  /// parallel loop of core/clustering/parallel_clustering.h (output may differ between runs).
  uint32_t threads = 1;
  bool deterministic = false;   ///< parallel loop whose output is the same for every thread count
  uint32_t region_vertices = 0; ///< parallel loop: target vertices per region (0 = automatic)
  std::function<void(bool, uint32_t, uint64_t)> on_loop;
  ArrayStorage* storage = nullptr;  ///< arrays sized by V (null = RAM)
};

/// Recomputes every cluster's isotropic sums from the labels (fixed order: deterministic).
std::vector<ClusterSums> accumulate_clusters(const ItemData& items, std::span<const int32_t> labels,
                                             uint32_t cluster_count);

/// E_iso − Σ A_j = Σ_j M_j ‖γ_j − c_i‖² with c_i the cluster centroids (eq. 12 with z_i = c_i).
double clustering_energy(const ItemData& items, std::span<const ClusterSums> sums);

/// Full minimisation (Algorithm 1 + §VI-B): unconstrained loops to near-convergence (with
/// centroid sites; the Q metrics then embed their QEM sites and converge again), cleaning
/// (each cluster keeps its heaviest connected piece; the rest is freed and re-absorbed), then
/// loops with the 1-ring connectivity check until no item moves. Never empties a cluster.
/// Labels must be a valid initial clustering (every cluster non-empty). Single-threaded unless
/// options.threads ≠ 1 or options.deterministic (then the loops run in parallel).
ClusteringReport minimize_clustering(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                                     uint32_t cluster_count, const ClusteringOptions& options = {});

/// The loop settings of a pass of `options` (unconstrained, stopping at near_convergence).
LoopOptions loop_options(const ClusteringOptions& options);

/// Loops of Algorithm 1 under the state's metric until no item moves, fewer than
/// `stop_fraction`·V items moved, or `max_loops` (constrained: every move keeps the source
/// cluster connected, checked on the vertex's 1-ring). Each committed move strictly lowers the
/// energy at the current sites; Q-metric sites of changed clusters are re-solved between loops.
/// `initially_active` (size K, or empty = all) marks the clusters whose boundaries need
/// testing; the others are known stable. Appends to `report`; returns loops run. On
/// options.threads threads (one code path: a single thread visits the regions in turn);
/// defined in parallel_clustering.cpp.
uint32_t run_clustering_loops(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                              ClusterState& state, const LoopOptions& options, ClusteringReport& report,
                              std::span<const uint8_t> initially_active = {});

/// Cleaning step (§VI-B, Fig. 6): frees every piece of a cluster but its heaviest connected
/// one (the first in vertex order on a tie), then gives each freed vertex to a neighbouring
/// region (absorb_free_vertices). Pieces by the chunk-wise union-find, in parallel over chunks;
/// one component id per vertex from `storage`. Returns the number of vertices reset; counts
/// disconnected clusters into `report`. Deterministic.
uint64_t clean_clusters(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                        uint32_t cluster_count, ClusteringReport& report, ArrayStorage& storage = ram_storage());

/// True when every cluster's vertices form one connected piece of the mesh graph. Chunk-wise
/// union-find: memory of one chunk per thread plus the frontiers.
bool clusters_connected(const MeshView& mesh, std::span<const int32_t> labels, uint32_t cluster_count);

}  // namespace streamcvd
