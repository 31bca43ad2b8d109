#include "streamcvd/core/mesh/coincident_components.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstring>
#include <utility>

#include "streamcvd/core/mesh/chunked_components.h"

namespace streamcvd {

namespace {

// Vertices after v compared with it. Coincident vertices share a Hilbert cell (21 bits per
// axis); another vertex lands between them only when that cell holds several distinct points.
constexpr uint32_t kLookAhead = 8;

}  // namespace

std::vector<uint8_t> components_touching_others(const MeshView& mesh, std::span<const uint32_t> component_of_vertex,
                                                uint32_t components) {
  const uint32_t V = mesh.vertex_count();
  const float* P = mesh.positions.data();
  tbb::enumerable_thread_specific<std::vector<std::pair<uint32_t, uint32_t>>> touching;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, V, 1u << 16), [&](const tbb::blocked_range<uint32_t>& r) {
    const uint32_t end = uint32_t(std::min<uint64_t>(uint64_t(r.end()) + kLookAhead, V));
    const RangeVisit visit(mesh, "sampling", {r.begin(), end}, kReadsPositions);  // the budget's stage
    auto& pairs = touching.local();
    for (uint32_t v = r.begin(); v != r.end(); ++v) {
      const uint32_t a = component_of_vertex[v];
      if (a == kNoComponent) continue;
      for (uint32_t w = v + 1; w < std::min(v + 1 + kLookAhead, end); ++w) {
        const uint32_t b = component_of_vertex[w];
        if (b != kNoComponent && b != a && std::memcmp(P + 3 * size_t(v), P + 3 * size_t(w), 3 * sizeof(float)) == 0)
          pairs.emplace_back(a, b);
      }
    }
  });
  std::vector<uint8_t> touches(components, 0);
  for (const auto& pairs : touching)
    for (const auto& [a, b] : pairs) touches[a] = touches[b] = 1;
  return touches;
}

}  // namespace streamcvd
