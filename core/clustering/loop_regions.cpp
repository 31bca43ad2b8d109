// Regions and census of the parallel clustering loop: see core/clustering/loop_regions.h.
#include "streamcvd/core/clustering/loop_regions.h"

#include <algorithm>
#include <utility>

namespace streamcvd::detail {

// Region boundaries: each store chunk split into pieces of about `length` vertices (a region
// never straddles two chunks, so a region's data is paged in with one chunk).
std::vector<uint32_t> region_bounds(const MeshView& mesh, uint32_t length) {
  const uint32_t V = mesh.vertex_count();
  length = std::max(length, V / (kMaxRegions / 2) + 1);  // chunk rounding adds at most one per chunk
  std::vector<std::pair<uint32_t, uint32_t>> ranges;
  for (const Chunk& c : mesh.chunks) {
    if (c.vertex_begin != (ranges.empty() ? 0 : ranges.back().second) || c.vertex_end < c.vertex_begin) {
      ranges.clear();
      break;
    }
    if (c.vertex_end > c.vertex_begin) ranges.emplace_back(c.vertex_begin, c.vertex_end);
  }
  if (ranges.empty() || ranges.back().second != V) ranges.assign(1, {0, V});
  std::vector<uint32_t> b = {0};
  for (auto [first, last] : ranges) {
    const uint64_t n = std::max<uint64_t>(1, (uint64_t(last - first) + length / 2) / std::max(1u, length));
    for (uint64_t i = 1; i <= n; ++i) {
      const uint32_t cut = uint32_t(first + uint64_t(last - first) * i / n);
      if (cut > b.back()) b.push_back(cut);
    }
  }
  if (b.back() != V) b.push_back(V);
  if (b.size() - 1 > kMaxRegions && ranges.size() > 1) {  // too many chunks: ignore them
    const uint32_t n = std::min<uint32_t>(kMaxRegions, std::max<uint32_t>(1, V / std::max(1u, length)));
    b.assign(1, 0);
    for (uint32_t i = 1; i <= n; ++i) b.push_back(uint32_t(uint64_t(V) * i / n));
  }
  return b;
}

// The boundaries shifted by half a region: clusters cut by one partition are inside the other.
std::vector<uint32_t> shifted_bounds(const std::vector<uint32_t>& b) {
  std::vector<uint32_t> s = {0};
  for (size_t i = 0; i + 1 < b.size(); ++i) {
    const uint32_t mid = b[i] + (b[i + 1] - b[i]) / 2;
    if (mid > s.back()) s.push_back(mid);
  }
  if (s.back() != b.back()) s.push_back(b.back());
  return s;
}

Partition allocate_partition(uint32_t vertex_count, std::vector<uint32_t> bounds, ArrayStorage& storage) {
  Partition p;
  p.begin = std::move(bounds);
  p.interior = LargeArray<uint8_t>(vertex_count, storage, "region interior marks");
  p.region = LargeArray<uint16_t>(vertex_count, storage, "vertex regions");
  return p;
}

Census make_census(const MeshView& mesh, const Partition& p, std::span<const int32_t> labels, uint32_t cluster_count) {
  Census c;
  c.boundary.assign(cluster_count, 0);
  c.sum.assign(cluster_count, 0);
  c.sum2.assign(cluster_count, 0);
  auto count = [&](uint32_t first, uint32_t last) {
    for (uint32_t v = first; v < last; ++v) {
      const int32_t l = labels[v];
      if (l < 0) continue;
      const uint64_t r = p.region[v];
      c.boundary[l] += !p.interior[v];
      c.sum[l] += r;
      c.sum2[l] += r * r;
    }
  };
  // Chunk by chunk, so that out of core each chunk's labels and marks are read ahead.
  uint32_t done = 0;
  for (const Chunk& k : mesh.chunks) {
    if (k.vertex_begin != done || k.vertex_end < k.vertex_begin || k.vertex_end > labels.size()) break;
    const RangeVisit visit(mesh, "clustering", {k.vertex_begin, k.vertex_end}, kReadsWorkArrays);
    count(k.vertex_begin, k.vertex_end);
    done = k.vertex_end;
  }
  count(done, uint32_t(labels.size()));
  return c;
}

}  // namespace streamcvd::detail
