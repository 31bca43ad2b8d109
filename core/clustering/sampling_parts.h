// What the component budget, the initial sampling and the absorption of free vertices share
// (core/clustering/sampling.h): visits of the sampling ranges as TBB tasks, the (range,
// component) parts with their sums, and the largest-remainder split. Internal header.
#pragma once

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstdint>
#include <limits>
#include <span>
#include <unordered_map>
#include <vector>

#include "streamcvd/core/mesh/chunked_components.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd::sampling {

constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

// fn(i) for every range index, as TBB tasks of one range each, each a visit of its range that
// reads `arrays` (MeshArray bits: out of core only those are read ahead).
template <class Fn>
void for_each_range(const MeshView& mesh, std::span<const VertexRange> ranges, uint8_t arrays, const Fn& fn) {
  tbb::parallel_for(tbb::blocked_range<size_t>(0, ranges.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      const RangeVisit visit(mesh, "sampling", ranges[i], arrays);
      fn(i);
    }
  });
}

// The vertices of one component inside one range: the unit the sampling shares clusters over.
struct Part {
  uint32_t component = kNone;
  uint32_t vertices = 0;
  double weight = 0;       // Σ item weights, summed in vertex order (deterministic)
  uint8_t boundary = 0;    // some vertex is on a boundary edge
  uint32_t clusters = 0;   // sampling: clusters this part grows
};

// Per-range sums by component. `component_of(v)` gives v's component or kNoComponent. The parts
// come out sorted by component. `index` is the caller's per-thread scratch.
template <class ComponentOf>
void collect_parts(VertexRange r, const ComponentOf& component_of, std::span<const double> weight,
                   std::span<const uint8_t> flags, std::unordered_map<uint32_t, uint32_t>& index,
                   std::vector<Part>& out) {
  out.clear();
  index.clear();
  uint32_t last_component = kNoComponent, last_part = 0;
  for (uint32_t v = r.begin; v < r.end; ++v) {
    const uint32_t c = component_of(v);
    if (c == kNoComponent) continue;
    if (c != last_component) {  // Hilbert order: runs of one component, few map look-ups
      auto [it, inserted] = index.try_emplace(c, uint32_t(out.size()));
      if (inserted) out.push_back(Part{c});
      last_component = c;
      last_part = it->second;
    }
    Part& p = out[last_part];
    p.weight += weight[v];
    ++p.vertices;
    p.boundary |= uint8_t((flags[v] & kVertexBoundary) != 0);
  }
  std::sort(out.begin(), out.end(), [](const Part& a, const Part& b) { return a.component < b.component; });
}

/// Largest-remainder split of `budget` over `weights`, each share clamped to [lo_i, hi_i]
/// (iterated: shares outside their bounds are fixed there and the rest re-shared). O(n²) worst
/// case, n rounds at most. Deterministic.
std::vector<uint32_t> proportional_split(const std::vector<double>& weights, uint64_t budget,
                                         const std::vector<uint32_t>& lo, const std::vector<uint32_t>& hi);

}  // namespace streamcvd::sampling
