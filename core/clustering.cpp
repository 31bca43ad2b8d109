// Algorithm 1 of the paper (boundary-edge FIFO minimisation), the cleaning step and the
// connectivity-constrained pass (§VI-A, §VI-B).
#include "core/clustering.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>

#include "core/parallel_clustering.h"

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

uint32_t run_clustering_loops(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels, ClusterState& state,
                              const LoopOptions& options, ClusteringReport& report,
                              std::span<const uint8_t> initially_active) {
  // One code path: a single thread runs the same region visits, one region after the other.
  return run_parallel_clustering_loops(mesh, items, labels, state, options, report, initially_active);
}

uint64_t clean_clusters(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                        uint32_t cluster_count, ClusteringReport& report) {
  const uint32_t V = mesh.vertex_count();
  // Label each cluster's connected pieces; keep the heaviest piece of each cluster.
  std::vector<uint32_t> piece(V, UINT32_MAX);
  std::vector<double> piece_weight;
  std::vector<int32_t> piece_cluster;
  std::vector<uint32_t> queue;
  for (uint32_t s = 0; s < V; ++s) {
    if (labels[s] < 0 || piece[s] != UINT32_MAX) continue;
    uint32_t id = uint32_t(piece_weight.size());
    int32_t l = labels[s];
    double w = 0;
    piece[s] = id;
    queue.assign(1, s);
    for (size_t h = 0; h < queue.size(); ++h) {
      uint32_t u = queue[h];
      w += items.weight[u];
      for (uint32_t n : mesh.neighbours(u))
        if (labels[n] == l && piece[n] == UINT32_MAX) {
          piece[n] = id;
          queue.push_back(n);
        }
    }
    piece_weight.push_back(w);
    piece_cluster.push_back(l);
  }
  std::vector<uint32_t> best(cluster_count, UINT32_MAX), pieces(cluster_count, 0);
  for (uint32_t p = 0; p < piece_weight.size(); ++p) {
    int32_t l = piece_cluster[p];
    ++pieces[l];
    if (best[l] == UINT32_MAX || piece_weight[p] > piece_weight[best[l]]) best[l] = p;
  }
  for (uint32_t c = 0; c < cluster_count; ++c) report.disconnected_clusters += pieces[c] > 1;
  uint64_t reset = 0;
  for (uint32_t v = 0; v < V; ++v)
    if (labels[v] >= 0 && best[labels[v]] != piece[v]) {
      labels[v] = -1;
      ++reset;
    }
  if (reset) absorb_free_vertices(mesh, labels);
  report.cleaned_vertices += reset;
  return reset;
}

bool clusters_connected(const MeshView& mesh, std::span<const int32_t> labels, uint32_t cluster_count) {
  const uint32_t V = mesh.vertex_count();
  std::vector<uint8_t> seen(V, 0), cluster_seen(cluster_count, 0);
  std::vector<uint32_t> queue;
  for (uint32_t s = 0; s < V; ++s) {
    int32_t l = labels[s];
    if (l < 0 || seen[s]) continue;
    if (cluster_seen[l]) return false;  // a second piece of cluster l
    cluster_seen[l] = 1;
    seen[s] = 1;
    queue.assign(1, s);
    for (size_t h = 0; h < queue.size(); ++h)
      for (uint32_t n : mesh.neighbours(queue[h]))
        if (labels[n] == l && !seen[n]) {
          seen[n] = 1;
          queue.push_back(n);
        }
  }
  return true;
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
  if (parallel) parallel_clean_clusters(mesh, items, labels, cluster_count, report, options.threads);
  else clean_clusters(mesh, items, labels, cluster_count, report);
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
