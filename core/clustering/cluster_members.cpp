// Cluster → vertices index (core/clustering/cluster_members.h).
#include "streamcvd/core/clustering/cluster_members.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <stdexcept>
#include <string>

#include "streamcvd/core/mesh/chunked_components.h"

namespace streamcvd {

ClusterMembers::ClusterMembers(const MeshView& mesh, std::span<const int32_t> labels, uint32_t cluster_count,
                               ArrayStorage& storage)
    : mesh_(mesh), labels_(labels), storage_(storage), size_(cluster_count, 0) {
  if (labels.size() != mesh.vertex_count())
    throw std::invalid_argument("ClusterMembers: " + std::to_string(labels.size()) + " labels for " +
                                std::to_string(mesh.vertex_count()) + " vertices");
  vertices_ = LargeArray<uint32_t>(labels.size(), storage_, "cluster members");
  rebuilds_ = 0;
  rebuild();
  rebuilds_ = 0;
}

void ClusterMembers::rebuild() {
  ++rebuilds_;
  const uint32_t K = cluster_count();
  joined_.clear();
  joined_total_ = 0;
  // A stable counting sort over runs of chunks (one count array per run): each cluster's
  // vertices come out ascending whatever the number of runs.
  const std::vector<VertexRange> ranges = chunk_vertex_blocks(mesh_);
  const uint32_t parts = uint32_t(std::clamp<size_t>(size_t(std::min(tbb::this_task_arena::max_concurrency(), 8)), 1,
                                                     std::max<size_t>(ranges.size(), 1)));
  const uint64_t V = labels_.size();
  std::vector<size_t> first_range(parts + 1, ranges.size());  // part p: ranges [first_range[p], first_range[p+1])
  for (uint32_t p = 0, r = 0; p < parts; ++p) {
    while (r < ranges.size() && ranges[r].begin < V * p / parts) ++r;
    first_range[p] = r;
  }
  std::vector<std::vector<uint32_t>> cursor(parts);
  tbb::parallel_for(uint32_t(0), parts, [&](uint32_t p) {
    cursor[p].assign(K, 0);
    for (size_t r = first_range[p]; r < first_range[p + 1]; ++r)
      for (uint32_t v = ranges[r].begin; v < ranges[r].end; ++v)
        if (labels_[v] >= 0) ++cursor[p][labels_[v]];
  });
  offsets_.assign(size_t(K) + 1, 0);
  for (uint32_t c = 0; c < K; ++c) {
    uint32_t at = offsets_[c];
    for (uint32_t p = 0; p < parts; ++p) at += std::exchange(cursor[p][c], at);
    offsets_[c + 1] = at;
    size_[c] = at - offsets_[c];
  }
  tbb::parallel_for(uint32_t(0), parts, [&](uint32_t p) {
    uint32_t* at = cursor[p].data();
    for (size_t r = first_range[p]; r < first_range[p + 1]; ++r)
      for (uint32_t v = ranges[r].begin; v < ranges[r].end; ++v)
        if (labels_[v] >= 0) vertices_[at[labels_[v]]++] = v;
  });
}

void ClusterMembers::moved(uint32_t v, int32_t from, int32_t to) {
  if (from == to) return;
  if (from >= 0) --size_[size_t(from)];
  if (to >= 0) {
    ++size_[size_t(to)];
    joined_[to].push_back(v);
    ++joined_total_;
  }
}

void ClusterMembers::compact() {
  if (joined_total_ > labels_.size() / 16) rebuild();
}

void ClusterMembers::members(int32_t c, std::vector<uint32_t>& out) const {
  out.clear();
  for (uint32_t i = offsets_[size_t(c)]; i < offsets_[size_t(c) + 1]; ++i)
    if (labels_[vertices_[i]] == c) out.push_back(vertices_[i]);
  if (auto it = joined_.find(c); it != joined_.end()) {
    for (uint32_t v : it->second)
      if (labels_[v] == c) out.push_back(v);
    std::sort(out.begin(), out.end());
    out.erase(std::unique(out.begin(), out.end()), out.end());
  }
  if (out.size() != size_[size_t(c)])
    throw std::logic_error("ClusterMembers: cluster " + std::to_string(c) + " has " + std::to_string(out.size()) +
                           " vertices labelled with it, " + std::to_string(size_[size_t(c)]) + " recorded");
}

}  // namespace streamcvd
