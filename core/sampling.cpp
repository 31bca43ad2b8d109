// Component budget and initial sampling (paper §VI-G), range by range (DESIGN.md §4).
//
// Everything sized by V is either the caller's (labels, component ids: LargeArrays from its
// storage) or one range's scratch per thread; what crosses ranges is K-sized (components, the
// (range, component) *parts*, clusters) or frontier-sized (the absorption's candidate lists).
// A range only ever writes its own vertices, and reads other ranges' labels only in a step where
// nobody writes: the output is the same for any thread count.
//   budget:   chunk-wise union-find → component ids per range → per-part sums → components.
//   sampling: per-part sums → each component's clusters shared over its parts (largest
//             remainder) → per range: exponential-race order, regions grown inside the range,
//             steals → absorption of the free vertices (inside ranges, then across frontiers).
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>
#include <unordered_map>

#include "core/chunked_components.h"
#include "core/clustering.h"

namespace streamcvd {

namespace {

constexpr uint32_t kVerbatimVertices = 16;
constexpr double kSmallComponentShare = 0.2;
constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

// fn(i) for every range index, as TBB tasks of one range each.
template <class Fn>
void for_each_range(size_t count, const Fn& fn) {
  tbb::parallel_for(tbb::blocked_range<size_t>(0, count, 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) fn(i);
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

// Largest-remainder split of `budget` over `weights`, each share clamped to [lo_i, hi_i].
std::vector<uint32_t> proportional_split(const std::vector<double>& weights, uint64_t budget,
                                         const std::vector<uint32_t>& lo, const std::vector<uint32_t>& hi) {
  const size_t n = weights.size();
  std::vector<uint32_t> share(n, 0);
  std::vector<uint8_t> fixed(n, 0);
  // Iterate: components whose proportional share falls outside [lo, hi] are fixed at the bound,
  // the rest re-share what remains. Terminates in at most n rounds.
  for (size_t round = 0; round <= n; ++round) {
    double free_weight = 0;
    uint64_t free_budget = budget;
    for (size_t i = 0; i < n; ++i) {
      if (fixed[i]) free_budget -= std::min<uint64_t>(free_budget, share[i]);
      else free_weight += weights[i];
    }
    bool changed = false;
    for (size_t i = 0; i < n; ++i) {
      if (fixed[i]) continue;
      double ideal = free_weight > 0 ? double(free_budget) * weights[i] / free_weight : 0.0;
      if (ideal < lo[i]) { share[i] = lo[i]; fixed[i] = 1; changed = true; }
      else if (ideal > hi[i]) { share[i] = hi[i]; fixed[i] = 1; changed = true; }
    }
    if (changed) continue;
    std::vector<std::pair<double, size_t>> remainders;
    uint64_t given = 0;
    for (size_t i = 0; i < n; ++i) {
      if (fixed[i]) continue;
      double ideal = free_weight > 0 ? double(free_budget) * weights[i] / free_weight : 0.0;
      share[i] = uint32_t(std::floor(ideal));
      given += share[i];
      remainders.push_back({ideal - std::floor(ideal), i});
    }
    std::stable_sort(remainders.begin(), remainders.end(),
                     [](const auto& x, const auto& y) { return x.first > y.first; });
    for (size_t k = 0; given < free_budget && k < remainders.size(); ++k) {
      size_t i = remainders[k].second;
      if (share[i] < hi[i]) { ++share[i]; ++given; }
    }
    break;
  }
  return share;
}

// The mesh graph for chunked_components: every vertex on a face, joined to its neighbours (each
// in-range edge once).
RangeFill mesh_graph_fill(const MeshView& mesh) {
  return [&mesh](size_t, VertexRange r, RangePieceBuilder& b) {
    for (uint32_t v = r.begin; v < r.end; ++v) {
      if (mesh.faces_of(v).empty()) continue;
      b.add(v);
      for (uint32_t n : mesh.neighbours(v))
        if (n > v || !r.contains(n)) b.join(v, n);
    }
  };
}

}  // namespace

std::vector<VertexRange> sampling_ranges(const MeshView& mesh) {
  const uint32_t V = mesh.vertex_count();
  if (mesh.chunks.empty()) return {VertexRange{0, V}};
  // One range per chunk for a small mesh (ranges of a few hundred vertices would only cut its
  // regions), up to 16 ranges from 1M vertices on so that every thread has work.
  const uint32_t min_ranges = std::clamp<uint32_t>(V / 65536, 1, 16);
  return chunk_ranges(mesh.chunks, 1u << 20, min_ranges);
}

ComponentBudget plan_component_budget(const MeshView& mesh, const ItemData& items, uint32_t clusters,
                                      SmallComponents small_components, ArrayStorage& storage) {
  ComponentBudget b;
  const uint32_t V = mesh.vertex_count();
  const std::vector<VertexRange> ranges = sampling_ranges(mesh);
  // One union-find pass: each range's piece ids go straight into component_of_vertex, and the
  // merge's table turns them into component ids in the pass that sums the parts.
  const RangeFill fill = mesh_graph_fill(mesh);
  b.component_of_vertex = LargeArray<uint32_t>(V, storage, "component of vertex");
  std::vector<RangePieces> pieces(ranges.size());
  {
    tbb::enumerable_thread_specific<RangePieceBuilder> builders;
    for_each_range(ranges.size(), [&](size_t i) {
      const VertexRange r = ranges[i];
      RangePieceBuilder& builder = builders.local();
      builder.begin(r);
      fill(i, r, builder);
      pieces[i] = builder.finish(b.component_of_vertex.span().subspan(r.begin, r.size()));
    });
  }
  const ComponentTable table = merge_range_pieces(ranges, pieces);
  pieces = {};
  const uint32_t C = uint32_t(table.components);
  std::vector<std::vector<Part>> parts(ranges.size());
  struct Scratch {
    std::unordered_map<uint32_t, uint32_t> index;
    std::vector<Part> parts;
  };
  tbb::enumerable_thread_specific<Scratch> scratch;
  for_each_range(ranges.size(), [&](size_t i) {
    const VertexRange r = ranges[i];
    for (uint32_t v = r.begin; v < r.end; ++v) {
      uint32_t& c = b.component_of_vertex[v];
      if (c != kNoComponent) c = table.component(i, c);
    }
    Scratch& s = scratch.local();
    collect_parts(r, [&](uint32_t v) { return b.component_of_vertex[v]; }, items.weight, mesh.vertex_flags, s.index,
                  s.parts);
    parts[i] = s.parts;
  });
  // Component sums: the parts in range order (the same for any thread count).
  std::vector<double> weight(C, 0.0);
  b.vertices_per_component.assign(C, 0);
  b.component_closed.assign(C, 1);
  for (const std::vector<Part>& range_parts : parts)
    for (const Part& p : range_parts) {
      weight[p.component] += p.weight;
      b.vertices_per_component[p.component] += p.vertices;
      if (p.boundary) b.component_closed[p.component] = 0;
    }
  parts = {};
  double total = std::accumulate(weight.begin(), weight.end(), 0.0);
  std::vector<uint32_t> lo(C), hi(C);
  std::vector<uint8_t> small(C, 0);
  for (uint32_t c = 0; c < C; ++c) {
    uint32_t minimum = std::min<uint32_t>(b.component_closed[c] ? 4 : 3, b.vertices_per_component[c]);
    double ideal = total > 0 ? double(clusters) * weight[c] / total : 0.0;
    small[c] = ideal < minimum;
    hi[c] = b.vertices_per_component[c];
    lo[c] = small[c] ? (small_components == SmallComponents::Keep ? minimum : 0) : minimum;
    if (small[c] && small_components == SmallComponents::Drop) hi[c] = 0;
    // A kept component of a few vertices is copied as it is (one cluster per vertex): the dual
    // of 3-4 clusters on a handful of triangles is too often empty or degenerate.
    if (small[c] && small_components == SmallComponents::Keep && b.vertices_per_component[c] <= kVerbatimVertices)
      lo[c] = hi[c] = b.vertices_per_component[c];
  }
  // Kept small components may take at most a fifth of the budget (a scan with hundreds of
  // floating specks at a small N must still give the main surface its share): the heaviest are
  // kept within that cap, the others dropped and counted.
  if (small_components == SmallComponents::Keep) {
    std::vector<uint32_t> smalls;
    uint64_t needed = 0;
    for (uint32_t c = 0; c < C; ++c)
      if (small[c]) {
        smalls.push_back(c);
        needed += lo[c];
      }
    const uint64_t cap = uint64_t(double(clusters) * kSmallComponentShare);
    if (needed > cap) {
      std::stable_sort(smalls.begin(), smalls.end(), [&](uint32_t x, uint32_t y) { return weight[x] > weight[y]; });
      uint64_t used = 0;
      uint32_t dropped = 0;
      for (uint32_t c : smalls) {
        if (used + lo[c] <= cap) {
          used += lo[c];
        } else {
          lo[c] = hi[c] = 0;
          ++dropped;
        }
      }
      b.note = std::to_string(dropped) + " of " + std::to_string(smalls.size()) +
               " small components dropped: keeping them all would take more than a fifth of N";
    }
  }
  // Small components take their minimum first; the large ones share what is left.
  b.clusters_per_component = proportional_split(weight, clusters, lo, hi);
  for (uint32_t c = 0; c < C; ++c) {
    b.total_clusters += b.clusters_per_component[c];
    if (small[c]) {
      if (b.clusters_per_component[c] == 0) ++b.components_dropped;
      else ++b.small_components_kept;
    }
  }
  if (b.total_clusters != clusters && b.note.empty()) {
    uint64_t clusterable = 0;
    for (uint32_t c = 0; c < C; ++c) clusterable += b.vertices_per_component[c];
    if (b.total_clusters > clusters)
      b.note = "the " + std::to_string(b.small_components_kept) + " small components kept need " +
               std::to_string(b.total_clusters) + " clusters, more than the " + std::to_string(clusters) + " asked";
    else if (clusterable < clusters)
      b.note = "the input has only " + std::to_string(clusterable) + " vertices on faces";
    else
      b.note = "components could not take the whole budget";
  }
  return b;
}

std::vector<int32_t> initial_sampling(const MeshView& mesh, const ItemData& items, const ComponentBudget& budget,
                                      uint64_t seed) {
  const uint32_t V = mesh.vertex_count();
  const uint32_t C = uint32_t(budget.clusters_per_component.size());
  std::vector<int32_t> label(V, -1);
  std::vector<double> component_weight(C, 0.0);
  for (uint32_t v = 0; v < V; ++v)
    if (budget.component_of_vertex[v] != kNoComponent) component_weight[budget.component_of_vertex[v]] += items.weight[v];
  std::vector<double> target(C, 0.0);  // D of eq. 19, per component
  for (uint32_t c = 0; c < C; ++c)
    if (budget.clusters_per_component[c] > 0) target[c] = component_weight[c] / budget.clusters_per_component[c];
  std::vector<uint32_t> remaining = budget.clusters_per_component;

  // Seeds are drawn in proportion to weight (a weighted random order: key −ln(u)/M_j, the
  // exponential race), so that a region gets clusters by its area·density, not by how finely
  // it happens to be sampled (paper Fig. 5). Weightless vertices come last.
  // The key is ordered by its float bits (positive floats sort like their bit patterns), with
  // ties in vertex order: a stable LSD radix sort on two 16-bit digits, O(V).
  std::vector<uint32_t> order(V);
  {
    std::mt19937_64 rng(seed);
    std::vector<uint32_t> key(V), tmp_key(V), tmp_order(V);
    for (uint32_t v = 0; v < V; ++v) {
      double u = (double(rng() >> 11) + 0.5) * 0x1.0p-53;  // uniform in (0, 1)
      float k = items.weight[v] > 0 ? float(-std::log(u) / items.weight[v]) : std::numeric_limits<float>::infinity();
      uint32_t bits;
      std::memcpy(&bits, &k, sizeof bits);
      key[v] = bits;
      order[v] = v;
    }
    for (int shift = 0; shift < 32; shift += 16) {
      std::vector<uint32_t> start(65537, 0);
      for (uint32_t v = 0; v < V; ++v) ++start[((key[v] >> shift) & 0xFFFF) + 1];
      std::partial_sum(start.begin(), start.end(), start.begin());
      for (uint32_t i = 0; i < V; ++i) {
        uint32_t slot = start[(key[i] >> shift) & 0xFFFF]++;
        tmp_key[slot] = key[i];
        tmp_order[slot] = order[i];
      }
      key.swap(tmp_key);
      order.swap(tmp_order);
    }
  }

  int32_t next_label = 0;
  std::vector<uint32_t> queue;
  queue.reserve(4096);
  std::vector<int32_t> queued_by(V, -1);
  for (uint32_t v : order) {
    uint32_t c = budget.component_of_vertex[v];
    if (c == kNoComponent || label[v] >= 0 || remaining[c] == 0) continue;
    // Grow a region from v over free vertices of its component until it weighs D (eq. 19).
    int32_t id = next_label++;
    --remaining[c];
    double acc = 0;
    queued_by[v] = id;
    queue.assign(1, v);
    for (size_t head = 0; head < queue.size(); ++head) {
      uint32_t u = queue[head];
      label[u] = id;
      acc += items.weight[u];
      if (acc >= target[c]) break;
      for (uint32_t n : mesh.neighbours(u))
        if (label[n] < 0 && queued_by[n] != id) {
          queued_by[n] = id;
          queue.push_back(n);
        }
    }
  }
  // Components that ran out of free vertices: the paper's fallback picks non-free vertices;
  // we take them from the largest clusters of that component so no cluster empties.
  bool any_left = false;
  for (uint32_t c = 0; c < C; ++c) any_left |= remaining[c] > 0;
  if (any_left) {
    std::vector<uint32_t> size(size_t(next_label), 0);
    for (uint32_t v = 0; v < V; ++v)
      if (label[v] >= 0) ++size[label[v]];
    for (uint32_t v : order) {
      uint32_t c = budget.component_of_vertex[v];
      if (c == kNoComponent || remaining[c] == 0) continue;
      if (label[v] >= 0 && size[label[v]] < 2) continue;
      if (label[v] >= 0) --size[label[v]];
      label[v] = next_label++;
      size.push_back(1);
      --remaining[c];
    }
  }
  absorb_free_vertices(mesh, label);
  return label;
}

void absorb_free_vertices(const MeshView& mesh, std::span<int32_t> labels) {
  const uint32_t V = mesh.vertex_count();
  std::vector<uint32_t> frontier;
  for (uint32_t v = 0; v < V; ++v) {
    if (labels[v] >= 0) continue;
    for (uint32_t n : mesh.neighbours(v))
      if (labels[n] >= 0) {
        frontier.push_back(v);
        break;
      }
  }
  // Layered BFS: a free vertex takes the label of its lowest-id labelled neighbour of the
  // previous layer, so the result does not depend on queue order subtleties.
  std::vector<uint32_t> next;
  while (!frontier.empty()) {
    next.clear();
    std::vector<std::pair<uint32_t, int32_t>> assign;
    assign.reserve(frontier.size());
    for (uint32_t v : frontier) {
      if (labels[v] >= 0) continue;
      for (uint32_t n : mesh.neighbours(v))
        if (labels[n] >= 0) {
          assign.push_back({v, labels[n]});
          break;
        }
    }
    for (auto [v, l] : assign) labels[v] = l;
    for (auto [v, l] : assign)
      for (uint32_t n : mesh.neighbours(v))
        if (labels[n] < 0) next.push_back(n);
    std::sort(next.begin(), next.end());
    next.erase(std::unique(next.begin(), next.end()), next.end());
    frontier.swap(next);
  }
}

}  // namespace streamcvd
