// Lloyd relaxation on the mesh graph (the baseline of paper §VII, Fig. 9). The assignment step
// is a multi-source priority flood, as in the "distortion-minimizing flooding" of variational
// shape approximation: a vertex is only offered to the clusters of its already-assigned
// neighbours, so every cluster stays one connected piece and keeps its seed (never empty).
#include "streamcvd/core/clustering/lloyd.h"
#include "streamcvd/core/mesh/timer.h"

#include <algorithm>
#include <chrono>
#include <limits>
#include <stdexcept>
#include <vector>

namespace streamcvd {

namespace {

struct Push {
  double cost;
  uint32_t vertex;
  int32_t cluster;
};

// Heap order: smallest cost on top; ties by vertex then cluster so the flood is deterministic.
struct LaterPush {
  bool operator()(const Push& a, const Push& b) const {
    if (a.cost != b.cost) return a.cost > b.cost;
    if (a.vertex != b.vertex) return a.vertex > b.vertex;
    return a.cluster > b.cluster;
  }
};

// Sites relative to ItemData::origin, 3 per cluster (the frame of the item centroids).
std::vector<double> relative_sites(const ItemData& items, const ClusterState& state) {
  std::vector<double> z = cluster_sites(items, state);
  for (size_t i = 0; i < z.size(); ++i) z[i] -= items.origin[i % 3];
  return z;
}

// One assignment step: seeds = each cluster's vertex nearest its site, then the flood. Vertices
// with label −1 stay free; a labelled vertex no seed reaches (a cluster spread over several
// components, which valid inputs do not have) keeps its old label and is left to the cleaning.
void assign(const MeshView& mesh, const ItemData& items, std::span<const int32_t> labels, std::span<const double> z,
            uint32_t K, std::vector<int32_t>& next, std::vector<double>& offered, std::vector<Push>& heap) {
  const uint32_t V = mesh.vertex_count();
  auto cost = [&](uint32_t v, int32_t c) { return energy_detail::dist2(&items.centroid[3 * size_t(v)], &z[3 * size_t(c)]); };
  std::vector<uint32_t> seed(K, UINT32_MAX);
  std::vector<double> seed_cost(K, std::numeric_limits<double>::infinity());
  for (uint32_t v = 0; v < V; ++v) {
    const int32_t c = labels[v];
    if (c < 0) continue;
    const double d = cost(v, c);
    if (d < seed_cost[c]) {  // strict: the smallest index wins ties
      seed_cost[c] = d;
      seed[c] = v;
    }
  }
  next.assign(V, -1);
  // offered[v]: the lowest cost pushed for v so far; a push that cannot win is not made (it would
  // be popped after the winner and skipped), which keeps the heap a few times smaller.
  offered.assign(V, std::numeric_limits<double>::infinity());
  heap.clear();
  auto offer_neighbours = [&](uint32_t v, int32_t c) {
    for (uint32_t n : mesh.neighbours(v)) {
      if (next[n] >= 0 || labels[n] < 0) continue;
      const double d = cost(n, c);
      if (!(d < offered[n])) continue;
      offered[n] = d;
      heap.push_back({d, n, c});
      std::push_heap(heap.begin(), heap.end(), LaterPush{});
    }
  };
  // Seeds are claimed before the flood starts: a seed is never taken by another cluster.
  for (uint32_t c = 0; c < K; ++c)
    if (seed[c] != UINT32_MAX) next[seed[c]] = int32_t(c);
  for (uint32_t c = 0; c < K; ++c)
    if (seed[c] != UINT32_MAX) offer_neighbours(seed[c], int32_t(c));
  while (!heap.empty()) {
    std::pop_heap(heap.begin(), heap.end(), LaterPush{});
    const Push p = heap.back();
    heap.pop_back();
    if (next[p.vertex] >= 0) continue;
    next[p.vertex] = p.cluster;
    offer_neighbours(p.vertex, p.cluster);
  }
  for (uint32_t v = 0; v < V; ++v)
    if (next[v] < 0) next[v] = labels[v];
}

}  // namespace

ClusteringReport lloyd_clustering(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                                  uint32_t cluster_count, const ClusteringOptions& options) {
  if (is_anisotropic(options.metric))
    throw std::invalid_argument("lloyd_clustering: only the metrics I and IQ are implemented");
  const auto t0 = std::chrono::steady_clock::now();
  ClusteringReport report;
  const LloydOptions& lloyd = options.lloyd;
  ClusterState state = solved_cluster_state(items, labels, cluster_count, options);
  report.metric = state.metric;
  double best_energy = state_energy(items, state);
  std::vector<int32_t> best, next;
  std::vector<double> offered;
  if (lloyd.keep_best) best.assign(labels.begin(), labels.end());
  std::vector<Push> heap;
  bool last_is_best = true;
  for (uint32_t iteration = 1; iteration <= lloyd.max_iterations; ++iteration) {
    const std::vector<double> z = relative_sites(items, state);
    assign(mesh, items, labels, z, cluster_count, next, offered, heap);
    uint64_t moves = 0;
    for (size_t v = 0; v < labels.size(); ++v) {
      moves += next[v] != labels[v];
      labels[v] = next[v];
    }
    state = solved_cluster_state(items, labels, cluster_count, options);
    const double energy = state_energy(items, state);
    report.moves_per_loop.push_back(moves);
    report.energy_per_loop.push_back(energy);
    const double elapsed = seconds_since(t0);
    report.seconds_per_loop.push_back(elapsed);
    report.unconstrained_loops = iteration;
    last_is_best = !lloyd.keep_best || energy <= best_energy;
    if (lloyd.keep_best && energy < best_energy) {
      best_energy = energy;
      best.assign(labels.begin(), labels.end());
    }
    if (options.loops.on_loop) options.loops.on_loop(false, iteration, moves);
    if (moves == 0) break;
    if (lloyd.time_limit_seconds > 0 && elapsed >= lloyd.time_limit_seconds) break;
  }
  if (!last_is_best) std::copy(best.begin(), best.end(), labels.begin());
  // The flood keeps clusters connected; the cleaning only acts on inputs with a cluster spread
  // over several components (then it restores the dual mesh's precondition).
  if (!clusters_connected(mesh, labels, cluster_count)) clean_clusters(mesh, items, labels, cluster_count, report);
  report.final_energy = state_energy(items, solved_cluster_state(items, labels, cluster_count, options));
  return report;
}

}  // namespace streamcvd
