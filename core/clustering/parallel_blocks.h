// Internal to the parallel clustering (core/clustering/parallel_clustering.cpp, cluster_sites.cpp): the
// fork-join over blocks of indices that every parallel step uses, with a ThreadSanitizer variant.
#pragma once

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

namespace streamcvd::detail {

// Threads of the running parallel pass (set by its entry point on the calling thread).
inline thread_local uint32_t tls_threads = 1;

#if !defined(__SANITIZE_THREAD__)
// Runs fn(i) for i in [0, n) as TBB tasks (work stealing) in the current arena. The atomic
// hand-over orders the caller's writes before the tasks and the tasks' before the return.
// Blocks of exactly `grain` indices (simple partitioner): a thread that the OS descheduled
// holds back at most one block at the join, which matters on a loaded machine.
template <class Fn>
void for_each_block(uint32_t n, uint32_t grain, const Fn& fn) {
  std::atomic<uint32_t> sync{0};
  sync.store(1, std::memory_order_release);
  tbb::parallel_for(
      tbb::blocked_range<uint32_t>(0, n, grain),
      [&](const tbb::blocked_range<uint32_t>& range) {
        (void)sync.load(std::memory_order_acquire);
        for (uint32_t i = range.begin(); i != range.end(); ++i) fn(i);
        sync.fetch_add(1, std::memory_order_acq_rel);
      },
      tbb::simple_partitioner());
  (void)sync.load(std::memory_order_acquire);
}
#else
// ThreadSanitizer build: the Debian libtbb is not instrumented, so TSan cannot see the
// synchronisation inside its scheduler and reports every hand-over as a race. Here the same
// blocks run on tls_threads std::threads taking blocks from an atomic counter (dynamic
// scheduling, like stealing), whose start and join TSan does see: the clustering's own
// synchronisation (cluster locks, atomic labels, ownership) is what the sanitizer then checks.
template <class Fn>
void for_each_block(uint32_t n, uint32_t grain, const Fn& fn) {
  std::atomic<uint32_t> next{0};
  auto work = [&] {
    for (uint32_t b; (b = next.fetch_add(grain, std::memory_order_relaxed)) < n;)
      for (uint32_t i = b; i < std::min(n, b + grain); ++i) fn(i);
  };
  std::vector<std::thread> helpers;
  for (uint32_t t = 1; t < tls_threads; ++t) helpers.emplace_back(work);
  work();
  for (std::thread& h : helpers) h.join();
}
#endif

// One region per task.
template <class Fn>
void for_each_region(uint32_t n, const Fn& fn) {
  for_each_block(n, 1, fn);
}

}  // namespace streamcvd::detail
