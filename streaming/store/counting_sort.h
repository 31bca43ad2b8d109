// Stable parallel counting sort, the workhorse of the store build's passes (vertex order, faces
// by owner). Internal to streaming/.
#pragma once

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <utility>
#include <vector>

namespace streamcvd {

/// Number of item ranges of counting_sort: one per thread, at most 8, fewer for small inputs
/// (each range costs a count array). The output never depends on it.
inline uint32_t counting_sort_parts(uint64_t items) {
  const int threads = tbb::this_task_arena::max_concurrency();
  return uint32_t(std::clamp<uint64_t>(std::min<uint64_t>(uint64_t(std::max(threads, 1)), 8), 1,
                                       std::max<uint64_t>(1, items >> 16)));
}

/// Stable counting sort of items 0..n-1 by bucket_of(i) < buckets: `start` gets buckets + 1
/// entries (bucket b holds positions [start[b], start[b+1])), and place(i, position) is called
/// once per item, in increasing i within each bucket. The items are split into
/// counting_sort_parts() contiguous ranges, each counted and placed by one task with its own
/// cursor per bucket (the prefix sum runs in (bucket, range) order): one branch-free pass over
/// the input per phase, and the result is the unique stable order whatever the number of
/// ranges. n < 2^32. Memory: parts × buckets 32-bit counts. `counted()` runs once `start` is
/// complete and before the first place() (e.g. to size the output).
template <typename Start, typename BucketOf, typename Place, typename Counted = void (*)()>
void counting_sort(uint64_t n, uint32_t buckets, BucketOf bucket_of, Start& start, Place place,
                   Counted counted = [] {}) {
  constexpr uint32_t kScanBlocks = 64;  // bucket blocks of the parallel prefix sum
  const uint32_t parts = counting_sort_parts(n);
  auto item_begin = [&](uint32_t p) { return n * p / parts; };
  std::vector<std::vector<uint32_t>> cursor(parts);
  tbb::parallel_for(uint32_t(0), parts, [&](uint32_t p) {
    cursor[p].assign(buckets, 0);  // here, so that each task pages in its own array
    for (uint64_t i = item_begin(p); i != item_begin(p + 1); ++i) ++cursor[p][bucket_of(i)];
  });
  // Prefix sum in (bucket, range) order, in parallel over kScanBlocks bucket blocks: their totals,
  // then each block from its base. Integer sums: the same result for any split.
  start.resize(size_t(buckets) + 1);
  auto block_begin = [&](uint32_t k) { return uint32_t(uint64_t(buckets) * k / kScanBlocks); };
  std::array<uint32_t, kScanBlocks + 1> base{};
  tbb::parallel_for(uint32_t(0), kScanBlocks, [&](uint32_t k) {
    uint32_t total = 0;
    for (uint32_t p = 0; p < parts; ++p)
      for (uint32_t b = block_begin(k); b != block_begin(k + 1); ++b) total += cursor[p][b];
    base[k + 1] = total;
  });
  for (uint32_t k = 0; k < kScanBlocks; ++k) base[k + 1] += base[k];
  tbb::parallel_for(uint32_t(0), kScanBlocks, [&](uint32_t k) {
    uint32_t sum = base[k];
    for (uint32_t b = block_begin(k); b != block_begin(k + 1); ++b) {
      start[b] = sum;
      for (uint32_t p = 0; p < parts; ++p) sum += std::exchange(cursor[p][b], sum);
    }
  });
  start[buckets] = base[kScanBlocks];
  counted();
  tbb::parallel_for(uint32_t(0), parts, [&](uint32_t p) {
    uint32_t* at = cursor[p].data();
    for (uint64_t i = item_begin(p); i != item_begin(p + 1); ++i) place(i, at[bucket_of(i)]++);
  });
}

}  // namespace streamcvd
