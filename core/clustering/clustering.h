// Discrete centroidal Voronoi clustering of mesh vertices (paper §V-A, §VI-A, §VI-B, §VI-G).
// Labels live in one flat array `cluster_of_vertex` (−1 = free); per-cluster accumulators
// (ΣM, ΣMγ) make each boundary-edge test O(1) (eq. 15: only L_a + L_b change).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/chunked_components.h"
#include "streamcvd/core/clustering/cluster_energy.h"
#include "streamcvd/core/clustering/item_data.h"
#include "streamcvd/core/mesh/large_array.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

enum class SmallComponents { Keep, Drop };

/// How many clusters each connected component of the mesh gets.
struct ComponentBudget {
  /// Component of each vertex (V entries, from the storage given to plan_component_budget),
  /// numbered by smallest vertex; UINT32_MAX (kNoComponent) for isolated vertices.
  LargeArray<uint32_t> component_of_vertex;
  std::vector<uint32_t> clusters_per_component;
  std::vector<uint32_t> vertices_per_component;
  std::vector<uint8_t> component_closed;     ///< 1 when the component has no boundary vertex
  uint32_t total_clusters = 0;               ///< Σ clusters_per_component (may differ from N)
  uint32_t small_components_kept = 0;        ///< components given the minimum to stay a surface
  uint32_t components_dropped = 0;           ///< components given no cluster (Drop mode)
  std::string note;                          ///< why total_clusters ≠ N, when it is
};

/// Splits N clusters over the vertex-connected components in proportion to their weight
/// (largest remainder). A component too small for its share gets min(4 closed / 3 open, its
/// vertex count) clusters, or one per vertex when it has at most 16 (Keep), or none (Drop);
/// kept small components take at most a fifth of N (the lightest are dropped beyond it, with a
/// note). No component gets more clusters than vertices.
/// Components come from the chunk-wise union-find (core/mesh/chunked_components.h) over the ranges
/// of sampling_ranges(mesh): memory is one range per thread plus the frontier records, and
/// component_of_vertex is allocated from `storage` and written range by range.
/// O(V + E), TBB-parallel over ranges; the result does not depend on the thread count or the
/// storage.
ComponentBudget plan_component_budget(const MeshView& mesh, const ItemData& items, uint32_t clusters,
                                      SmallComponents small_components, ArrayStorage& storage);

/// Initial sampling (§VI-G), range by range (the store's chunks, see sampling_ranges). Each
/// component's clusters are shared over the ranges it touches in proportion to its weight there
/// (largest remainder, at most one cluster per vertex: the totals are exact; a part too light
/// for a cluster may get none). In each range, seeds are drawn in a weighted random order (the
/// exponential race, RNG seeded by (seed, range index)) and regions grown from them over free
/// vertices of the range until each holds D = component weight / its cluster count (eq. 19);
/// when a part runs out of free vertices, single vertices are taken from its clusters (never
/// one that would cut its cluster). Free vertices are then absorbed (absorb_free_vertices).
/// Returns labels (V entries from `storage`) in [0, budget.total_clusters), −1 only for isolated
/// vertices and vertices of components without clusters; every cluster is non-empty and
/// connected. Labels are numbered by range, then by seed order inside the range.
/// Memory: the labels, plus one range's scratch per thread (~32 bytes per vertex of the largest
/// range, at most 2^20 vertices) and K-sized tables. O(V + E), TBB-parallel over ranges; the labels depend only on the
/// mesh, the items, the budget and the seed (not on the thread count or the storage).
/// Throws std::invalid_argument when the budget was made for another mesh.
LargeArray<int32_t> initial_sampling(const MeshView& mesh, const ItemData& items, const ComponentBudget& budget,
                                     uint64_t seed, ArrayStorage& storage);

/// The vertex ranges the budget, the sampling and the absorption of free vertices work on: the
/// store's chunks, cut by chunk_ranges into at least min(16, V / 65536) ranges (a store of one
/// chunk still runs on every thread, a small mesh stays one range), or all vertices as one range
/// for a view without a chunk table. Depends only on the chunk table and V.
std::vector<VertexRange> sampling_ranges(const MeshView& mesh);

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
/// testing; the others are known stable. Appends to `report`; returns loops run. Single-threaded
/// when options.threads == 1 and not deterministic; otherwise runs the parallel loop.
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

/// Gives every free (−1) non-isolated vertex reachable from a labelled one the label of a
/// neighbouring region, so that connected regions stay connected. Range by range
/// (sampling_ranges): first a multi-source BFS inside each range from its labelled vertices,
/// then rounds across range frontiers (a free vertex next to a labelled one of another range
/// takes the label of its lowest-id such neighbour, and the BFS goes on inside its range) until
/// nothing changes. Memory: one range's queue per thread plus lists of frontier vertices.
/// O(V + E) plus O(frontier) per round; TBB-parallel over ranges; the result does not depend on
/// the thread count.
void absorb_free_vertices(const MeshView& mesh, std::span<int32_t> labels);

/// True when every cluster's vertices form one connected piece of the mesh graph. Chunk-wise
/// union-find: memory of one chunk per thread plus the frontiers.
bool clusters_connected(const MeshView& mesh, std::span<const int32_t> labels, uint32_t cluster_count);

}  // namespace streamcvd
