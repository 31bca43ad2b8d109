// Algorithm 1 of the paper (boundary-edge FIFO minimisation), the cleaning step and the
// connectivity-constrained pass (§VI-A, §VI-B).
#include "core/clustering.h"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>

#include "core/connectivity_check.h"
#include "core/parallel_clustering.h"

namespace streamcvd {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

bool removal_keeps_connected(const MeshView& mesh, std::span<const int32_t> labels, uint32_t v, int32_t a) {
  return detail::removal_keeps_connected(mesh, [&](uint32_t u) { return labels[u]; }, v, a);
}

}  // namespace

std::vector<ClusterSums> accumulate_clusters(const ItemData& items, std::span<const int32_t> labels,
                                             uint32_t cluster_count) {
  return make_cluster_state(items, labels, cluster_count, Metric::I).iso;
}

double clustering_energy(const ItemData& items, std::span<const ClusterSums> sums) {
  ClusterState s;
  s.iso.assign(sums.begin(), sums.end());
  return state_energy(items, s);
}

namespace {

template <bool kAniso, bool kOffsets>
uint32_t clustering_loops(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels, ClusterState& state,
                          const LoopOptions& options, ClusteringReport& report,
                          std::span<const uint8_t> initially_active) {
  const bool constrained = options.constrained;
  auto delta = [&](uint32_t item, int32_t from, int32_t to) {
    if constexpr (kAniso) return aniso_move_delta<kOffsets>(items, state, item, from, to);
    else return iso_move_delta<kOffsets>(items, state, item, from, to);
  };
  const uint32_t V = mesh.vertex_count();
  const auto t0 = std::chrono::steady_clock::now();
  // changed_in[c]: last loop in which cluster c changed. Loops are numbered from 2, so 1 marks
  // the initially active clusters and 0 the ones known to be stable.
  const uint32_t K = state.cluster_count();
  std::vector<uint32_t> changed_in(K, 1);
  if (!initially_active.empty())
    for (size_t c = 0; c < K; ++c) changed_in[c] = initially_active[c] ? 1 : 0;
  std::vector<uint8_t> changed_now;
  // The candidate list holds every vertex on a cluster boundary (the FIFO of Algorithm 1, kept
  // by vertex: a vertex stands for its boundary edges). Vertices of clusters that did not change
  // in the previous loop stay parked in it: the modified-clusters skip of §VI-A, without even
  // visiting their edges. An edge is still tested when either of its clusters changed, from the
  // side of the changed cluster.
  std::vector<uint32_t> candidates;
  std::vector<uint8_t> listed(V, 0);
  for (uint32_t v = 0; v < V; ++v) {
    int32_t a = labels[v];
    if (a < 0) continue;
    for (uint32_t n : mesh.neighbours(v))
      if (labels[n] >= 0 && labels[n] != a) {
        candidates.push_back(v);
        listed[v] = 1;
        break;
      }
  }
  auto list_vertex = [&](uint32_t u) {
    if (!listed[u]) {
      listed[u] = 1;
      candidates.push_back(u);
    }
  };
  uint32_t loops = 0;
  for (uint32_t loop = 2; loops < options.max_loops; ++loop) {
    ++loops;
    uint64_t moves = 0;
    size_t kept = 0;
    for (size_t i = 0; i < candidates.size(); ++i) {
      const uint32_t v = candidates[i];
      if (labels[v] < 0) {
        listed[v] = 0;
        continue;
      }
      if (options.skip_unchanged && changed_in[labels[v]] + 1 < loop) {
        candidates[kept++] = v;  // parked: its cluster did not change since its last test
        continue;
      }
      bool boundary = false;
      for (size_t slot = mesh.vertex_vertex_offsets[v]; slot < mesh.vertex_vertex_offsets[v + 1]; ++slot) {
        const uint32_t k = mesh.vertex_vertex[slot];
        const int32_t a = labels[v], b = labels[k];
        if (b < 0 || a == b) continue;
        boundary = true;
        // F1: k joins a (b shrinks). F2: v joins b (a shrinks). Compare L_a + L_b only (eq. 15).
        double gain1 = 0, gain2 = 0;
        if (state.iso[b].count > 1) gain1 = move_gain(delta(k, b, a));
        if (state.iso[a].count > 1) gain2 = move_gain(delta(v, a, b));
        if (constrained) {
          if (gain1 > 0 && !removal_keeps_connected(mesh, labels, k, b)) gain1 = 0;
          if (gain2 > 0 && !removal_keeps_connected(mesh, labels, v, a)) gain2 = 0;
        }
        if (gain1 <= 0 && gain2 <= 0) continue;
        const uint32_t moved = gain1 >= gain2 ? k : v;
        if (moved == k) {
          apply_move(items, state, k, b, a);
          labels[k] = a;
        } else {
          apply_move(items, state, v, a, b);
          labels[v] = b;
        }
        changed_in[a] = changed_in[b] = loop;
        ++moves;
        list_vertex(moved);
        for (uint32_t n : mesh.neighbours(moved)) list_vertex(n);
      }
      if (boundary) candidates[kept++] = v;
      else listed[v] = 0;
    }
    candidates.resize(kept);
    report.moves_per_loop.push_back(moves);
    report.energy_per_loop.push_back(state_energy(items, state));
    if (kOffsets && moves > 0 && loops < options.offset_update_loops) {
      // New QEM sites for the clusters that changed (the energy is monotone at fixed sites only;
      // freezing them after offset_update_loops makes the pass terminate).
      changed_now.assign(K, 0);
      for (uint32_t c = 0; c < K; ++c) changed_now[c] = changed_in[c] == loop;
      update_site_offsets(state, changed_now);
    }
    report.seconds_per_loop.push_back(seconds_since(t0));
    if (options.on_loop) options.on_loop(constrained, loops, moves);
    if (moves == 0 || double(moves) < options.stop_fraction * double(V)) break;
  }
  return loops;
}

}  // namespace

uint32_t run_clustering_loops(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels, ClusterState& state,
                              const LoopOptions& options, ClusteringReport& report,
                              std::span<const uint8_t> initially_active) {
  if (options.threads != 1 || options.deterministic)
    return run_parallel_clustering_loops(mesh, items, labels, state, options, report, initially_active);
  const bool aniso = !state.aniso.empty(), offsets = state.use_offsets;
  if (aniso) {
    return offsets ? clustering_loops<true, true>(mesh, items, labels, state, options, report, initially_active)
                   : clustering_loops<true, false>(mesh, items, labels, state, options, report, initially_active);
  }
  return offsets ? clustering_loops<false, true>(mesh, items, labels, state, options, report, initially_active)
                 : clustering_loops<false, false>(mesh, items, labels, state, options, report, initially_active);
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
  // results as the serial calls; the serial path is left exactly as it was).
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
