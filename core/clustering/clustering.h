// Discrete centroidal Voronoi clustering of mesh vertices (paper §V-A, §VI-A, §VI-B); its start,
// the component budget and the initial sampling (§VI-G), is core/clustering/sampling.h.
// Labels live in one flat array `cluster_of_vertex` (−1 = free); per-cluster accumulators
// (ΣM, ΣMγ) make each boundary-edge test O(1) (eq. 15: only L_a + L_b change).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string_view>
#include <vector>

#include "streamcvd/core/clustering/cluster_energy.h"
#include "streamcvd/core/clustering/item_data.h"
#include "streamcvd/core/clustering/sampling.h"
#include "streamcvd/core/mesh/large_array.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

/// How the boundary-edge loops of Algorithm 1 run. A job has one set, ClusteringOptions::loops;
/// each pass starts from a copy of it (minimize_clustering's passes, the repair's relaxation)
/// and changes only what is the pass's own: constrained, stop_fraction, max_loops, on_loop.
struct LoopOptions {
  bool constrained = false;       ///< every move keeps the source cluster connected (§VI-B)
  /// Stop when fewer than this fraction of V items moved in a loop (0: when none moves). In
  /// ClusteringOptions::loops, the near-convergence of the unconstrained passes; the
  /// constrained pass of minimize_clustering always runs until no item moves.
  double stop_fraction = 0.0;
  uint32_t max_loops = 2000;      ///< safety bound on loops per pass
  bool skip_unchanged = true;     ///< the modified-clusters skip of §VI-A
  uint32_t offset_update_loops = 5;  ///< Q metrics: loops per pass after which the QEM sites freeze
  /// Threads: 0 = all cores (TBB's limit), 1 = one thread (the reference output, the same on
  /// every run), T > 1 = T threads, whose output may differ between runs unless deterministic
  /// (core/clustering/parallel_clustering.h).
  uint32_t threads = 0;
  bool deterministic = false;   ///< parallel loop whose output is the same for every thread count
  uint32_t region_vertices = 0; ///< parallel loop: target vertices per region (0 = automatic)
  /// Called after every loop with (constrained pass?, loop number, items moved); for progress.
  /// Lloyd calls it after every iteration with (false, iteration, items moved).
  std::function<void(bool, uint32_t, uint64_t)> on_loop;
  /// Where the loops' arrays sized by V live (null = RAM; the out-of-core pipeline's WorkSpace).
  ArrayStorage* storage = nullptr;
};

/// The settings of the Lloyd baseline (core/clustering/lloyd.h) that are Lloyd's alone; the
/// metric, the QEM threshold, the threads and the progress are the clustering's.
struct LloydOptions {
  uint32_t max_iterations = 100;  ///< Lloyd need not converge (paper §VII): a hard bound
  double time_limit_seconds = 0;  ///< stop after the iteration that exceeds it; 0 = no limit
  /// Keep the lowest-energy clustering met instead of the last one: the flooding is not
  /// monotone, and near a cycle the last iterate can be slightly worse than an earlier one.
  bool keep_best = true;
};

/// A clustering job: which algorithm, under which energy, with which loops. The defaults are
/// the library's and the CLI's (tools/cmd_remesh.cpp and the Python binding read them here).
struct ClusteringOptions {
  enum class Algorithm : uint8_t { Cvd, Lloyd };
  Algorithm algorithm = Algorithm::Cvd;  ///< Cvd: Algorithm 1; Lloyd: the §VII baseline (core/clustering/lloyd.h, I/IQ only)
  /// Energy (§V): I, IQ, A or AQ. Items must carry tensors for A/AQ and quadrics for IQ/AQ
  /// (make_cluster_state throws std::invalid_argument otherwise).
  Metric metric = Metric::IQ;
  double qem_threshold = 1e-2;  ///< Q metrics: relative eigenvalue truncation (ClusterState)
  LoopOptions loops = {.stop_fraction = 1e-3};  ///< Algorithm 1's loops (and the threads of every stage)
  LloydOptions lloyd;                           ///< Algorithm::Lloyd only
};

/// "cvd" or "lloyd" (the CLI's, the Python binding's and the report's spelling). O(1).
const char* algorithm_name(ClusteringOptions::Algorithm algorithm);
/// Parses "cvd" or "lloyd" (case-insensitive); false (`out` unchanged) when the text is neither.
bool parse_algorithm(std::string_view text, ClusteringOptions::Algorithm& out);

struct ClusteringReport {
  std::vector<uint64_t> moves_per_loop;
  std::vector<double> energy_per_loop;  ///< E_iso − Σ A_j (eq. 12) after each loop
  std::vector<double> seconds_per_loop; ///< wall time at the end of each loop, from the pass start
  uint32_t unconstrained_loops = 0, constrained_loops = 0;
  uint64_t cleaned_vertices = 0;        ///< vertices reset by the cleaning step
  uint32_t disconnected_clusters = 0;   ///< clusters found in several pieces by the cleaning step
  Metric metric = Metric::I;            ///< the metric of the energies (the options')
  double final_energy = 0;              ///< energy of the final clustering under that metric
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
/// Labels must be a valid initial clustering (every cluster non-empty). Runs on
/// options.loops.threads threads (see LoopOptions::threads); options.algorithm and
/// options.lloyd are not read. O((V + E) / T) per loop; nothing else may touch the labels.
ClusteringReport minimize_clustering(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                                     uint32_t cluster_count, const ClusteringOptions& options);

/// The state of a clustering under options.metric with its sites solved: make_cluster_state,
/// then the QEM point of every cluster for the Q metrics (update_site_offsets; I and A have
/// no site to solve), spread over options.loops.threads threads (the same bits for any
/// count). The one way the clustering passes, Lloyd and remesh() get the sites of a
/// clustering. O(V + K) plus K 3×3 eigen-solves over the threads. Throws like
/// make_cluster_state.
ClusterState solved_cluster_state(const ItemData& items, std::span<const int32_t> labels, uint32_t cluster_count,
                                  const ClusteringOptions& options);

/// Loops of Algorithm 1 under the state's metric until no item moves, fewer than
/// `stop_fraction`·V items moved, or `max_loops` (constrained: every move keeps the source
/// cluster connected, checked on the vertex's 1-ring). Each committed move strictly lowers the
/// energy at the current sites; Q-metric sites of changed clusters are re-solved between loops.
/// `initially_active` (size K, or empty = all) marks the clusters whose boundaries need
/// testing; the others are known stable. `unsettled`, when given, is set to the clusters (size
/// K) the last loop changed, whose boundaries no loop has tested since (none when the pass
/// converged): the initially_active of a pass that goes on from here. Appends to `report`;
/// returns loops run. On options.threads threads (one code path: a single thread visits the
/// regions in turn); defined in parallel_clustering.cpp.
uint32_t run_clustering_loops(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                              ClusterState& state, const LoopOptions& options, ClusteringReport& report,
                              std::span<const uint8_t> initially_active = {},
                              std::vector<uint8_t>* unsettled = nullptr);

/// Cleaning step (§VI-B, Fig. 6): frees every piece of a cluster but its heaviest connected
/// one (the first in vertex order on a tie), then gives each freed vertex to a neighbouring
/// region (absorb_free_vertices). Pieces by the chunk-wise union-find, in parallel over chunks;
/// one component id per vertex from `storage`. Returns the number of vertices reset; counts
/// disconnected clusters into `report`; sets changed[c] (when given, size K) for each cluster
/// that lost or gained a vertex. Deterministic.
uint64_t clean_clusters(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                        uint32_t cluster_count, ClusteringReport& report, ArrayStorage& storage = ram_storage(),
                        std::vector<uint8_t>* changed = nullptr);

/// True when every cluster's vertices form one connected piece of the mesh graph. Chunk-wise
/// union-find: memory of one chunk per thread plus the frontiers.
bool clusters_connected(const MeshView& mesh, std::span<const int32_t> labels, uint32_t cluster_count);

}  // namespace streamcvd
