// Parallel steps of minimize_clustering around the loops (core/clustering/parallel_clustering.h): the QEM
// site solves and the thread count.
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>

#include "streamcvd/core/mesh/parallel_blocks.h"
#include "streamcvd/core/clustering/parallel_clustering.h"

namespace streamcvd {

using detail::for_each_block;
using detail::tls_threads;

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
