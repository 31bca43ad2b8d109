// Parallel Algorithm 1 (DESIGN.md §4): the boundary-edge loop of core/clustering/clustering.h run over
// regions of the Hilbert-ordered vertex range as TBB tasks (work stealing), with per-cluster
// locks for the clusters that several regions touch. Same move test (core/clustering/cluster_energy.h),
// same stop rules and the same report as the serial loop.
//
// Two modes:
// - default: regions of one partition run concurrently; a cluster all of whose vertices are
//   region-interior is owned by that region and used without locks; every other cluster is
//   locked (try-lock in id order, labels re-read after locking, the edge postponed on failure).
//   Postponed edges are retried serially at the end of the loop. The result depends on the
//   scheduling: runs with the same seed and thread count may differ.
// - deterministic: no locks; each loop runs two phases over two partitions (the second shifted
//   by half a region), each region testing only the edges whose two clusters it owns, then a
//   serial pass over the vertices left, in a fixed order. Regions depend on V only, so the
//   output is byte-identical for every thread count.
#pragma once

#include <cstdint>
#include <span>

#include "streamcvd/core/clustering/clustering.h"

namespace streamcvd {

/// Threads a `threads` option (LoopOptions::threads) resolves to: 0 = TBB's current
/// max_allowed_parallelism (all cores unless a tbb::global_control limits it), otherwise
/// `threads`. O(1), thread-safe.
uint32_t clustering_thread_count(uint32_t threads);

// run_clustering_loops (core/clustering/clustering.h) is defined in parallel_clustering.cpp:
// options.threads worker threads in a tbb::task_arena of its own; thread-safe against nothing
// else touching the labels or the state. O((V + E) / T) per loop plus a serial pass over the
// postponed edges. solved_cluster_state spreads the site solves the same way (cluster_sites.cpp).

}  // namespace streamcvd
