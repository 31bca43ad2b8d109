// Parallel steps of minimize_clustering around the loops (core/parallel_clustering.h): the
// cleaning step by a lock-free union-find, the QEM site solves, the thread count.
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>

#include "core/parallel_blocks.h"
#include "core/parallel_clustering.h"

namespace streamcvd {

namespace {

using detail::for_each_block;
using detail::tls_threads;

// The pieces of every cluster by a lock-free union-find over the edges joining two vertices of
// one cluster (the larger root is linked under the smaller, so each piece's final root is its
// smallest vertex whatever the interleaving); then the same choice as clean_clusters: per
// cluster the heaviest piece, the first in vertex order on a tie.
uint64_t clean_in_arena(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels, uint32_t K,
                        ClusteringReport& report) {
  const uint32_t V = mesh.vertex_count();
  constexpr uint32_t kBlock = 16384;
  std::vector<std::atomic<uint32_t>> parent(V);
  for (uint32_t v = 0; v < V; ++v) parent[v].store(v, std::memory_order_relaxed);
  auto find = [&](uint32_t x) {
    for (uint32_t p; (p = parent[x].load(std::memory_order_relaxed)) != x;) {
      const uint32_t g = parent[p].load(std::memory_order_relaxed);
      if (g != p) parent[x].compare_exchange_weak(p, g, std::memory_order_relaxed);  // path halving
      x = g;
    }
    return x;
  };
  for_each_block(V, kBlock, [&](uint32_t u) {
    const int32_t l = labels[u];
    if (l < 0) return;
    for (uint32_t n : mesh.neighbours(u)) {
      if (n <= u || labels[n] != l) continue;
      for (uint32_t a = u, b = n;;) {
        a = find(a);
        b = find(b);
        if (a == b) break;
        if (a > b) std::swap(a, b);
        uint32_t expected = b;  // link root b under the smaller root a
        if (parent[b].compare_exchange_strong(expected, a, std::memory_order_relaxed)) break;
      }
    }
  });
  std::vector<uint32_t> root(V);
  for_each_block(V, kBlock, [&](uint32_t v) { root[v] = find(v); });
  std::vector<double> weight(V, 0.0);
  for (uint32_t v = 0; v < V; ++v)
    if (labels[v] >= 0) weight[root[v]] += items.weight[v];
  std::vector<uint32_t> best(K, UINT32_MAX), pieces(K, 0);
  for (uint32_t v = 0; v < V; ++v) {
    const int32_t l = labels[v];
    if (l < 0 || root[v] != v) continue;
    ++pieces[l];
    if (best[l] == UINT32_MAX || weight[v] > weight[best[l]]) best[l] = v;
  }
  for (uint32_t c = 0; c < K; ++c) report.disconnected_clusters += pieces[c] > 1;
  uint64_t reset = 0;
  for (uint32_t v = 0; v < V; ++v)
    if (labels[v] >= 0 && best[labels[v]] != root[v]) {
      labels[v] = -1;
      ++reset;
    }
  if (reset) absorb_free_vertices(mesh, labels);
  report.cleaned_vertices += reset;
  return reset;
}

}  // namespace

uint64_t parallel_clean_clusters(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                                 uint32_t cluster_count, ClusteringReport& report, uint32_t threads) {
  threads = clustering_thread_count(threads);
  tbb::task_arena arena(int(std::min<uint32_t>(threads, 4096)));
  tls_threads = threads;
  uint64_t reset = 0;
  arena.execute([&] { reset = clean_in_arena(mesh, items, labels, cluster_count, report); });
  return reset;
}

void parallel_update_site_offsets(ClusterState& state, uint32_t threads) {
  if (state.quadric.empty()) return;
  state.use_offsets = true;
  threads = clustering_thread_count(threads);
  tbb::task_arena arena(int(std::min<uint32_t>(threads, 4096)));
  tls_threads = threads;
  arena.execute([&] { for_each_block(state.cluster_count(), 1024, [&](uint32_t c) { update_site_offset(state, c); }); });
}

uint32_t clustering_thread_count(uint32_t threads) {
  if (threads > 0) return threads;
  return uint32_t(std::max<size_t>(1, tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)));
}

}  // namespace streamcvd
