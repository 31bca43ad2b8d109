// The sites of a clustering under its metric, solved over threads (the QEM points of the Q
// metrics are one 3×3 eigen-solve per cluster, independent of each other), and the thread count
// the clustering options resolve to.
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>

#include "streamcvd/core/clustering/clustering.h"
#include "streamcvd/core/clustering/parallel_clustering.h"
#include "streamcvd/core/clustering/parallel_blocks.h"

namespace streamcvd {

ClusterState solved_cluster_state(const ItemData& items, std::span<const int32_t> labels, uint32_t cluster_count,
                                  const ClusteringOptions& options) {
  ClusterState state = make_cluster_state(items, labels, cluster_count, options.metric, options.qem_threshold);
  const uint32_t threads = clustering_thread_count(options.loops.threads);
  if (state.quadric.empty() || threads == 1) {
    update_site_offsets(state);  // nothing to solve, or one thread: no arena
    return state;
  }
  state.use_offsets = true;
  tbb::task_arena arena(int(std::min<uint32_t>(threads, 4096)));
  detail::tls_threads = threads;
  arena.execute([&] {
    detail::for_each_block(state.cluster_count(), 1024, [&](uint32_t c) { update_site_offset(state, c); });
  });
  return state;
}

uint32_t clustering_thread_count(uint32_t threads) {
  if (threads > 0) return threads;
  return uint32_t(std::max<size_t>(1, tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism)));
}

}  // namespace streamcvd
