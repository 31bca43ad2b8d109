// The repair loop (core/dual/repair.h) with K-sized state. The vertices of the clusters a round
// touches come from a cluster → vertices index (core/clustering/cluster_members.h) built once; every label
// the repair writes goes through a change log of (vertex, old label), which updates the index
// and tells the defect tracker where the dual may have changed. The tracker re-checks only the
// dual around the changed clusters, with the dual triples and the fan test of
// core/dual/dual_topology.h (the ones build_dual_mesh and find_manifold_defects use). Per round:
// O(vertices of the touched clusters + their faces) plus a few O(K) scans of byte and weight
// arrays (candidates of the compensating merges) and O(boundary) for the strips; never O(V).
#include "streamcvd/core/dual/repair.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <numeric>
#include <unordered_map>

#include "streamcvd/core/clustering/cluster_members.h"
#include "streamcvd/core/dual/dual_topology.h"
#include "streamcvd/core/mesh/timer.h"

namespace streamcvd {

namespace {

// Position of vertex v in the ascending member list of its cluster.
inline uint32_t slot_of(std::span<const uint32_t> members, uint32_t v) {
  return uint32_t(std::lower_bound(members.begin(), members.end(), v) - members.begin());
}

// Multi-source BFS inside cluster `c` (whose members are `members`) from `sources`; returns the
// last vertex reached, the member farthest (in hops) from every source: the next
// farthest-point seed.
uint32_t farthest_in_cluster(const MeshView& mesh, std::span<const int32_t> labels, int32_t c,
                             std::span<const uint32_t> members, std::span<const uint32_t> sources,
                             std::vector<uint32_t>& queue, std::vector<uint32_t>& stamp, uint32_t mark) {
  queue.assign(sources.begin(), sources.end());
  for (uint32_t s : sources) stamp[slot_of(members, s)] = mark;
  for (size_t h = 0; h < queue.size(); ++h)
    for (uint32_t n : mesh.neighbours(queue[h]))
      if (labels[n] == c) {
        uint32_t& st = stamp[slot_of(members, n)];
        if (st == mark) continue;
        st = mark;
        queue.push_back(n);
      }
  return queue.back();
}

}  // namespace

uint32_t split_cluster(const MeshView& mesh, std::span<int32_t> labels, std::span<const uint32_t> members,
                       std::span<const int32_t> new_labels, SplitScratch& scratch) {
  if (members.size() < 2 || new_labels.empty()) return 0;
  const int32_t c = labels[members[0]];
  scratch.stamp.assign(members.size(), 0);
  scratch.next_mark = 1;
  std::vector<uint32_t>& stamp = scratch.stamp;
  std::vector<uint32_t>& queue = scratch.queue;
  // Farthest-point seeds: the first is far from an arbitrary member, each next one is the
  // member farthest from all seeds chosen so far.
  std::vector<uint32_t> seeds;
  const uint32_t first = members[0];
  seeds.push_back(farthest_in_cluster(mesh, labels, c, members, {&first, 1}, queue, stamp, scratch.next_mark++));
  while (seeds.size() < new_labels.size() + 1 && seeds.size() < members.size()) {
    uint32_t s = farthest_in_cluster(mesh, labels, c, members, seeds, queue, stamp, scratch.next_mark++);
    if (std::find(seeds.begin(), seeds.end(), s) != seeds.end()) break;
    seeds.push_back(s);
  }
  if (seeds.size() < 2) return 0;
  // Multi-source BFS: each member joins the seed that reaches it first; every part connected.
  const uint32_t mark = scratch.next_mark++;
  std::vector<uint32_t>& frontier = queue;
  frontier = seeds;
  for (size_t k = 0; k < seeds.size(); ++k) {
    stamp[slot_of(members, seeds[k])] = mark;
    if (k > 0) labels[seeds[k]] = new_labels[k - 1];
  }
  for (size_t h = 0; h < frontier.size(); ++h) {
    uint32_t u = frontier[h];
    for (uint32_t n : mesh.neighbours(u))
      if (labels[n] == c) {
        uint32_t& st = stamp[slot_of(members, n)];
        if (st == mark) continue;
        st = mark;
        labels[n] = labels[u];
        frontier.push_back(n);
      }
  }
  return uint32_t(seeds.size() - 1);
}

namespace {

using Triple = dual::Face;

struct LabelChange {
  uint32_t vertex;
  int32_t old_label;
};

// Every label the repair writes: the labels themselves, the cluster → vertices index, the log
// of (vertex, old label) since the last check, and the clusters whose members changed since
// their per-cluster figures were last refreshed.
class LabelEditor {
 public:
  LabelEditor(const MeshView& mesh, std::span<int32_t> labels, uint32_t K, ArrayStorage& storage)
      : labels_(labels), members_(mesh, labels, K, storage), stale_(K, 0) {}

  std::span<int32_t> labels() { return labels_; }
  int32_t operator[](uint32_t v) const { return labels_[v]; }
  const ClusterMembers& index() const { return members_; }
  ClusterMembers& index() { return members_; }

  void set(uint32_t v, int32_t label) {
    const int32_t old = labels_[v];
    if (old == label) return;
    labels_[v] = label;
    note(v, old);
  }
  // labels[v] was written by someone else (a split, the relaxation); `old` was its label.
  void note(uint32_t v, int32_t old) {
    const int32_t now = labels_[v];
    if (old == now) return;
    log_.push_back({v, old});
    members_.moved(v, old, now);
    mark_stale(old);
    mark_stale(now);
  }
  std::vector<LabelChange> take_log() { return std::exchange(log_, {}); }
  std::vector<int32_t> take_stale() {
    for (int32_t c : stale_list_) stale_[c] = 0;
    return std::exchange(stale_list_, {});
  }

 private:
  void mark_stale(int32_t c) {
    if (c >= 0 && !stale_[c]) {
      stale_[c] = 1;
      stale_list_.push_back(c);
    }
  }

  std::span<int32_t> labels_;
  ClusterMembers members_;
  std::vector<LabelChange> log_;
  std::vector<uint8_t> stale_;
  std::vector<int32_t> stale_list_;
};

// A K-sized flag set that lists its members, so that clearing costs what was set.
class ClusterSet {
 public:
  explicit ClusterSet(uint32_t K) : in_(K, 0) {}
  bool insert(int32_t c) {
    if (c < 0 || in_[c]) return false;
    in_[c] = 1;
    list_.push_back(c);
    return true;
  }
  bool contains(int32_t c) const { return in_[c] != 0; }
  const std::vector<int32_t>& list() const { return list_; }
  std::span<const uint8_t> flags() const { return in_; }
  void clear() {
    for (int32_t c : list_) in_[c] = 0;
    list_.clear();
  }

 private:
  std::vector<uint8_t> in_;
  std::vector<int32_t> list_;
};

// Labels-only defect finder on the dual of a clustering that changes a little at a time.
// A dual vertex's defect status depends only on the faces around it, and a dual face changes
// only when a corner of its input triangle changes label: after a change, only the clusters
// on the changed vertices' 1-rings (and on boundary loops that changed) are re-checked.
class DefectTracker {
 public:
  DefectTracker(const MeshView& mesh, const BoundaryLoops& loops, uint32_t K, const DualMeshOptions& options,
                const ClusterMembers& members)
      : mesh_(mesh), loops_(loops), K_(K), strips_(options.boundary_strips), options_(options), members_(members),
        set_(K), defective_(K, 0), has_faces_(K, 0) {
    if (strips_)
      for (uint32_t l = 0; l + 1 < loops.offsets.size(); ++l)
        for (uint32_t i = loops.offsets[l]; i < loops.offsets[l + 1]; ++i) loop_of_vertex_.push_back({loops.vertices[i], l});
    std::sort(loop_of_vertex_.begin(), loop_of_vertex_.end());
  }

  // Checks every cluster. Returns the clusters on and around defects.
  std::vector<int32_t> check_all(std::span<const int32_t> labels) {
    for (uint32_t c = 0; c < K_; ++c) set_.insert(int32_t(c));
    return check(labels, true);
  }

  // Re-checks the clusters whose faces may differ since the last check: `log` lists the label
  // changes since then, in order (a vertex may appear several times).
  std::vector<int32_t> check_changes(std::span<const int32_t> labels, std::vector<LabelChange> log) {
    // The label of each logged vertex at the last check: its first old label.
    std::stable_sort(log.begin(), log.end(), [](const LabelChange& a, const LabelChange& b) { return a.vertex < b.vertex; });
    log.erase(std::unique(log.begin(), log.end(), [](const LabelChange& a, const LabelChange& b) { return a.vertex == b.vertex; }),
              log.end());
    auto prev = [&](uint32_t v) {
      auto it = std::lower_bound(log.begin(), log.end(), v, [](const LabelChange& a, uint32_t x) { return a.vertex < x; });
      return it != log.end() && it->vertex == v ? it->old_label : labels[v];
    };
    for (int32_t c : defective_list_) set_.insert(c);
    std::vector<uint32_t> changed_loops;
    for (const LabelChange& ch : log) {
      const uint32_t v = ch.vertex;
      if (ch.old_label == labels[v]) continue;  // changed and changed back
      set_.insert(ch.old_label);
      set_.insert(labels[v]);
      for (uint32_t n : mesh_.neighbours(v)) {
        set_.insert(prev(n));
        set_.insert(labels[n]);
      }
      if (strips_ && (mesh_.vertex_flags[v] & kVertexBoundary)) {
        auto it = std::lower_bound(loop_of_vertex_.begin(), loop_of_vertex_.end(), std::pair<uint32_t, uint32_t>{v, 0});
        if (it != loop_of_vertex_.end() && it->first == v) changed_loops.push_back(it->second);
      }
    }
    std::sort(changed_loops.begin(), changed_loops.end());
    changed_loops.erase(std::unique(changed_loops.begin(), changed_loops.end()), changed_loops.end());
    for (uint32_t l : changed_loops)
      for (uint32_t i = loops_.offsets[l]; i < loops_.offsets[l + 1]; ++i) {
        set_.insert(prev(loops_.vertices[i]));
        set_.insert(labels[loops_.vertices[i]]);
      }
    return check(labels, false);
  }

  uint64_t defect_vertices() const { return defect_vertices_; }
  uint64_t unjoined_pairs() const { return unjoined_pairs_; }
  /// Strip vertices the dual of the last checked labels adds (0 without strips).
  uint32_t strip_vertices() const { return strip_vertices_; }

 private:
  std::vector<int32_t> check(std::span<const int32_t> labels, bool all) {
    std::span<const uint32_t> size = members_.sizes();
    // Dual faces with a corner in the set: every face when all clusters are in it.
    std::vector<Triple> faces;
    std::vector<uint64_t> neighbour_pairs;  // clusters meeting along an input edge, from the set
    if (all) {
      dual::Triples triples = dual::collect_triples(mesh_, labels, true);
      faces = std::move(triples.faces);
      neighbour_pairs = std::move(triples.neighbour_pairs);
    } else {
      std::vector<uint32_t> vertices;  // the set's members
      std::vector<uint32_t> members;
      for (int32_t c : set_.list()) {
        members_.members(c, members);
        vertices.insert(vertices.end(), members.begin(), members.end());
      }
      // In store order: out of core, the set's clusters lie all over the mesh (the merges of a
      // count round), and reading their faces in set order re-reads pages (the result is sorted).
      std::sort(vertices.begin(), vertices.end());
      faces = dual::triples_around(mesh_, labels, vertices, set_.flags());
      neighbour_pairs = dual::neighbour_pairs_around(mesh_, labels, vertices);
    }
    uint32_t strip_vertices = 0;
    if (strips_) {
      std::vector<Triple> strip = boundary_strip_faces(mesh_, loops_, labels, K_, size, options_, strip_vertices);
      std::sort(strip.begin(), strip.end());
      const size_t interior = faces.size();
      faces.insert(faces.end(), strip.begin(), strip.end());
      std::inplace_merge(faces.begin(), faces.begin() + std::ptrdiff_t(interior), faces.end());
      faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
    }
    // Verdicts for the clusters in the set and every strip vertex.
    const std::vector<dual::FanVerdict> verdicts =
        dual::check_fans(faces, [&](uint32_t x) { return x >= K_ || set_.contains(int32_t(x)); });
    for (int32_t c : defective_list_) defective_[c] = 0;
    std::vector<int32_t> still;  // defective clusters outside the set keep their status
    for (int32_t c : defective_list_)
      if (!set_.contains(c)) {
        defective_[c] = 1;
        still.push_back(c);
      }
    defective_list_ = std::move(still);
    defect_vertices_ = 0;
    strip_vertices_ = strip_vertices;
    std::vector<uint8_t> strip_bad(strip_vertices, 0);
    for (const dual::FanVerdict& v : verdicts) {
      if (v.vertex < K_) has_faces_[v.vertex] = 1;
      if (!v.defective) continue;
      ++defect_vertices_;
      if (v.vertex < K_) {
        defective_[v.vertex] = 1;
        defective_list_.push_back(int32_t(v.vertex));
      } else {
        strip_bad[v.vertex - K_] = 1;
      }
    }
    std::vector<int32_t> bad;
    // The clusters of every face around a defective vertex.
    for (const Triple& t : faces) {
      bool around = false;
      for (uint32_t x : t) around |= x < K_ ? defective_[x] != 0 && set_.contains(int32_t(x)) : strip_bad[x - K_] != 0;
      if (around)
        for (uint32_t y : t)
          if (y < K_) bad.push_back(int32_t(y));
    }
    // Neighbours in the input with no dual edge between them: the output comes apart along
    // their frontier (e.g. a thin neck ringed by one cluster) although every fan is a disc.
    // Counted apart from the fan defects: the built dual shows no defect there.
    const std::vector<uint64_t> unjoined = dual::unjoined_pairs(neighbour_pairs, faces, K_);
    unjoined_pairs_ = unjoined.size();
    for (uint64_t pair : unjoined)
      for (const int32_t c : {int32_t(pair >> 32), int32_t(uint32_t(pair))}) {
        if (!defective_[c]) {
          defective_[c] = 1;
          defective_list_.push_back(c);
        }
        bad.push_back(c);
      }
    for (int32_t c : set_.list())
      if (size[c] > 0 && !has_faces_[c]) {  // a cluster on no dual face
        if (!defective_[c]) {
          defective_[c] = 1;
          defective_list_.push_back(c);
          ++defect_vertices_;
        }
        bad.push_back(c);
      }
    for (const dual::FanVerdict& v : verdicts)
      if (v.vertex < K_) has_faces_[v.vertex] = 0;
    set_.clear();
    std::sort(defective_list_.begin(), defective_list_.end());
    std::sort(bad.begin(), bad.end());
    bad.erase(std::unique(bad.begin(), bad.end()), bad.end());
    return bad;
  }

  const MeshView& mesh_;
  const BoundaryLoops& loops_;
  const uint32_t K_;
  const bool strips_;
  const DualMeshOptions options_;
  const ClusterMembers& members_;
  ClusterSet set_;
  std::vector<uint8_t> defective_, has_faces_;
  std::vector<int32_t> defective_list_;
  std::vector<std::pair<uint32_t, uint32_t>> loop_of_vertex_;  // {boundary loop vertex, loop}
  uint64_t defect_vertices_ = 0;
  uint64_t unjoined_pairs_ = 0;
  uint32_t strip_vertices_ = 0;
};

// One repair round at a time with state that persists across rounds: per-cluster weights and
// boundary contact (refreshed for the clusters whose members changed), and K-sized flag arrays
// cleared through their lists.
class ClusterRepair {
 public:
  ClusterRepair(const MeshView& mesh, const ItemData& items, LabelEditor& labels, uint32_t K,
                std::span<const uint8_t> adjustable)
      : mesh_(mesh), items_(items), labels_(labels), K_(K), adjustable_(adjustable), weight_(K, 0.0),
        touches_boundary_(K, 0), is_defect_(K), near_(K), used_(K), beside_merge_(K), partner_(K, -1) {
    std::vector<int32_t> all(K);
    std::iota(all.begin(), all.end(), 0);
    refresh(all);
    labels_.take_stale();
  }

  // Splits and dissolves the clusters of `defect_clusters` (sorted, unique), and changes the
  // number of non-empty clusters by `count_change` with compensating merges or splits (0: the
  // count stays). With `keep_strips` those compensations only touch clusters off the boundary,
  // so the strip vertices of the dual stay as they are. Returns the clusters changed.
  std::vector<int32_t> round(std::span<const int32_t> defect_clusters, int64_t count_change, bool keep_strips,
                             RepairRoundStats& stats);

 private:
  // Weights are sums over the members in ascending vertex order: the same bits as a pass over
  // the labels in vertex order would give.
  void refresh(std::span<const int32_t> clusters) {
    tbb::enumerable_thread_specific<std::vector<uint32_t>> scratch;
    tbb::parallel_for(tbb::blocked_range<size_t>(0, clusters.size(), 256), [&](const tbb::blocked_range<size_t>& r) {
      std::vector<uint32_t>& m = scratch.local();
      for (size_t i = r.begin(); i != r.end(); ++i) {
        const int32_t c = clusters[i];
        labels_.index().members(c, m);
        double w = 0;
        uint8_t boundary = 0;
        for (uint32_t v : m) {
          w += items_.weight[v];
          boundary |= mesh_.vertex_flags[v] & kVertexBoundary;
        }
        weight_[c] = w;
        touches_boundary_[c] = boundary != 0;
      }
    });
  }

  // The members of c at the start of the round (every cluster the round reads is read before
  // the round changes it, or was merged away: then its list is the one taken for the merge).
  std::span<const uint32_t> members_of(int32_t c) {
    auto [it, fresh] = round_members_.try_emplace(c);
    if (fresh) labels_.index().members(c, it->second);
    return it->second;
  }
  // Clusters next to c under the current labels (c's members from the round's start), sorted.
  void neighbour_clusters(int32_t c, std::vector<int32_t>& out) {
    out.clear();
    for (uint32_t v : members_of(c))
      for (uint32_t n : mesh_.neighbours(v))
        if (labels_[n] >= 0 && labels_[n] != c) out.push_back(labels_[n]);
    sort_unique(out);
  }
  // The neighbour clusters of c: the list read before the round's merges, or, when a merge
  // next to c has changed it since, a fresh one in `fresh`.
  std::span<const int32_t> neighbours_now(int32_t c, std::vector<int32_t>& fresh) {
    auto it = round_neighbours_.find(c);
    if (it != round_neighbours_.end() && !beside_merge_.contains(c)) return it->second;
    neighbour_clusters(c, fresh);
    return fresh;
  }
  static void sort_unique(std::vector<int32_t>& v) {
    std::sort(v.begin(), v.end());
    v.erase(std::unique(v.begin(), v.end()), v.end());
  }
  static size_t common_count(std::span<const int32_t> x, std::span<const int32_t> y) {
    size_t n = 0;
    for (size_t i = 0, j = 0; i < x.size() && j < y.size();) {
      if (x[i] == y[j]) ++n, ++i, ++j;
      else if (x[i] < y[j]) ++i;
      else ++j;
    }
    return n;
  }
  uint32_t size_of(int32_t c) {
    auto it = round_members_.find(c);
    return it != round_members_.end() ? uint32_t(it->second.size()) : labels_.index().size(c);
  }

  const MeshView& mesh_;
  const ItemData& items_;
  LabelEditor& labels_;
  const uint32_t K_;
  std::span<const uint8_t> adjustable_;
  std::vector<double> weight_;
  std::vector<uint8_t> touches_boundary_;
  ClusterSet is_defect_, near_, used_, beside_merge_;
  std::vector<int32_t> partner_;
  std::unordered_map<int32_t, std::vector<uint32_t>> round_members_;
  std::unordered_map<int32_t, std::vector<int32_t>> round_neighbours_;  // merge candidates' lists
  SplitScratch scratch_;
};

std::vector<int32_t> ClusterRepair::round(std::span<const int32_t> defect_clusters, int64_t count_change,
                                          bool keep_strips, RepairRoundStats& stats) {
  {
    std::vector<int32_t> stale = labels_.take_stale();
    std::sort(stale.begin(), stale.end());  // ids in store order (see the merge candidates)
    refresh(stale);
  }
  round_members_.clear();
  for (int32_t c : defect_clusters)
    if (c >= 0 && uint32_t(c) < K_) is_defect_.insert(c);
  // Neighbour clusters of the defect clusters; "near" marks defects and their neighbours,
  // where no compensating merge may happen.
  std::vector<int32_t> defects = is_defect_.list();
  std::sort(defects.begin(), defects.end());
  std::vector<std::vector<int32_t>> neighbours_of_defect(defects.size());
  for (size_t i = 0; i < defects.size(); ++i) {
    const int32_t c = defects[i];
    near_.insert(c);
    auto& list = neighbours_of_defect[i];
    for (uint32_t v : members_of(c))
      for (uint32_t n : mesh_.neighbours(v))
        if (labels_[n] >= 0 && labels_[n] != c) list.push_back(labels_[n]);
    std::sort(list.begin(), list.end());
    list.erase(std::unique(list.begin(), list.end()), list.end());
    for (int32_t n : list) near_.insert(n);
  }
  std::vector<int32_t> touched;
  std::vector<int32_t> free_ids;  // ids released by dissolved islands and merges
  std::vector<int32_t> to_split;
  for (size_t i = 0; i < defects.size(); ++i) {
    const int32_t c = defects[i];
    const auto& list = neighbours_of_defect[i];
    if (list.size() == 1 && !touches_boundary_[c] && !is_defect_.contains(list[0])) {
      // An island: its surrounding cluster takes it whole (stays connected: it encloses it).
      for (uint32_t v : members_of(c)) labels_.set(v, list[0]);
      free_ids.push_back(c);
      touched.push_back(list[0]);
      ++stats.dissolved_islands;
    } else if (size_of(c) >= 2) {
      to_split.push_back(c);
    }
  }
  // More clusters asked for: empty ids become free ones, which the heaviest clusters take below.
  {
    const size_t freed = free_ids.size();  // the dissolved islands' ids
    for (uint32_t c = 0; c < K_ && count_change > 0 && int64_t(free_ids.size() - freed) < count_change; ++c)
      if (labels_.index().size(c) == 0 && std::find(free_ids.begin(), free_ids.begin() + std::ptrdiff_t(freed), int32_t(c)) ==
                                              free_ids.begin() + std::ptrdiff_t(freed))
        free_ids.push_back(int32_t(c));
  }
  // Fewer clusters asked for: that many freed ids stay unused.
  const size_t keep_free = count_change < 0 ? size_t(-count_change) : 0;
  auto compensable = [&](int32_t c) { return !near_.contains(c) && adjustable_[c] && !(keep_strips && touches_boundary_[c]); };
  // Compensate so that the number of non-empty clusters changes by count_change.
  // A defective cluster is cut in two (measured: cutting in three fixed no more dragon defects
  // and lost genus on fertility at N = 200 more often).
  constexpr size_t kParts = 2;
  auto ids_needed = [&] {
    size_t n = 0;
    for (int32_t c : to_split) n += std::min<size_t>(kParts, size_of(c)) - 1;
    return n;
  };
  if (ids_needed() + keep_free > free_ids.size()) {
    // Merge light adjacent pairs away from every defect: the lightest eligible clusters (a few
    // times as many as needed, found in O(K)) propose their lightest neighbour; proposals are
    // taken lightest pair first. Only the candidates' own vertices are scanned.
    const size_t needed = ids_needed() + keep_free - free_ids.size();
    std::vector<int32_t> candidates;
    const std::span<const uint32_t> size = labels_.index().sizes();
    for (uint32_t c = 0; c < K_; ++c)
      if (compensable(int32_t(c)) && size[c] > 0) candidates.push_back(int32_t(c));
    const size_t keep = std::min(candidates.size(), 8 * needed + 16);
    auto lighter = [&](int32_t x, int32_t y) { return weight_[x] != weight_[y] ? weight_[x] < weight_[y] : x < y; };
    std::nth_element(candidates.begin(), candidates.begin() + std::ptrdiff_t(keep), candidates.end(), lighter);
    candidates.resize(keep);
    // Read in id order: the sampling numbers clusters range by range, so ascending ids walk the
    // store (and the member index) forwards and each page is read once. In weight order the
    // reads jump across the whole mesh: out of core, a 105M-face store at 2 GiB re-read its
    // pages for every candidate (repair 186 s instead of 31 s).
    std::sort(candidates.begin(), candidates.end());
    for (int32_t a : candidates) {
      std::vector<int32_t>& around = round_neighbours_[a];
      for (uint32_t v : members_of(a))
        for (uint32_t n : mesh_.neighbours(v)) {
          const int32_t b = labels_[n];
          if (b < 0 || b == a) continue;
          around.push_back(b);
          if (!compensable(b)) continue;
          if (partner_[a] < 0 || lighter(b, partner_[a])) partner_[a] = b;
        }
      sort_unique(around);
    }
    {  // the partners' neighbour lists, in id order too
      std::vector<int32_t> partners;
      for (int32_t a : candidates)
        if (partner_[a] >= 0 && !round_neighbours_.contains(partner_[a])) partners.push_back(partner_[a]);
      sort_unique(partners);
      for (int32_t b : partners) neighbour_clusters(b, round_neighbours_[b]);
    }
    std::vector<int32_t> proposers;
    for (int32_t a : candidates)
      if (partner_[a] >= 0) proposers.push_back(a);
    auto pair_weight = [&](int32_t a) { return weight_[a] + weight_[partner_[a]]; };
    std::stable_sort(proposers.begin(), proposers.end(),
                     [&](int32_t x, int32_t y) { return pair_weight(x) < pair_weight(y); });
    std::vector<int32_t> fresh_a, fresh_b;
    for (int32_t a : proposers) {
      if (ids_needed() + keep_free <= free_ids.size()) break;
      const int32_t b = partner_[a];
      if (used_.contains(a) || used_.contains(b)) continue;
      // A merge collapses the dual edge a–b. Off the boundary it keeps the dual manifold only
      // when a and b have exactly two common neighbours, the clusters at the ends of their
      // frontier (the link condition of an edge collapse); the neighbours of a merged pair
      // wait for the next round, so that two merges never share a link.
      // Lists taken before this round's merges, unless a merge next to the cluster changed them.
      const std::span<const int32_t> around_a = neighbours_now(a, fresh_a);
      const std::span<const int32_t> around_b = neighbours_now(b, fresh_b);
      if (!touches_boundary_[a] && !touches_boundary_[b] && common_count(around_a, around_b) != 2) continue;
      used_.insert(a);
      used_.insert(b);
      for (const std::span<const int32_t> around : {around_a, around_b})
        for (int32_t n : around) {
          beside_merge_.insert(n);
          if (keep_free > 0) used_.insert(n);  // count rounds: many merges at once, kept apart
        }
      for (uint32_t v : members_of(b)) labels_.set(v, a);
      free_ids.push_back(b);
      touched.push_back(a);
      ++stats.merges;
    }
    for (int32_t a : candidates) partner_[a] = -1;
    used_.clear();
    beside_merge_.clear();
    round_neighbours_.clear();
    while (!to_split.empty() && ids_needed() + keep_free > free_ids.size()) to_split.pop_back();
  }
  auto split = [&](int32_t c, std::span<const int32_t> ids) {
    std::span<const uint32_t> members = members_of(c);
    const uint32_t made = split_cluster(mesh_, labels_.labels(), members, ids, scratch_);
    for (uint32_t v : members) labels_.note(v, c);
    return made;
  };
  for (int32_t c : to_split) {
    const size_t parts = std::min<size_t>(kParts, size_of(c));
    std::vector<int32_t> ids(free_ids.end() - std::ptrdiff_t(parts - 1), free_ids.end());
    const uint32_t made = split(c, ids);
    if (made == 0) continue;
    touched.push_back(c);
    for (uint32_t k = 0; k < made; ++k) touched.push_back(ids[k]);
    // Ids the split could not use (too few far-apart members) stay free.
    free_ids.resize(free_ids.size() - (parts - 1));
    for (uint32_t k = made; k < parts - 1; ++k) free_ids.push_back(ids[k]);
    ++stats.splits;
  }
  // Ids still free (more islands than splits, or more clusters asked for): split the heaviest.
  if (free_ids.size() > keep_free) {
    std::vector<int32_t> order(K_);
    std::iota(order.begin(), order.end(), 0);
    std::stable_sort(order.begin(), order.end(), [&](int32_t x, int32_t y) { return weight_[x] > weight_[y]; });
    for (int32_t c : order) {
      if (free_ids.size() <= keep_free) break;
      if (!compensable(c)) continue;
      // Only clusters untouched this round (whose members are the round's first) are split here;
      // a cluster merged away has none left.
      if (std::find(touched.begin(), touched.end(), c) != touched.end()) continue;
      if (labels_.index().size(c) < 2) continue;
      const int32_t id = free_ids.back();
      if (split(c, {&id, 1}) == 0) continue;
      free_ids.pop_back();
      touched.push_back(c);
      touched.push_back(id);
      ++stats.splits;
    }
  }
  is_defect_.clear();
  near_.clear();
  std::sort(touched.begin(), touched.end());
  touched.erase(std::unique(touched.begin(), touched.end()), touched.end());
  return touched;
}

}  // namespace

DefectRepairResult repair_dual_defects(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                                       uint32_t cluster_count, std::span<const uint8_t> adjustable,
                                       const BoundaryLoops& loops, const DefectRepairOptions& options,
                                       ClusteringReport& report, ArrayStorage& storage) {
  const uint32_t K = cluster_count;
  DefectRepairResult result;
  result.touched.assign(K, 0);
  auto t = std::chrono::steady_clock::now();
  LabelEditor editor(mesh, labels, K, storage);
  DefectTracker tracker(mesh, loops, K, options.dual, editor.index());
  std::vector<int32_t> bad = tracker.check_all(labels);
  // Output vertices wanted minus those the dual of the current labels has (non-empty clusters
  // plus strip vertices), when a vertex target is set; O(K).
  auto count_change = [&]() -> int64_t {
    if (options.target_vertices == 0) return 0;
    const std::span<const uint32_t> size = editor.index().sizes();
    const int64_t used = std::count_if(size.begin(), size.end(), [](uint32_t n) { return n > 0; });
    return int64_t(options.target_vertices) - used - int64_t(tracker.strip_vertices());
  };
  int64_t change = count_change();
  result.check_seconds += seconds_since(t);
  if (bad.empty() && change == 0) {
    result.defect_vertices = tracker.defect_vertices();
    result.unjoined_pairs = tracker.unjoined_pairs();
    return result;
  }
  t = std::chrono::steady_clock::now();
  ClusterRepair repair(mesh, items, editor, K, adjustable);
  result.repair_seconds += seconds_since(t);
  // Vertices of the clusters repaired around a defect, and of their neighbours: the region the
  // final relaxation leaves alone (relaxing it tends to rebuild the thin-feature clusters).
  std::vector<uint32_t> near_defect, members;
  size_t near_unique = 0;
  while ((!bad.empty() || change != 0) && result.rounds < options.max_rounds) {
    t = std::chrono::steady_clock::now();
    editor.index().compact();
    for (int32_t c : bad) {
      editor.index().members(c, members);
      for (uint32_t v : members) {
        near_defect.push_back(v);
        for (uint32_t n : mesh.neighbours(v)) near_defect.push_back(n);
      }
    }
    if (near_defect.size() > 2 * near_unique) {  // rounds revisit the same region: dedupe as it doubles
      std::sort(near_defect.begin(), near_defect.end());
      near_defect.erase(std::unique(near_defect.begin(), near_defect.end()), near_defect.end());
      near_unique = near_defect.size();
    }
    RepairRoundStats stats;
    // The count changes only in rounds without defects: merges next to a defect's splits made
    // the two chase each other (dragon: 36 rounds instead of 12).
    const int64_t asked = bad.empty() ? change : 0;
    const std::vector<int32_t> touched = repair.round(bad, asked, options.target_vertices != 0, stats);
    // Clusters merged for the count are relaxed too: left as they are, the merged pairs are
    // twice the area of their neighbours (strip plane, N = 400: CV of the cluster areas 0.20
    // instead of 0.07). Spread over the surface, they make the relaxation visit most chunks.
    for (int32_t c : touched) result.touched[c] = 1;
    result.repaired_clusters += touched.size();
    result.splits += stats.splits;
    result.merges += stats.merges;
    result.islands += stats.dissolved_islands;
    ++result.rounds;
    if (asked != 0) ++result.count_rounds;
    result.repair_seconds += seconds_since(t);
    t = std::chrono::steady_clock::now();
    bad = tracker.check_changes(labels, editor.take_log());
    change = count_change();
    result.check_seconds += seconds_since(t);
    // A count round that found nothing to merge or split: N cannot be reached (e.g. the strips
    // alone need more than N vertices); more rounds would find nothing either.
    if (asked != 0 && stats.merges + stats.splits + stats.dissolved_islands == 0) break;
  }
  result.defect_vertices = tracker.defect_vertices();
  result.unjoined_pairs = tracker.unjoined_pairs();
  if (!bad.empty() || result.rounds == 0 || !options.relax) return result;
  // The repair leaves split halves and merged pairs unrelaxed. Relax the touched clusters once
  // (constrained) with the clusters around the repaired defects frozen (their vertices hidden
  // as free, so nothing moves into or out of them): relaxing those rebuilds the thin-feature
  // clusters (measured on the dragon: an unfrozen relaxation always brought defects back).
  // The relaxation is kept only when the dual stays defect-free.
  t = std::chrono::steady_clock::now();
  std::vector<uint8_t> active = result.touched;
  // Whole clusters are frozen, so the 1-ring connectivity test stays exact for the others.
  ClusterSet frozen(K);
  for (uint32_t v : near_defect) frozen.insert(labels[v]);
  std::vector<int32_t> frozen_list = frozen.list();
  std::sort(frozen_list.begin(), frozen_list.end());
  std::vector<uint32_t> hidden;  // the frozen clusters' vertices, by cluster
  std::vector<uint32_t> hidden_begin = {0};
  for (int32_t c : frozen_list) {
    editor.index().members(c, members);
    hidden.insert(hidden.end(), members.begin(), members.end());
    hidden_begin.push_back(uint32_t(hidden.size()));
  }
  // The relaxation writes labels directly: the labels before it, in the job's storage, tell
  // which vertices it moved (the clustering loops themselves are O(V) anyway).
  const std::vector<VertexRange> ranges = dual::chunk_vertex_blocks(mesh);
  LargeArray<int32_t> before(labels.size(), storage, "labels before the relaxation");
  tbb::parallel_for(tbb::blocked_range<size_t>(0, ranges.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i)
      std::copy(labels.begin() + ranges[i].begin, labels.begin() + ranges[i].end, before.begin() + ranges[i].begin);
  });
  for (size_t k = 0; k < frozen_list.size(); ++k) {
    active[frozen_list[k]] = 0;
    for (uint32_t i = hidden_begin[k]; i < hidden_begin[k + 1]; ++i) labels[hidden[i]] = -1;
  }
  ClusterState state = make_cluster_state(items, labels, K, options.clustering.metric, options.clustering.qem_threshold);
  update_site_offsets(state);
  LoopOptions relax = loop_options(options.clustering);
  relax.constrained = true;
  relax.stop_fraction = 0.0;
  // A few loops: they even out the split halves and merged pairs; more only shave the energy,
  // and each visits every chunk holding a touched cluster (out of core: a read of the store).
  relax.max_loops = 4;
  relax.on_loop = {};
  run_clustering_loops(mesh, items, labels, state, relax, report, active);
  for (size_t k = 0; k < frozen_list.size(); ++k)
    for (uint32_t i = hidden_begin[k]; i < hidden_begin[k + 1]; ++i) labels[hidden[i]] = frozen_list[k];
  std::vector<std::vector<LabelChange>> moved(ranges.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, ranges.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i)
      for (uint32_t v = ranges[i].begin; v < ranges[i].end; ++v)
        if (labels[v] != before[v]) moved[i].push_back({v, before[v]});
  });
  before.reset();
  for (const auto& m : moved)
    for (const LabelChange& ch : m) editor.note(ch.vertex, ch.old_label);
  if (tracker.check_changes(labels, editor.take_log()).empty() && count_change() == change) {
    result.relaxed = true;
  } else {
    for (const auto& m : moved)
      for (const LabelChange& ch : m) editor.set(ch.vertex, ch.old_label);
    tracker.check_changes(labels, editor.take_log());
  }
  result.defect_vertices = tracker.defect_vertices();
  result.unjoined_pairs = tracker.unjoined_pairs();
  result.repair_seconds += seconds_since(t);
  return result;
}

}  // namespace streamcvd
