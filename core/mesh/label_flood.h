// Breadth-first flood inside one cluster label: the vertices labelled `label` that mesh edges
// between such vertices join to a set of sources. The farthest-point seeds and the parts of a
// cluster split (core/dual/cluster_repair.cpp) are such floods. Header-only, no allocation past
// the queue's capacity; the caller owns the scratch (not shared between threads).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

/// Multi-source BFS from `sources` (vertices labelled `label`) over the 1-rings, through vertices
/// labelled `label` only. `queue` receives the vertices reached in BFS order, sources first (its
/// back is the vertex farthest in hops from every source). A vertex v is reached once:
/// stamp[slot(v)] == mark afterwards (`slot` maps the label's vertices into `stamp`, e.g. to the
/// label's member index, so the scratch is sized by the cluster, not V). reached(from, v) runs
/// when v is first reached from `from`; it may relabel v. O(Σ degree of the reached vertices ·
/// cost of slot).
template <class Slot, class Reached>
void flood_label(const MeshView& mesh, std::span<const int32_t> labels, int32_t label, std::span<const uint32_t> sources,
                 const Slot& slot, std::span<uint32_t> stamp, uint32_t mark, std::vector<uint32_t>& queue,
                 const Reached& reached) {
  queue.assign(sources.begin(), sources.end());
  for (uint32_t s : sources) stamp[slot(s)] = mark;
  for (size_t h = 0; h < queue.size(); ++h) {
    const uint32_t u = queue[h];
    for (uint32_t n : mesh.neighbours(u))
      if (labels[n] == label) {
        uint32_t& st = stamp[slot(n)];
        if (st == mark) continue;
        st = mark;
        reached(u, n);
        queue.push_back(n);
      }
  }
}

}  // namespace streamcvd
