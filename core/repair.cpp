#include "core/repair.h"

#include <algorithm>
#include <numeric>

namespace streamcvd {

namespace {

// BFS inside one cluster from `source`; returns the last vertex reached (a far-away vertex).
uint32_t farthest_in_cluster(const MeshView& mesh, std::span<const int32_t> labels, uint32_t source,
                             std::vector<uint32_t>& queue, std::vector<uint32_t>& stamp, uint32_t mark) {
  const int32_t c = labels[source];
  queue.assign(1, source);
  stamp[source] = mark;
  for (size_t h = 0; h < queue.size(); ++h)
    for (uint32_t n : mesh.neighbours(queue[h]))
      if (labels[n] == c && stamp[n] != mark) {
        stamp[n] = mark;
        queue.push_back(n);
      }
  return queue.back();
}

}  // namespace

bool split_cluster(const MeshView& mesh, std::span<int32_t> labels, std::span<const uint32_t> members,
                   int32_t new_label, SplitScratch& scratch) {
  if (members.size() < 2) return false;
  const int32_t c = labels[members[0]];
  if (scratch.stamp.size() != mesh.vertex_count()) scratch.stamp.assign(mesh.vertex_count(), 0);
  std::vector<uint32_t>& stamp = scratch.stamp;
  const uint32_t mark = scratch.next_mark;
  scratch.next_mark += 3;
  std::vector<uint32_t> queue;
  uint32_t s1 = farthest_in_cluster(mesh, labels, members[0], queue, stamp, mark);
  uint32_t s2 = farthest_in_cluster(mesh, labels, s1, queue, stamp, mark + 1);
  if (s1 == s2) return false;
  // Two-source BFS: each member joins the seed that reaches it first; both halves connected.
  std::vector<uint32_t> frontier = {s1, s2};
  stamp[s1] = mark + 2;
  stamp[s2] = mark + 2;
  labels[s2] = new_label;
  for (size_t h = 0; h < frontier.size(); ++h) {
    uint32_t u = frontier[h];
    for (uint32_t n : mesh.neighbours(u))
      if (labels[n] == c && stamp[n] != mark + 2) {
        stamp[n] = mark + 2;
        labels[n] = labels[u];
        frontier.push_back(n);
      }
  }
  return true;
}

std::vector<int32_t> repair_clusters(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                                     uint32_t cluster_count, std::span<const int32_t> defect_clusters,
                                     std::span<const uint8_t> adjustable, RepairRoundStats& stats) {
  const uint32_t V = mesh.vertex_count();
  const uint32_t K = cluster_count;
  std::vector<uint8_t> is_defect(K, 0);
  for (int32_t c : defect_clusters)
    if (c >= 0 && uint32_t(c) < K) is_defect[c] = 1;
  // Members of every cluster (CSR by label), weights, boundary contact.
  std::vector<uint32_t> member_offsets(K + 1, 0);
  std::vector<double> weight(K, 0.0);
  std::vector<uint8_t> touches_boundary(K, 0);
  for (uint32_t v = 0; v < V; ++v)
    if (labels[v] >= 0) {
      ++member_offsets[labels[v] + 1];
      weight[labels[v]] += items.weight[v];
      if (mesh.vertex_flags[v] & kVertexBoundary) touches_boundary[labels[v]] = 1;
    }
  std::partial_sum(member_offsets.begin(), member_offsets.end(), member_offsets.begin());
  std::vector<uint32_t> members(member_offsets[K]);
  {
    std::vector<uint32_t> fill(member_offsets.begin(), member_offsets.end() - 1);
    for (uint32_t v = 0; v < V; ++v)
      if (labels[v] >= 0) members[fill[labels[v]]++] = v;
  }
  auto members_of = [&](int32_t c) {
    return std::span<const uint32_t>(members.data() + member_offsets[c], member_offsets[c + 1] - member_offsets[c]);
  };
  // Neighbour clusters of the defect clusters; "near" marks defects and their neighbours,
  // where no compensating merge may happen.
  std::vector<uint8_t> near(K, 0);
  std::vector<std::vector<int32_t>> neighbours_of_defect(K);
  for (uint32_t c = 0; c < K; ++c) {
    if (!is_defect[c]) continue;
    near[c] = 1;
    auto& list = neighbours_of_defect[c];
    for (uint32_t v : members_of(int32_t(c)))
      for (uint32_t n : mesh.neighbours(v))
        if (labels[n] >= 0 && labels[n] != int32_t(c)) list.push_back(labels[n]);
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
    for (int32_t n : list) near[n] = 1;
  }
  SplitScratch scratch;
  std::vector<int32_t> touched;
  std::vector<int32_t> free_ids;    // ids released by dissolved islands and merges
  std::vector<int32_t> to_split;
  for (uint32_t c = 0; c < K; ++c) {
    if (!is_defect[c]) continue;
    const auto& list = neighbours_of_defect[c];
    if (list.size() == 1 && !touches_boundary[c] && !is_defect[list[0]]) {
      // An island: its surrounding cluster takes it whole (stays connected: it encloses it).
      for (uint32_t v : members_of(int32_t(c))) labels[v] = list[0];
      free_ids.push_back(int32_t(c));
      touched.push_back(list[0]);
      ++stats.dissolved_islands;
    } else if (members_of(int32_t(c)).size() >= 2) {
      to_split.push_back(int32_t(c));
    }
  }
  // Compensate so that the number of non-empty clusters stays K.
  if (to_split.size() > free_ids.size()) {
    // Merge light adjacent pairs away from every defect: each cluster proposes its lightest
    // neighbour, proposals are taken lightest first (O(E) scan + O(K log K) sort).
    std::vector<int32_t> partner(K, -1);
    for (uint32_t v = 0; v < V; ++v) {
      int32_t a = labels[v];
      if (a < 0 || near[a] || !adjustable[a]) continue;
      for (uint32_t n : mesh.neighbours(v)) {
        int32_t b = labels[n];
        if (b < 0 || b == a || near[b] || !adjustable[b]) continue;
        if (partner[a] < 0 || weight[b] < weight[partner[a]] || (weight[b] == weight[partner[a]] && b < partner[a]))
          partner[a] = b;
      }
    }
    std::vector<int32_t> proposers;
    for (uint32_t a = 0; a < K; ++a)
      if (partner[a] >= 0) proposers.push_back(int32_t(a));
    auto pair_weight = [&](int32_t a) { return weight[a] + weight[partner[a]]; };
    std::stable_sort(proposers.begin(), proposers.end(),
                     [&](int32_t x, int32_t y) { return pair_weight(x) < pair_weight(y); });
    std::vector<uint8_t> used(K, 0);
    for (int32_t a : proposers) {
      if (to_split.size() <= free_ids.size()) break;
      int32_t b = partner[a];
      if (used[a] || used[b]) continue;
      used[a] = used[b] = 1;
      for (uint32_t v : members_of(b)) labels[v] = a;
      free_ids.push_back(b);
      touched.push_back(a);
      ++stats.merges;
    }
    to_split.resize(std::min(to_split.size(), free_ids.size()));
  }
  for (int32_t c : to_split) {
    int32_t id = free_ids.back();
    if (!split_cluster(mesh, labels, members_of(c), id, scratch)) continue;
    free_ids.pop_back();
    touched.push_back(c);
    touched.push_back(id);
    ++stats.splits;
  }
  // Ids still free (more islands than splits): split the heaviest clusters.
  if (!free_ids.empty()) {
    std::vector<int32_t> order(K);
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](int32_t x, int32_t y) { return weight[x] > weight[y]; });
    for (int32_t c : order) {
      if (free_ids.empty()) break;
      if (near[c] || !adjustable[c] || members_of(c).size() < 2) continue;
      // Members recorded before merges: only clusters untouched this round are split here.
      if (std::find(touched.begin(), touched.end(), c) != touched.end()) continue;
      int32_t id = free_ids.back();
      if (!split_cluster(mesh, labels, members_of(c), id, scratch)) continue;
      free_ids.pop_back();
      touched.push_back(c);
      touched.push_back(id);
      ++stats.splits;
    }
  }
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  return touched;
}

}  // namespace streamcvd
