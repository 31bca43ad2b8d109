// Algorithm 1 of the paper (boundary-edge FIFO minimisation), the cleaning step and the
// connectivity-constrained pass (§VI-A, §VI-B). The loops themselves are in
// parallel_clustering.cpp (one code path for any thread count).
#include "streamcvd/core/clustering/clustering.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>

#include "streamcvd/core/clustering/parallel_clustering.h"

namespace streamcvd {

std::vector<ClusterSums> accumulate_clusters(const ItemData& items, std::span<const int32_t> labels,
                                             uint32_t cluster_count) {
  return make_cluster_state(items, labels, cluster_count, Metric::I).iso;
}

double clustering_energy(const ItemData& items, std::span<const ClusterSums> sums) {
  ClusterState s;
  s.iso.assign(sums.begin(), sums.end());
  return state_energy(items, s);
}

LoopOptions loop_options(const ClusteringOptions& options) {
  LoopOptions loop;
  loop.stop_fraction = options.near_convergence;
  loop.max_loops = options.max_loops;
  loop.skip_unchanged = options.skip_unchanged;
  loop.offset_update_loops = options.offset_update_loops;
  loop.on_loop = options.on_loop;
  loop.threads = options.threads;
  loop.deterministic = options.deterministic;
  loop.region_vertices = options.region_vertices;
  loop.storage = options.storage;
  return loop;
}

ClusteringReport minimize_clustering(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                                     uint32_t cluster_count, const ClusteringOptions& options) {
  ClusteringReport report;
  LoopOptions loop = loop_options(options);
  // First convergence with centroid sites (I or A); the Q metrics then embed the QEM sites
  // (§V-C) and converge again before the cleaning.
  const Metric base = is_anisotropic(options.metric) ? Metric::A : Metric::I;
  // The parallel path also spreads the site solves and the cleaning over the threads (same
  // results as the serial calls).
  const bool parallel = options.threads != 1 || options.deterministic;
  auto solve_sites = [&](ClusterState& s) {
    if (parallel) parallel_update_site_offsets(s, options.threads);
    else update_site_offsets(s);
  };
  ClusterState state = make_cluster_state(items, labels, cluster_count, base);
  report.unconstrained_loops = run_clustering_loops(mesh, items, labels, state, loop, report);
  if (uses_quadrics(options.metric)) {
    state = make_cluster_state(items, labels, cluster_count, options.metric, options.qem_threshold);
    solve_sites(state);
    report.unconstrained_loops += run_clustering_loops(mesh, items, labels, state, loop, report);
  }
  clean_clusters(mesh, items, labels, cluster_count, report, options.storage ? *options.storage : ram_storage());
  // Incremental sums drift: rebuild them before the constrained pass (DESIGN.md §3).
  state = make_cluster_state(items, labels, cluster_count, options.metric, options.qem_threshold);
  solve_sites(state);
  loop.constrained = true;
  loop.stop_fraction = 0.0;
  report.constrained_loops = run_clustering_loops(mesh, items, labels, state, loop, report);
  report.metric = state.metric;
  report.final_energy = state_energy(items, state);
  return report;
}

}  // namespace streamcvd
