// Absorption of free vertices (paper §VI-G after the sampling, §VI-B after the cleaning), range by
// range: a layered BFS inside each range, then rounds across the range frontiers. What crosses
// ranges is frontier-sized (the candidate lists); a range reads other ranges' labels only in a
// step where nobody writes, so the result is the same for any thread count.
#include <tbb/enumerable_thread_specific.h>

#include <algorithm>
#include <vector>

#include "streamcvd/core/clustering/sampling.h"
#include "streamcvd/core/clustering/sampling_parts.h"

namespace streamcvd {

using sampling::for_each_range;

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
  for_each_range(mesh, ranges, kReadsNeighbours, [&](size_t i) {
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
    for_each_range(mesh, ranges, kReadsNeighbours, [&](size_t i) {
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
    for_each_range(mesh, ranges, kReadsNeighbours, [&](size_t i) {
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
    for_each_range(mesh, ranges, 0, [&](size_t i) {
      std::vector<uint32_t>& c = candidates[i];
      std::sort(c.begin(), c.end());
      c.erase(std::unique(c.begin(), c.end()), c.end());
    });
  }
}


}  // namespace streamcvd
