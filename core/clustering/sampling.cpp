// The initial sampling (paper §VI-G), range by range (DESIGN.md §4): per-part sums → each
// component's clusters shared over its parts (largest remainder) → per range: exponential-race
// order, regions grown inside the range, steals → absorption of the free vertices
// (free_vertices.cpp). A range only ever writes its own vertices: the labels are the same for
// any thread count.
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <numeric>
#include <random>
#include <stdexcept>

#include "streamcvd/core/clustering/sampling.h"
#include "streamcvd/core/clustering/sampling_parts.h"

namespace streamcvd {

using sampling::for_each_range;
using sampling::kNone;
using sampling::Part;

namespace {

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
  std::vector<int32_t> renumbered;          // per cluster of the range: its id in store order
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


// Renumbers the clusters of range r (labels [first_label, first_label + count)) by their first
// vertex in store order. The seeds come in random order, so their ids were scattered over the
// range; numbered along the Hilbert order, neighbouring clusters get near ids, and every later
// pass indexed by cluster (the clustering's sums, the dual, the repair, the quality pass over
// output vertices) reads nearby memory (dragon ×9 → 300,000, I: 4.06 → 3.69 s, the quality pass
// 0.82 → 0.61 s, same Qav). O(range + count); `map` is the caller's scratch.
void number_clusters_in_store_order(VertexRange r, int32_t first_label, size_t count, std::span<int32_t> label,
                                    std::vector<int32_t>& map) {
  map.assign(count, -1);
  int32_t next = first_label;
  for (uint32_t v = r.begin; v < r.end; ++v) {
    const int32_t l = label[v];
    if (l < 0) continue;
    int32_t& renumbered = map[size_t(l - first_label)];
    if (renumbered < 0) renumbered = next++;
    label[v] = renumbered;
  }
  if (size_t(next - first_label) != count) throw std::logic_error("initial_sampling: a cluster of a range has no vertex");
}

}  // namespace

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
  for_each_range(mesh, ranges, kReadsFlags, [&](size_t i) {
    SamplingScratch& s = scratch.local();
    sampling::collect_parts(ranges[i], [&](uint32_t v) { return component_of[v]; }, weight, mesh.vertex_flags, s.index, s.parts);
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
    std::vector<uint32_t> share = sampling::proportional_split(part_weight, k, lo, hi);
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
  for_each_range(mesh, ranges, kReadsNeighbours, [&](size_t i) {
    SamplingScratch& s = scratch.local();
    sample_range(mesh, weight, component_of, ranges[i], seed + i * kRangeSeedStep, parts[i], target,
                 int32_t(first_label[i]), label.span(), s);
    number_clusters_in_store_order(ranges[i], int32_t(first_label[i]), size_t(first_label[i + 1] - first_label[i]),
                                   label.span(), s.renumbered);
  });
  scratch.clear();
  absorb_free_vertices(mesh, label.span());
  return label;
}


}  // namespace streamcvd
