// The component budget (paper §VI-G, DESIGN.md §4): chunk-wise union-find → component ids per
// range → per-part sums → components → clusters per component (largest remainder). Everything
// sized by V is the caller's (component ids, from its storage) or one range's scratch per thread.
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <unordered_map>

#include "streamcvd/core/clustering/sampling.h"
#include "streamcvd/core/clustering/sampling_parts.h"
#include "streamcvd/core/mesh/coincident_components.h"
#include "streamcvd/core/mesh/vec3.h"

namespace streamcvd {

using sampling::for_each_range;
using sampling::Part;

namespace {

constexpr uint32_t kVerbatimVertices = 16;
constexpr double kSmallComponentShare = 0.2;

// The mesh graph for chunked_components: every vertex on a face, joined to its neighbours (each
// in-range edge once).
RangeFill mesh_graph_fill(const MeshView& mesh) {
  return [&mesh](size_t, VertexRange r, RangePieceBuilder& b) {
    for (uint32_t v = r.begin; v < r.end; ++v) {
      if (mesh.is_isolated(v)) continue;
      b.add(v);
      for (uint32_t n : mesh.neighbours(v))
        if (n > v || !r.contains(n)) b.join(v, n);
    }
  };
}

// Closed components that enclose (nearly) no volume: of those flagged in `candidates`, the ones
// whose |signed volume| (divergence theorem: Σ p0 · (p1 × p2) / 6 over their faces) is below
// kDoubleLayerVolume · area^1.5. Faces are counted at their smallest corner, range by range, and
// summed in range order (the same for any thread count). O(V + the candidates' faces),
// TBB-parallel over ranges; memory O(candidates per range).
constexpr double kDoubleLayerVolume = 1e-3;
std::vector<uint8_t> double_layer_components(const MeshView& mesh, std::span<const VertexRange> ranges,
                                             std::span<const uint32_t> component_of_vertex,
                                             const std::vector<uint8_t>& candidates) {
  struct Sums {
    double area = 0, volume = 0;
  };
  vec3::Vec3 origin = {0, 0, 0};  // the first chunk's centre: fewer digits lost in the products
  if (!mesh.chunks.empty())
    for (int k = 0; k < 3; ++k) origin[k] = 0.5 * (double(mesh.chunks[0].bbox_min[k]) + mesh.chunks[0].bbox_max[k]);
  std::vector<std::vector<std::pair<uint32_t, Sums>>> parts(ranges.size());
  tbb::enumerable_thread_specific<std::unordered_map<uint32_t, Sums>> scratch;
  for_each_range(mesh, ranges, kReadsAllArrays, [&](size_t i) {
    std::unordered_map<uint32_t, Sums>& sums = scratch.local();
    sums.clear();
    for (uint32_t v = ranges[i].begin; v < ranges[i].end; ++v) {
      const uint32_t c = component_of_vertex[v];
      if (c == kNoComponent || !candidates[c]) continue;
      uint32_t last = UINT32_MAX;
      for (uint32_t f : mesh.faces_of(v)) {
        if (f == last) continue;  // listed once per corner holding v
        last = f;
        const uint32_t* t = &mesh.triangles[3 * size_t(f)];
        if (std::min({t[0], t[1], t[2]}) != v) continue;
        const vec3::Vec3 p0 = vec3::sub(vec3::point(mesh.positions, t[0]), origin);
        const vec3::Vec3 p1 = vec3::sub(vec3::point(mesh.positions, t[1]), origin);
        const vec3::Vec3 p2 = vec3::sub(vec3::point(mesh.positions, t[2]), origin);
        const vec3::Vec3 n = vec3::cross(vec3::sub(p1, p0), vec3::sub(p2, p0));
        Sums& s = sums[c];
        s.area += 0.5 * vec3::norm(n);
        s.volume += vec3::dot(p0, n) / 6;  // p0 · (e1 × e2) = p0 · (p1 × p2)
      }
    }
    parts[i].assign(sums.begin(), sums.end());
    std::sort(parts[i].begin(), parts[i].end(), [](const auto& x, const auto& y) { return x.first < y.first; });
  });
  std::vector<Sums> total(candidates.size());
  for (const auto& range_parts : parts)
    for (const auto& [c, s] : range_parts) total[c].area += s.area, total[c].volume += s.volume;
  std::vector<uint8_t> flat(candidates.size(), 0);
  for (size_t c = 0; c < candidates.size(); ++c)
    flat[c] = candidates[c] && std::abs(total[c].volume) < kDoubleLayerVolume * std::pow(total[c].area, 1.5);
  return flat;
}

}  // namespace

namespace sampling {

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

}  // namespace sampling

const char* small_components_name(SmallComponents mode) { return mode == SmallComponents::Drop ? "drop" : "keep"; }

bool parse_small_components(std::string_view text, SmallComponents& out) {
  for (SmallComponents m : {SmallComponents::Keep, SmallComponents::Drop})
    if (text == small_components_name(m)) {
      out = m;
      return true;
    }
  return false;
}

std::vector<VertexRange> sampling_ranges(const MeshView& mesh) {
  const uint32_t V = mesh.vertex_count();
  if (mesh.chunks.empty()) return {VertexRange{0, V}};
  // One range per chunk for a small mesh (ranges of a few hundred vertices would only cut its
  // regions), up to 16 ranges from 1M vertices on so that every thread has work.
  const uint32_t min_ranges = std::clamp<uint32_t>(V / 65536, 1, 16);
  return chunk_ranges(mesh.chunks, 1u << 20, min_ranges);
}

ComponentBudget plan_component_budget(const MeshView& mesh, const ItemData& items, uint32_t clusters,
                                      SmallComponents small_components, ArrayStorage& storage,
                                      bool drop_touching_small) {
  ComponentBudget b;
  const uint32_t V = mesh.vertex_count();
  const std::vector<VertexRange> ranges = sampling_ranges(mesh);
  // One union-find pass: each range's piece ids go straight into component_of_vertex, and the
  // merge's table turns them into component ids in the pass that sums the parts.
  const RangeFill fill = mesh_graph_fill(mesh);
  b.component_of_vertex = LargeArray<uint32_t>(V, storage, "component of vertex", ArrayUse::Cold);
  std::vector<RangePieces> pieces(ranges.size());
  {
    tbb::enumerable_thread_specific<RangePieceBuilder> builders;
    // The vertex flags say which vertices are on no face: the face lists are not read.
    for_each_range(mesh, ranges, kReadsNeighbours | kReadsFlags, [&](size_t i) {
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
  for_each_range(mesh, ranges, kReadsFlags, [&](size_t i) {
    const VertexRange r = ranges[i];
    for (uint32_t v = r.begin; v < r.end; ++v) {
      uint32_t& c = b.component_of_vertex[v];
      if (c != kNoComponent) c = table.component(i, c);
    }
    Scratch& s = scratch.local();
    sampling::collect_parts(r, [&](uint32_t v) { return b.component_of_vertex[v]; }, items.weight, mesh.vertex_flags, s.index,
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
  // A sheet the cleaning cut off a non-manifold junction (a fin, a flap of a doubled wall) goes,
  // whatever the small-component rule (issue 16), when it is below the output resolution or a
  // double layer: closed round no volume, the two sides of one surface (the cleaning pairs a
  // face with its near copy, streaming/store/store_clean.cpp), which the output would repeat as
  // a flat closed piece inside the surface it was cut from.
  if (drop_touching_small && C > 1) {
    const std::vector<uint8_t> touches = components_touching_others(mesh, b.component_of_vertex.span(), C);
    std::vector<uint8_t> flat(C, 0);
    for (uint32_t c = 0; c < C; ++c) flat[c] = touches[c] && !small[c] && b.component_closed[c] && hi[c] > 0;
    if (std::find(flat.begin(), flat.end(), uint8_t(1)) != flat.end())
      flat = double_layer_components(mesh, ranges, b.component_of_vertex.span(), flat);
    for (uint32_t c = 0; c < C; ++c)
      if (((small[c] && touches[c]) || flat[c]) && hi[c] > 0) {
        lo[c] = hi[c] = 0;
        ++b.sheets_dropped;
      }
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
  b.clusters_per_component = sampling::proportional_split(weight, clusters, lo, hi);
  for (uint32_t c = 0; c < C; ++c) {
    b.total_clusters += b.clusters_per_component[c];
    if (b.clusters_per_component[c] == 0) ++b.components_dropped;  // small, or a double layer
    else if (small[c]) ++b.small_components_kept;
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

}  // namespace streamcvd
