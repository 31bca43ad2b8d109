#include "core/repair.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <numeric>

namespace streamcvd {

namespace {

// Multi-source BFS inside cluster `c` from `sources`; returns the last vertex reached, the
// member farthest (in hops) from every source: the next farthest-point seed.
uint32_t farthest_in_cluster(const MeshView& mesh, std::span<const int32_t> labels, int32_t c,
                             std::span<const uint32_t> sources, std::vector<uint32_t>& queue,
                             std::vector<uint32_t>& stamp, uint32_t mark) {
  queue.assign(sources.begin(), sources.end());
  for (uint32_t s : sources) stamp[s] = mark;
  for (size_t h = 0; h < queue.size(); ++h)
    for (uint32_t n : mesh.neighbours(queue[h]))
      if (labels[n] == c && stamp[n] != mark) {
        stamp[n] = mark;
        queue.push_back(n);
      }
  return queue.back();
}

}  // namespace

uint32_t split_cluster(const MeshView& mesh, std::span<int32_t> labels, std::span<const uint32_t> members,
                       std::span<const int32_t> new_labels, SplitScratch& scratch) {
  if (members.size() < 2 || new_labels.empty()) return 0;
  const int32_t c = labels[members[0]];
  if (scratch.stamp.size() != mesh.vertex_count()) scratch.stamp.assign(mesh.vertex_count(), 0);
  std::vector<uint32_t>& stamp = scratch.stamp;
  std::vector<uint32_t> queue;
  // Farthest-point seeds: the first is far from an arbitrary member, each next one is the
  // member farthest from all seeds chosen so far.
  std::vector<uint32_t> seeds;
  const uint32_t first = members[0];
  seeds.push_back(farthest_in_cluster(mesh, labels, c, {&first, 1}, queue, stamp, scratch.next_mark++));
  while (seeds.size() < new_labels.size() + 1 && seeds.size() < members.size()) {
    uint32_t s = farthest_in_cluster(mesh, labels, c, seeds, queue, stamp, scratch.next_mark++);
    if (std::find(seeds.begin(), seeds.end(), s) != seeds.end()) break;
    seeds.push_back(s);
  }
  if (seeds.size() < 2) return 0;
  // Multi-source BFS: each member joins the seed that reaches it first; every part connected.
  const uint32_t mark = scratch.next_mark++;
  std::vector<uint32_t> frontier = seeds;
  for (size_t k = 0; k < seeds.size(); ++k) {
    stamp[seeds[k]] = mark;
    if (k > 0) labels[seeds[k]] = new_labels[k - 1];
  }
  for (size_t h = 0; h < frontier.size(); ++h) {
    uint32_t u = frontier[h];
    for (uint32_t n : mesh.neighbours(u))
      if (labels[n] == c && stamp[n] != mark) {
        stamp[n] = mark;
        labels[n] = labels[u];
        frontier.push_back(n);
      }
  }
  return uint32_t(seeds.size() - 1);
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
  // A defective cluster is cut in two (measured: cutting in three fixed no more dragon defects
  // and lost genus on fertility at N = 200 more often).
  constexpr size_t kParts = 2;
  auto ids_needed = [&] {
    size_t n = 0;
    for (int32_t c : to_split) n += std::min(kParts, members_of(c).size()) - 1;
    return n;
  };
  if (ids_needed() > free_ids.size()) {
    // Merge light adjacent pairs away from every defect: the lightest eligible clusters (a few
    // times as many as needed, found in O(K)) propose their lightest neighbour; proposals are
    // taken lightest pair first. Only the candidates' own vertices are scanned.
    const size_t needed = ids_needed() - free_ids.size();
    std::vector<int32_t> candidates;
    for (uint32_t c = 0; c < K; ++c)
      if (!near[c] && adjustable[c] && members_of(int32_t(c)).size() > 0) candidates.push_back(int32_t(c));
    const size_t keep = std::min(candidates.size(), 8 * needed + 16);
    auto lighter = [&](int32_t x, int32_t y) { return weight[x] != weight[y] ? weight[x] < weight[y] : x < y; };
    std::nth_element(candidates.begin(), candidates.begin() + keep, candidates.end(), lighter);
    candidates.resize(keep);
    std::vector<int32_t> partner(K, -1);
    for (int32_t a : candidates)
      for (uint32_t v : members_of(a))
        for (uint32_t n : mesh.neighbours(v)) {
          int32_t b = labels[n];
          if (b < 0 || b == a || near[b] || !adjustable[b]) continue;
          if (partner[a] < 0 || lighter(b, partner[a])) partner[a] = b;
        }
    std::vector<int32_t> proposers;
    for (int32_t a : candidates)
      if (partner[a] >= 0) proposers.push_back(a);
    auto pair_weight = [&](int32_t a) { return weight[a] + weight[partner[a]]; };
    std::stable_sort(proposers.begin(), proposers.end(),
                     [&](int32_t x, int32_t y) { return pair_weight(x) < pair_weight(y); });
    std::vector<uint8_t> used(K, 0);
    for (int32_t a : proposers) {
      if (ids_needed() <= free_ids.size()) break;
      int32_t b = partner[a];
      if (used[a] || used[b]) continue;
      used[a] = used[b] = 1;
      for (uint32_t v : members_of(b)) labels[v] = a;
      free_ids.push_back(b);
      touched.push_back(a);
      ++stats.merges;
    }
    while (!to_split.empty() && ids_needed() > free_ids.size()) to_split.pop_back();
  }
  for (int32_t c : to_split) {
    size_t parts = std::min(kParts, members_of(c).size());
    std::vector<int32_t> ids(free_ids.end() - std::ptrdiff_t(parts - 1), free_ids.end());
    uint32_t made = split_cluster(mesh, labels, members_of(c), ids, scratch);
    if (made == 0) continue;
    touched.push_back(c);
    for (uint32_t k = 0; k < made; ++k) touched.push_back(ids[k]);
    // Ids the split could not use (too few far-apart members) stay free.
    free_ids.resize(free_ids.size() - (parts - 1));
    for (uint32_t k = made; k < parts - 1; ++k) free_ids.push_back(ids[k]);
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
      if (split_cluster(mesh, labels, members_of(c), {&id, 1}, scratch) == 0) continue;
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

namespace streamcvd {

namespace {

using Triple = std::array<uint32_t, 3>;

inline Triple rotate_smallest_first(uint32_t a, uint32_t b, uint32_t c) {
  if (a < b && a < c) return {a, b, c};
  if (b < a && b < c) return {b, c, a};
  return {c, a, b};
}

// True when the faces around vertex x (distinct oriented triples, each holding x) are not a
// manifold neighbourhood: an edge at x in more than two faces or twice in one direction, faces
// in more than one fan, or two faces on one vertex set. The same tests as
// find_manifold_defects, restricted to the edges at x (a vertex's corners only join through
// its own edges).
bool vertex_defective(uint32_t x, std::span<const Triple> faces, std::vector<std::array<uint32_t, 3>>& entries,
                      std::vector<uint32_t>& parent, std::vector<Triple>& sets) {
  entries.clear();  // {neighbour, outgoing?, face}
  for (uint32_t i = 0; i < faces.size(); ++i) {
    const Triple& t = faces[i];
    const int k = t[0] == x ? 0 : t[1] == x ? 1 : 2;
    entries.push_back({t[(k + 1) % 3], 1, i});  // x → next
    entries.push_back({t[(k + 2) % 3], 0, i});  // previous → x
  }
  std::sort(entries.begin(), entries.end());
  parent.resize(faces.size());
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](uint32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  uint32_t fans = uint32_t(faces.size());
  for (size_t i = 0; i < entries.size();) {
    size_t j = i;
    uint32_t out = 0;
    while (j < entries.size() && entries[j][0] == entries[i][0]) out += entries[j++][1];
    const size_t n = j - i, in = n - out;
    if (n > 2 || out == 2 || in == 2) return true;
    if (n == 2) {
      uint32_t a = find(entries[i][2]), b = find(entries[i + 1][2]);
      if (a != b) {
        parent[a] = b;
        --fans;
      }
    }
    i = j;
  }
  if (fans != 1) return true;
  sets.assign(faces.begin(), faces.end());
  for (Triple& t : sets) std::sort(t.begin(), t.end());
  std::sort(sets.begin(), sets.end());
  return std::adjacent_find(sets.begin(), sets.end()) != sets.end();
}

// Labels-only defect finder on the dual of a clustering that changes a little at a time.
// A dual vertex's defect status depends only on the faces around it, and a dual face changes
// only when a corner of its input triangle changes label: after a change, only the clusters
// on the changed vertices' 1-rings (and on boundary loops that changed) are re-checked.
class DefectTracker {
 public:
  DefectTracker(const MeshView& mesh, const BoundaryLoops& loops, uint32_t K, const DualMeshOptions& options)
      : mesh_(mesh), loops_(loops), K_(K), strips_(options.boundary_strips), options_(options), defective_(K, 0), in_set_(K, 0) {}

  // Checks every cluster. Returns the clusters on and around defects.
  std::vector<int32_t> check_all(std::span<const int32_t> labels) {
    std::fill(in_set_.begin(), in_set_.end(), 1);
    prev_.assign(labels.begin(), labels.end());
    all_ = true;
    std::vector<int32_t> bad = check(labels);
    all_ = false;
    return bad;
  }

  // Re-checks the clusters whose faces may differ from the last check.
  std::vector<int32_t> check_changes(std::span<const int32_t> labels) {
    std::fill(in_set_.begin(), in_set_.end(), 0);
    for (uint32_t c = 0; c < K_; ++c) in_set_[c] = defective_[c];
    auto mark = [&](int32_t l) {
      if (l >= 0) in_set_[l] = 1;
    };
    const uint32_t V = mesh_.vertex_count();
    for (uint32_t v = 0; v < V; ++v) {
      if (prev_[v] == labels[v]) continue;
      mark(prev_[v]);
      mark(labels[v]);
      for (uint32_t n : mesh_.neighbours(v)) {
        mark(prev_[n]);
        mark(labels[n]);
      }
    }
    if (strips_)
      for (size_t l = 0; l + 1 < loops_.offsets.size(); ++l) {
        std::span<const uint32_t> loop(loops_.vertices.data() + loops_.offsets[l], loops_.offsets[l + 1] - loops_.offsets[l]);
        bool changed = false;
        for (uint32_t v : loop) changed |= prev_[v] != labels[v];
        if (changed)
          for (uint32_t v : loop) {
            mark(prev_[v]);
            mark(labels[v]);
          }
      }
    std::copy(labels.begin(), labels.end(), prev_.begin());
    return check(labels);
  }

  uint64_t defect_vertices() const { return defect_vertices_; }

 private:
  std::vector<int32_t> check(std::span<const int32_t> labels) {
    const uint32_t V = mesh_.vertex_count();
    std::vector<uint32_t> size(K_, 0);
    for (int32_t l : labels)
      if (l >= 0) ++size[l];
    // Dual faces with a corner in the set, each once (from its first corner in the set).
    std::vector<Triple> faces;
    const uint32_t* T = mesh_.triangles.data();
    if (all_) {  // every face once, in face order
      for (uint64_t f = 0; f < mesh_.face_count(); ++f) {
        const int32_t a = labels[T[3 * f]], b = labels[T[3 * f + 1]], c = labels[T[3 * f + 2]];
        if (a < 0 || b < 0 || c < 0 || a == b || b == c || a == c) continue;
        faces.push_back(rotate_smallest_first(uint32_t(a), uint32_t(b), uint32_t(c)));
      }
    }
    for (uint32_t v = 0; v < V && !all_; ++v) {
      const int32_t lv = labels[v];
      if (lv < 0 || !in_set_[lv]) continue;
      for (uint32_t f : mesh_.faces_of(v)) {
        const uint32_t* t = T + 3 * size_t(f);
        const int32_t a = labels[t[0]], b = labels[t[1]], c = labels[t[2]];
        if (a < 0 || b < 0 || c < 0 || a == b || b == c || a == c) continue;
        const int first = in_set_[a] ? 0 : in_set_[b] ? 1 : 2;
        if (t[first] != v) continue;
        faces.push_back(rotate_smallest_first(uint32_t(a), uint32_t(b), uint32_t(c)));
      }
    }
    uint32_t strip_vertices = 0;
    if (strips_) {
      std::vector<Triple> strip = boundary_strip_faces(mesh_, loops_, labels, K_, size, options_, strip_vertices);
      faces.insert(faces.end(), strip.begin(), strip.end());
    }
    std::sort(faces.begin(), faces.end());
    faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
    // Faces around each checked vertex (clusters in the set, every strip vertex).
    std::vector<std::pair<uint32_t, uint32_t>> around;  // {vertex, face}
    for (uint32_t i = 0; i < faces.size(); ++i)
      for (uint32_t x : faces[i])
        if (x >= K_ || in_set_[x]) around.push_back({x, i});
    std::sort(around.begin(), around.end());
    std::vector<int32_t> bad;
    std::vector<Triple> fan, sets;
    std::vector<std::array<uint32_t, 3>> entries;
    std::vector<uint32_t> parent;
    std::vector<uint8_t> has_faces(K_, 0);
    defect_vertices_ = 0;
    for (uint32_t c = 0; c < K_; ++c)
      if (in_set_[c]) defective_[c] = 0;
    for (size_t i = 0; i < around.size();) {
      size_t j = i;
      fan.clear();
      while (j < around.size() && around[j].first == around[i].first) fan.push_back(faces[around[j++].second]);
      const uint32_t x = around[i].first;
      if (x < K_) has_faces[x] = 1;
      if (vertex_defective(x, fan, entries, parent, sets)) {
        ++defect_vertices_;
        if (x < K_) defective_[x] = 1;
        for (const Triple& t : fan)
          for (uint32_t y : t)
            if (y < K_) bad.push_back(int32_t(y));
      }
      i = j;
    }
    for (uint32_t c = 0; c < K_; ++c)
      if (in_set_[c] && size[c] > 0 && !has_faces[c]) {  // a cluster on no dual face
        defective_[c] = 1;
        ++defect_vertices_;
        bad.push_back(int32_t(c));
      }
    std::sort(bad.begin(), bad.end());
    bad.erase(std::unique(bad.begin(), bad.end()), bad.end());
    return bad;
  }

  const MeshView& mesh_;
  const BoundaryLoops& loops_;
  const uint32_t K_;
  const bool strips_;
  const DualMeshOptions options_;
  std::vector<uint8_t> defective_, in_set_;
  std::vector<int32_t> prev_;
  uint64_t defect_vertices_ = 0;
  bool all_ = false;
};

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

DefectRepairResult repair_dual_defects(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                                       uint32_t cluster_count, std::span<const uint8_t> adjustable,
                                       const BoundaryLoops& loops, const DefectRepairOptions& options,
                                       ClusteringReport& report) {
  const uint32_t K = cluster_count;
  const uint32_t V = mesh.vertex_count();
  DefectRepairResult result;
  result.touched.assign(K, 0);
  auto t = std::chrono::steady_clock::now();
  DefectTracker tracker(mesh, loops, K, options.dual);
  std::vector<int32_t> bad = tracker.check_all(labels);
  result.check_seconds += seconds_since(t);
  // Vertices of the clusters repaired around a defect, and of their neighbours: the region the
  // final relaxation leaves alone (relaxing it tends to rebuild the thin-feature clusters).
  std::vector<uint8_t> near_defect(V, 0);
  std::vector<uint8_t> is_bad(K, 0);
  while (!bad.empty() && result.rounds < options.max_rounds) {
    t = std::chrono::steady_clock::now();
    for (int32_t c : bad) is_bad[c] = 1;
    for (uint32_t v = 0; v < V; ++v)
      if (labels[v] >= 0 && is_bad[labels[v]]) {
        near_defect[v] = 1;
        for (uint32_t n : mesh.neighbours(v)) near_defect[n] = 1;
      }
    for (int32_t c : bad) is_bad[c] = 0;
    RepairRoundStats stats;
    const std::vector<int32_t> touched = repair_clusters(mesh, items, labels, K, bad, adjustable, stats);
    for (int32_t c : touched) result.touched[c] = 1;
    result.repaired_clusters += touched.size();
    result.splits += stats.splits;
    result.merges += stats.merges;
    result.islands += stats.dissolved_islands;
    ++result.rounds;
    result.repair_seconds += seconds_since(t);
    t = std::chrono::steady_clock::now();
    bad = tracker.check_changes(labels);
    result.check_seconds += seconds_since(t);
  }
  result.defect_vertices = tracker.defect_vertices();
  if (!bad.empty() || result.rounds == 0 || !options.relax) return result;
  // The repair leaves split halves and merged pairs unrelaxed. Relax the touched clusters once
  // (constrained) with the clusters around the repaired defects frozen (their vertices hidden
  // as free, so nothing moves into or out of them): relaxing those rebuilds the thin-feature
  // clusters (measured on the dragon: an unfrozen relaxation always brought defects back).
  // The relaxation is kept only when the dual stays defect-free.
  t = std::chrono::steady_clock::now();
  const std::vector<int32_t> before(labels.begin(), labels.end());
  std::vector<uint8_t> active = result.touched;
  // Whole clusters are frozen, so the 1-ring connectivity test stays exact for the others.
  std::vector<uint8_t> frozen(K, 0);
  for (uint32_t v = 0; v < V; ++v)
    if (near_defect[v] && labels[v] >= 0) frozen[labels[v]] = 1;
  for (uint32_t v = 0; v < V; ++v)
    if (labels[v] >= 0 && frozen[labels[v]]) {
      active[labels[v]] = 0;
      labels[v] = -1;
    }
  ClusterState state = make_cluster_state(items, labels, K, options.clustering.metric, options.clustering.qem_threshold);
  update_site_offsets(state);
  LoopOptions relax = loop_options(options.clustering);
  relax.constrained = true;
  relax.stop_fraction = 0.0;
  relax.on_loop = {};
  run_clustering_loops(mesh, items, labels, state, relax, report, active);
  for (uint32_t v = 0; v < V; ++v)
    if (before[v] >= 0 && frozen[before[v]]) labels[v] = before[v];
  if (tracker.check_changes(labels).empty()) {
    result.relaxed = true;
  } else {
    std::copy(before.begin(), before.end(), labels.begin());
    tracker.check_changes(labels);
  }
  result.defect_vertices = tracker.defect_vertices();
  result.repair_seconds += seconds_since(t);
  return result;
}

}  // namespace streamcvd
