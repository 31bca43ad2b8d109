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

#include "streamcvd/core/mesh/chunked_components.h"
#include "streamcvd/core/clustering/clustering.h"

namespace streamcvd {

namespace {

constexpr uint32_t kVerbatimVertices = 16;
constexpr double kSmallComponentShare = 0.2;
constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();

// fn(i) for every range index, as TBB tasks of one range each, each a visit of its range.
template <class Fn>
void for_each_range(const MeshView& mesh, std::span<const VertexRange> ranges, const Fn& fn) {
  tbb::parallel_for(tbb::blocked_range<size_t>(0, ranges.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      const RangeVisit visit(mesh, "sampling", ranges[i], kReadsNeighbours | kReadsVertexFaces | kReadsFlags);
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

// Range i draws from mt19937_64(seed + i·step): independent streams (the engine's seeding
// scrambles its seed), and a mesh of one range draws what the global sampling drew.
constexpr uint64_t kRangeSeedStep = 0x9E3779B97F4A7C15ull;

// One thread's scratch for the sampling of a range (local vertex index = v − range.begin).
struct SamplingScratch {
  std::unordered_map<uint32_t, uint32_t> index;
  std::vector<Part> parts;
  std::vector<uint32_t> part_of;            // local vertex → part of its range, kNone
  std::vector<uint32_t> key, tmp_key, order, tmp_order;
  std::vector<uint64_t> pairs;              // small ranges: (key, local vertex) sorted directly
  std::vector<uint32_t> counts;             // radix digit counts
  std::vector<int32_t> queued_by;           // local vertex → last region that queued it
  std::vector<uint32_t> queue;              // region growth, then the steal check's stack
  std::vector<uint32_t> remaining;          // per part: clusters still to seed
  std::vector<uint32_t> size;               // per cluster of the range (steals)
  std::vector<uint32_t> seen;               // local vertex → epoch of the steal check
  uint32_t epoch = 0;
};

// `order` = the range's local vertices in increasing key, ties by vertex: the sorted exponential
// race. Large ranges by a stable LSD radix sort on two 16-bit digits (positive floats sort like
// their bit patterns), small ones by sorting (key, vertex) pairs; the two give the same order.
void race_order(SamplingScratch& s, uint32_t n) {
  s.order.resize(n);
  if (n < 4096) {
    s.pairs.resize(n);
    for (uint32_t i = 0; i < n; ++i) s.pairs[i] = uint64_t(s.key[i]) << 32 | i;
    std::sort(s.pairs.begin(), s.pairs.end());
    for (uint32_t i = 0; i < n; ++i) s.order[i] = uint32_t(s.pairs[i]);
    return;
  }
  s.tmp_key.resize(n);
  s.tmp_order.resize(n);
  for (uint32_t i = 0; i < n; ++i) s.order[i] = i;
  for (int shift = 0; shift < 32; shift += 16) {
    s.counts.assign(65537, 0);
    for (uint32_t i = 0; i < n; ++i) ++s.counts[((s.key[i] >> shift) & 0xFFFF) + 1];
    std::partial_sum(s.counts.begin(), s.counts.end(), s.counts.begin());
    for (uint32_t i = 0; i < n; ++i) {
      const uint32_t slot = s.counts[(s.key[i] >> shift) & 0xFFFF]++;
      s.tmp_key[slot] = s.key[i];
      s.tmp_order[slot] = s.order[i];
    }
    s.key.swap(s.tmp_key);
    s.order.swap(s.tmp_order);
  }
}

// True when v's cluster stays connected without v: its neighbours in the cluster reach each
// other through the cluster without v (a BFS that stops once they are all found). The cluster
// lies inside range r (regions grow inside their range).
bool removable(const MeshView& mesh, VertexRange r, std::span<const int32_t> labels, uint32_t v, SamplingScratch& s) {
  const int32_t a = labels[v];
  const std::span<const uint32_t> around = mesh.neighbours(v);
  uint32_t need = 0, first = kNone;
  for (uint32_t n : around)
    if (r.contains(n) && labels[n] == a) {
      if (first == kNone) first = n;
      ++need;
    }
  if (need <= 1) return true;
  if (s.seen.size() != r.size() || ++s.epoch == 0) {
    s.seen.assign(r.size(), 0);
    s.epoch = 1;
  }
  s.seen[v - r.begin] = s.epoch;
  s.seen[first - r.begin] = s.epoch;
  s.queue.assign(1, first);
  uint32_t reached = 1;
  while (!s.queue.empty()) {
    const uint32_t u = s.queue.back();
    s.queue.pop_back();
    for (uint32_t n : mesh.neighbours(u)) {
      if (!r.contains(n) || labels[n] != a || s.seen[n - r.begin] == s.epoch) continue;
      s.seen[n - r.begin] = s.epoch;
      if (std::binary_search(around.begin(), around.end(), n) && ++reached == need) return true;
      s.queue.push_back(n);
    }
  }
  return false;
}

// Seeds and grows the regions of range r. `parts` are the range's parts (by component) with
// their cluster counts; `target` is D per component; labels of the range start at `first_label`.
void sample_range(const MeshView& mesh, std::span<const double> weight, std::span<const uint32_t> component_of,
                  VertexRange r, uint64_t rng_seed, std::span<const Part> parts, std::span<const double> target,
                  int32_t first_label, std::span<int32_t> label, SamplingScratch& s) {
  const uint32_t n = r.size();
  std::fill(label.begin() + r.begin, label.begin() + r.end, -1);
  s.part_of.resize(n);
  for (uint32_t i = 0, last_component = kNoComponent, last_part = kNone; i < n; ++i) {
    const uint32_t c = component_of[r.begin + i];
    if (c != last_component) {
      last_component = c;
      auto it = std::lower_bound(parts.begin(), parts.end(), c,
                                 [](const Part& p, uint32_t x) { return p.component < x; });
      last_part = it != parts.end() && it->component == c && it->clusters > 0 ? uint32_t(it - parts.begin()) : kNone;
    }
    s.part_of[i] = last_part;
  }
  // Seeds are drawn in proportion to weight (a weighted random order: key −ln(u)/M_j, the
  // exponential race), so that a region gets clusters by its area·density, not by how finely
  // it happens to be sampled (paper Fig. 5). Weightless vertices come last.
  std::mt19937_64 rng(rng_seed);
  s.key.resize(n);
  for (uint32_t i = 0; i < n; ++i) {
    const double u = (double(rng() >> 11) + 0.5) * 0x1.0p-53;  // uniform in (0, 1)
    const double w = weight[r.begin + i];
    const float k = w > 0 ? float(-std::log(u) / w) : std::numeric_limits<float>::infinity();
    std::memcpy(&s.key[i], &k, sizeof k);
  }
  race_order(s, n);

  s.remaining.resize(parts.size());
  for (size_t p = 0; p < parts.size(); ++p) s.remaining[p] = parts[p].clusters;
  s.queued_by.assign(n, -1);
  int32_t next_label = first_label;
  for (uint32_t i : s.order) {
    const uint32_t p = s.part_of[i];
    const uint32_t v = r.begin + i;
    if (p == kNone || label[v] >= 0 || s.remaining[p] == 0) continue;
    // Grow a region from v over free vertices of its part until it weighs D (eq. 19).
    const int32_t id = next_label++;
    --s.remaining[p];
    const double d = target[parts[p].component];
    double acc = 0;
    s.queued_by[i] = id;
    s.queue.assign(1, v);
    for (size_t head = 0; head < s.queue.size(); ++head) {
      const uint32_t u = s.queue[head];
      label[u] = id;
      acc += weight[u];
      if (acc >= d) break;
      for (uint32_t m : mesh.neighbours(u))
        if (r.contains(m) && label[m] < 0 && s.queued_by[m - r.begin] != id) {
          s.queued_by[m - r.begin] = id;
          s.queue.push_back(m);
        }
    }
  }
  // Parts that ran out of free vertices: the paper's fallback picks non-free vertices; we take
  // single vertices from clusters of that part that keep at least one vertex and stay connected.
  // A part has no more clusters than vertices, so a pass always finds one while some are due.
  bool any_left = false;
  for (uint32_t left : s.remaining) any_left |= left > 0;
  if (!any_left) return;
  s.size.assign(size_t(next_label - first_label), 0);
  for (uint32_t v = r.begin; v < r.end; ++v)
    if (label[v] >= 0) ++s.size[size_t(label[v] - first_label)];
  while (any_left) {
    bool progressed = false;
    for (uint32_t i : s.order) {
      const uint32_t p = s.part_of[i];
      const uint32_t v = r.begin + i;
      if (p == kNone || s.remaining[p] == 0) continue;
      if (label[v] >= 0) {
        if (s.size[size_t(label[v] - first_label)] < 2 || !removable(mesh, r, label, v, s)) continue;
        --s.size[size_t(label[v] - first_label)];
      }
      label[v] = next_label++;
      s.size.push_back(1);
      --s.remaining[p];
      progressed = true;
    }
    any_left = false;
    for (uint32_t left : s.remaining) any_left |= left > 0;
    if (any_left && !progressed) throw std::logic_error("initial_sampling: a part has more clusters than vertices");
  }
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
    for_each_range(mesh, ranges, [&](size_t i) {
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
  for_each_range(mesh, ranges, [&](size_t i) {
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

LargeArray<int32_t> initial_sampling(const MeshView& mesh, const ItemData& items, const ComponentBudget& budget,
                                     uint64_t seed, ArrayStorage& storage) {
  const uint32_t V = mesh.vertex_count();
  const uint32_t C = uint32_t(budget.clusters_per_component.size());
  if (budget.component_of_vertex.size() != V || items.weight.size() != V)
    throw std::invalid_argument("initial_sampling: the budget or the items are for a mesh of another size");
  const std::vector<VertexRange> ranges = sampling_ranges(mesh);
  const std::span<const uint32_t> component_of = budget.component_of_vertex.span();
  const std::span<const double> weight = items.weight;

  // Parts and their weights under these items (the sampling items may differ from the budget's).
  std::vector<std::vector<Part>> parts(ranges.size());
  tbb::enumerable_thread_specific<SamplingScratch> scratch;
  for_each_range(mesh, ranges, [&](size_t i) {
    SamplingScratch& s = scratch.local();
    collect_parts(ranges[i], [&](uint32_t v) { return component_of[v]; }, weight, mesh.vertex_flags, s.index, s.parts);
    parts[i] = s.parts;
    for (const Part& p : parts[i])
      if (p.component >= C) throw std::invalid_argument("initial_sampling: a component id beyond the budget");
  });

  // Each component's clusters over its parts, in proportion to their weights, at most one per
  // vertex (the budget gives no component more clusters than vertices, so the total is exact).
  // D (eq. 19) is the component's weight over its clusters, whichever range a region grows in.
  std::vector<uint32_t> part_start(size_t(C) + 1, 0);  // parts of component c, in range order
  for (const std::vector<Part>& range_parts : parts)
    for (const Part& p : range_parts) ++part_start[p.component + 1];
  std::partial_sum(part_start.begin(), part_start.end(), part_start.begin());
  std::vector<Part*> by_component(part_start.back());
  {
    std::vector<uint32_t> fill(part_start.begin(), part_start.end() - 1);
    for (std::vector<Part>& range_parts : parts)
      for (Part& p : range_parts) by_component[fill[p.component]++] = &p;
  }
  std::vector<double> target(C, 0.0), part_weight;
  std::vector<uint32_t> lo, hi;
  for (uint32_t c = 0; c < C; ++c) {
    const uint32_t k = budget.clusters_per_component[c];
    const std::span<Part* const> cp(by_component.data() + part_start[c], part_start[c + 1] - part_start[c]);
    double w = 0;
    for (const Part* p : cp) w += p->weight;
    if (k == 0 || cp.empty()) continue;
    target[c] = w / k;
    if (cp.size() == 1) {
      cp[0]->clusters = std::min(k, cp[0]->vertices);
      continue;
    }
    part_weight.resize(cp.size());
    lo.assign(cp.size(), 0);
    hi.resize(cp.size());
    for (size_t j = 0; j < cp.size(); ++j) {
      part_weight[j] = cp[j]->weight;
      hi[j] = cp[j]->vertices;
    }
    std::vector<uint32_t> share = proportional_split(part_weight, k, lo, hi);
    // Weightless parts get at most one each from the remainders: the rest, in range order.
    uint64_t given = std::accumulate(share.begin(), share.end(), uint64_t(0));
    for (size_t j = 0; given < k && j < cp.size(); ++j) {
      const uint32_t more = uint32_t(std::min<uint64_t>(k - given, hi[j] - share[j]));
      share[j] += more;
      given += more;
    }
    for (size_t j = 0; j < cp.size(); ++j) cp[j]->clusters = share[j];
  }
  std::vector<int64_t> first_label(ranges.size() + 1, 0);
  for (size_t i = 0; i < ranges.size(); ++i) {
    first_label[i + 1] = first_label[i];
    for (const Part& p : parts[i]) first_label[i + 1] += p.clusters;
  }
  if (first_label.back() > std::numeric_limits<int32_t>::max())
    throw std::invalid_argument("initial_sampling: more clusters than int32 labels");

  LargeArray<int32_t> label(V, storage, "labels");
  for_each_range(mesh, ranges, [&](size_t i) {
    sample_range(mesh, weight, component_of, ranges[i], seed + i * kRangeSeedStep, parts[i], target,
                 int32_t(first_label[i]), label.span(), scratch.local());
  });
  scratch.clear();
  absorb_free_vertices(mesh, label.span());
  return label;
}

void absorb_free_vertices(const MeshView& mesh, std::span<int32_t> labels) {
  const std::vector<VertexRange> ranges = sampling_ranges(mesh);
  const size_t R = ranges.size();
  struct Offer {
    uint32_t vertex;
    int32_t label;
  };
  struct Scratch {
    std::vector<uint32_t> assigned, next;  // one BFS layer, the next
    std::vector<Offer> layer;              // labels of a layer, before they are applied
  };
  tbb::enumerable_thread_specific<Scratch> scratch;
  // Free vertices of each range that might take a label across the frontier (sorted, unique).
  std::vector<std::vector<uint32_t>> candidates(R);
  // Neighbours in other ranges of what a range labelled in a round (unsorted).
  std::vector<std::vector<uint32_t>> outbox(R);
  std::vector<std::vector<Offer>> offers(R);
  // Layered BFS inside range r from s.layer (ascending): the layer's labels are applied, then
  // the free neighbours in r of the vertices just labelled (ascending) take the label of their
  // lowest-id labelled neighbour in r, and so on; on_labelled(v) sees every vertex labelled.
  // A layer's labels come from earlier layers only, so the result does not depend on the order
  // inside a layer. Reads and writes only labels of r.
  auto spread = [&](VertexRange r, Scratch& s, const auto& on_labelled) {
    while (!s.layer.empty()) {
      s.assigned.clear();
      for (const Offer& o : s.layer) {
        labels[o.vertex] = o.label;
        s.assigned.push_back(o.vertex);
        on_labelled(o.vertex);
      }
      s.next.clear();
      for (uint32_t u : s.assigned)
        for (uint32_t n : mesh.neighbours(u))
          if (r.contains(n) && labels[n] < 0) s.next.push_back(n);
      std::sort(s.next.begin(), s.next.end());
      s.next.erase(std::unique(s.next.begin(), s.next.end()), s.next.end());
      s.layer.clear();
      for (uint32_t v : s.next)
        for (uint32_t n : mesh.neighbours(v))
          if (r.contains(n) && labels[n] >= 0) {
            s.layer.push_back({v, labels[n]});
            break;
          }
    }
  };

  // Inside every range: the free vertices next to a labelled one of the range are the first
  // layer; those left free by the BFS that touch another range are the first round's candidates.
  for_each_range(mesh, ranges, [&](size_t i) {
    const VertexRange r = ranges[i];
    Scratch& s = scratch.local();
    s.layer.clear();
    candidates[i].clear();
    for (uint32_t v = r.begin; v < r.end; ++v) {
      if (labels[v] >= 0) continue;
      bool across = false, found = false;
      for (uint32_t n : mesh.neighbours(v)) {
        if (!r.contains(n)) across = true;
        else if (!found && labels[n] >= 0) {
          s.layer.push_back({v, labels[n]});
          found = true;
        }
      }
      if (across && !found) candidates[i].push_back(v);
    }
    spread(r, s, [](uint32_t) {});
    std::erase_if(candidates[i], [&](uint32_t v) { return labels[v] >= 0; });
  });

  auto range_of = [&](uint32_t v) {
    auto it = std::upper_bound(ranges.begin(), ranges.end(), v, [](uint32_t x, const VertexRange& r) { return x < r.begin; });
    return size_t(it - ranges.begin()) - 1;
  };
  for (;;) {
    // Across the frontiers, reading only (nobody writes in this step): a candidate takes the
    // label of its lowest-id labelled neighbour in another range.
    for_each_range(mesh, ranges, [&](size_t i) {
      const VertexRange r = ranges[i];
      offers[i].clear();
      for (uint32_t v : candidates[i]) {
        if (labels[v] >= 0) continue;
        for (uint32_t n : mesh.neighbours(v))
          if (!r.contains(n) && labels[n] >= 0) {
            offers[i].push_back({v, labels[n]});
            break;
          }
      }
    });
    bool any = false;
    for (const std::vector<Offer>& o : offers) any |= !o.empty();
    if (!any) break;
    // Each range takes its offers and spreads them inside; the neighbours in other ranges of
    // what it labelled are the next round's candidates.
    for_each_range(mesh, ranges, [&](size_t i) {
      const VertexRange r = ranges[i];
      Scratch& s = scratch.local();
      outbox[i].clear();
      s.layer.assign(offers[i].begin(), offers[i].end());
      spread(r, s, [&](uint32_t u) {
        for (uint32_t n : mesh.neighbours(u))
          if (!r.contains(n)) outbox[i].push_back(n);
      });
    });
    for (std::vector<uint32_t>& c : candidates) c.clear();
    for (const std::vector<uint32_t>& out : outbox)
      for (uint32_t n : out) candidates[range_of(n)].push_back(n);
    for_each_range(mesh, ranges, [&](size_t i) {
      std::vector<uint32_t>& c = candidates[i];
      std::sort(c.begin(), c.end());
      c.erase(std::unique(c.begin(), c.end()), c.end());
    });
  }
}

}  // namespace streamcvd
