// The repair's round (core/dual/cluster_repair.h): ClusterRepair::round dissolves islands and
// lenses, splits the other defective clusters (split_cluster, core/dual/cluster_split.cpp) and
// keeps the cluster count with merges of light pairs far from any defect (link condition) or
// splits of heavy clusters.
#include "streamcvd/core/dual/cluster_repair.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <numeric>

#include "streamcvd/core/dual/dual_topology.h"

namespace streamcvd::detail {

namespace {

// Number of ids both sorted lists hold.
size_t common_count(std::span<const int32_t> x, std::span<const int32_t> y) {
  size_t n = 0;
  for (size_t i = 0, j = 0; i < x.size() && j < y.size();) {
    if (x[i] == y[j]) ++n, ++i, ++j;
    else if (x[i] < y[j]) ++i;
    else ++j;
  }
  return n;
}

// Calls visit(c) for the ids c of [0, n) in the order `before` (a strict total order) until it
// returns false. The order is found a batch at a time: nth_element, then a sort of the batch,
// each batch four times the last, from `first_batch`. O(n) when the first batches suffice, as
// they do when a few of n are taken (a sort of all n cost 25 ms a round at n = 300,000).
template <class Before, class Visit>
void visit_in_order(uint32_t n, size_t first_batch, const Before& before, const Visit& visit) {
  std::vector<int32_t> order(n);
  std::iota(order.begin(), order.end(), 0);
  for (size_t done = 0, batch = std::max<size_t>(first_batch, 1); done < order.size(); batch *= 4) {
    const auto first = order.begin() + std::ptrdiff_t(done);
    done = std::min(order.size(), done + batch);
    const auto last = order.begin() + std::ptrdiff_t(done);
    std::nth_element(first, last - 1, order.end(), before);
    std::sort(first, last, before);
    for (auto it = first; it != last; ++it)
      if (!visit(*it)) return;
  }
}

}  // namespace

ClusterRepair::ClusterRepair(const MeshView& mesh, const ItemData& items, LabelEditor& labels, uint32_t K,
                             std::span<const uint8_t> adjustable, const BoundaryLoops& loops)
    : mesh_(mesh), loops_(loops), items_(items), labels_(labels), K_(K), adjustable_(adjustable), weight_(K, 0.0),
      touches_boundary_(K, 0), repaired_(K, 0), is_defect_(K), near_(K), used_(K), beside_merge_(K), spared_(K), partner_(K, -1) {
  std::vector<int32_t> all(K);
  std::iota(all.begin(), all.end(), 0);
  refresh(all);
  labels_.take_stale();
}

// Weights are sums over the members in ascending vertex order: the same bits as a pass over
// the labels in vertex order would give.
void ClusterRepair::refresh(std::span<const int32_t> clusters) {
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
std::span<const uint32_t> ClusterRepair::members_of(int32_t c) {
  auto [it, fresh] = round_members_.try_emplace(c);
  if (fresh) labels_.index().members(c, it->second);
  return it->second;
}

// Clusters next to c under the current labels (c's members from the round's start), sorted.
void ClusterRepair::neighbour_clusters(int32_t c, std::vector<int32_t>& out) {
  out.clear();
  for (uint32_t v : members_of(c))
    for (uint32_t n : mesh_.neighbours(v))
      if (labels_[n] >= 0 && labels_[n] != c) out.push_back(labels_[n]);
  dual::sort_unique(out);
}

// The neighbour clusters of c: the list read before the round's merges, or, when a merge
// next to c has changed it since, a fresh one in `fresh`.
std::span<const int32_t> ClusterRepair::neighbours_now(int32_t c, std::vector<int32_t>& fresh) {
  auto it = round_neighbours_.find(c);
  if (it != round_neighbours_.end() && !beside_merge_.contains(c)) return it->second;
  neighbour_clusters(c, fresh);
  return fresh;
}

uint32_t ClusterRepair::size_of(int32_t c) {
  auto it = round_members_.find(c);
  return it != round_members_.end() ? uint32_t(it->second.size()) : labels_.index().size(c);
}

// A ring round a small tip, whose one side is a group of clusters that meet only each other and
// the ring, with fewer members in all than the ring: the group joins the ring, which becomes a
// cap over the tip (its dual vertex one closed fan), and its ids are freed. Cut across, such a
// ring kept a part round the tip, shrinking a round at a time (dragon → 1000, default threads:
// a 102-member ring round two clusters of 5 and 7 members, 5 rounds to 6 members). The ring and
// the group are spared for the round. O(members of the side's clusters and their 1-rings).
void ClusterRepair::merge_tips(std::span<const Ring> rings, std::vector<int32_t>& free_ids,
                               std::vector<int32_t>& touched, RepairRoundStats& stats) {
  std::vector<int32_t> around;
  for (const Ring& ring : rings) {
    const int32_t c = ring.cluster;
    if (c < 0 || uint32_t(c) >= K_ || !is_defect_.contains(c) || spared_.contains(c)) continue;
    for (const std::vector<int32_t>& side : ring.sides) {
      uint64_t members = 0;
      bool tip = !side.empty();
      for (int32_t t : side) {
        if (t < 0 || uint32_t(t) >= K_ || spared_.contains(t) || touches_boundary_[t]) {
          tip = false;
          break;
        }
        members += size_of(t);
        neighbour_clusters(t, around);
        tip &= std::all_of(around.begin(), around.end(), [&](int32_t y) {
          return y == c || std::binary_search(side.begin(), side.end(), y);
        });
        if (!tip) break;
      }
      if (!tip || members > size_of(c)) continue;
      for (int32_t t : side) {
        for (uint32_t v : members_of(t)) labels_.set(v, c);
        free_ids.push_back(t);
        spared_.insert(t);
        ++stats.dissolved_islands;
      }
      spared_.insert(c);
      touched.push_back(c);
      break;
    }
  }
}

std::vector<int32_t> ClusterRepair::compensate(int64_t count_change, std::span<const int32_t> keep_off,
                                               RepairRoundStats& stats) {
  round_members_.clear();
  std::vector<int32_t> around;
  for (int32_t c : keep_off) {
    near_.insert(c);
    neighbour_clusters(c, around);
    for (int32_t n : around) near_.insert(n);
  }
  return round({}, {}, {}, count_change, true, stats);
}

std::vector<int32_t> ClusterRepair::round(std::span<const int32_t> defect_clusters, std::span<const Ring> rings,
                                          std::span<const OpenHole> open_holes, int64_t count_change, bool keep_strips,
                                          RepairRoundStats& stats) {
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
    neighbour_clusters(c, neighbours_of_defect[i]);
    for (int32_t n : neighbours_of_defect[i]) near_.insert(n);
  }
  std::vector<int32_t> touched;
  std::vector<int32_t> free_ids;  // ids released by dissolved islands and merges
  std::vector<int32_t> to_split;
  // Clusters with one or two neighbours go first: their dual vertex has one face or two on the
  // same three vertices, whatever its shape, and their neighbours' defects are theirs.
  // spared_: dissolved clusters and their neighbours, not split this round.
  merge_tips(rings, free_ids, touched, stats);
  std::vector<size_t> contacts;
  for (size_t i = 0; i < defects.size(); ++i) {
    const int32_t c = defects[i];
    const auto& list = neighbours_of_defect[i];
    if (touches_boundary_[c] || list.empty() || list.size() > 2) continue;
    // Once per cluster: a cluster dissolved into one that a later round splits again could be
    // remade and dissolved for ever (dragon → 1000 at 2 threads: 40 rounds, a cap on a tube
    // dissolved into the band below it and split off again). Past the first time, both split.
    if (repaired_[c] || spared_.contains(c)) continue;
    // A band between its two neighbours (a ring round a tube) is cut across instead: merged,
    // its neighbour becomes the band (torus of 80 × 32, N = 20: every cluster a ring, and
    // merging them led to the last-resort face deletion).
    if (list.size() == 2 && !frontier_in_one_part(mesh_, labels_.labels(), members_of(c), scratch_)) continue;
    // An island joins the cluster round it (connected: it encloses it); a cluster between two
    // (a lens on their frontier, dragon → 1000: 1-vertex clusters after a split, whose two
    // neighbours were then halved round after round) joins the one it touches more.
    contacts.assign(list.size(), 0);
    for (uint32_t v : members_of(c))
      for (uint32_t n : mesh_.neighbours(v)) {
        auto it = std::lower_bound(list.begin(), list.end(), labels_[n]);
        if (it != list.end() && *it == labels_[n]) ++contacts[size_t(it - list.begin())];
      }
    const int32_t into = list[size_t(std::max_element(contacts.begin(), contacts.end()) - contacts.begin())];
    if (repaired_[into]) continue;
    for (uint32_t v : members_of(c)) labels_.set(v, into);
    free_ids.push_back(c);
    touched.push_back(into);
    ++stats.dissolved_islands;
    spared_.insert(c);
    for (int32_t n : list) spared_.insert(n);
  }
  for (int32_t c : defects)
    if (!spared_.contains(c) && size_of(c) >= 2) to_split.push_back(c);
  spared_.clear();
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
  // Compensations stay off every cluster an earlier round repaired: a heavy cluster split there
  // tends to sit on the thin feature the defect was on, and remade it (dragon → 1000: a 1-vertex
  // cluster dissolved and its id split off the heavy cluster next to it, 16 rounds running).
  auto compensable = [&](int32_t c) {
    return !near_.contains(c) && !repaired_[c] && adjustable_[c] && !(keep_strips && touches_boundary_[c]);
  };
  // Compensate so that the number of non-empty clusters changes by count_change.
  // A defective cluster is cut in two (measured: cutting every one in three fixed no more
  // dragon defects and lost genus on fertility at N = 200 more often), a ring in three: halves
  // of a ring meet along both cuts, a dual edge with four faces, which later rounds peeled a
  // few members at a time (dragon → 1000, default threads: 5 of 48 runs over 10 rounds, 0 with
  // rings cut in three; seeds 1–60: 9 → 4).
  auto ring_of = [&](int32_t c) -> const Ring* {
    auto it = std::lower_bound(rings.begin(), rings.end(), c, [](const Ring& r, int32_t x) { return r.cluster < x; });
    return it != rings.end() && it->cluster == c ? &*it : nullptr;
  };
  auto parts_of = [&](int32_t c) { return std::min<size_t>(ring_of(c) ? 3 : 2, size_of(c)); };
  auto ids_needed = [&] {
    size_t n = 0;
    for (int32_t c : to_split) n += parts_of(c) - 1;
    return n;
  };
  if (ids_needed() + keep_free > free_ids.size()) {
    // Merge light adjacent pairs away from every defect: the lightest eligible clusters (a few
    // times as many as needed, found in O(K)) propose their lightest neighbour; proposals are
    // taken lightest pair first. Only the candidates' own vertices are scanned. When those
    // give too few merges, the next lightest batch, four times larger, is tried: the lightest
    // clusters may all sit where no merge is allowed (crude decimation of the dragon subdivided
    // to 26.6M faces → 200,000: 40 candidates on small pieces refused, no merge, so no split of
    // six defective clusters, 28 rounds to the cap).
    const std::span<const uint32_t> size = labels_.index().sizes();
    std::vector<int32_t> eligible;
    for (uint32_t c = 0; c < K_; ++c)
      if (compensable(int32_t(c)) && size[c] > 0) eligible.push_back(int32_t(c));
    auto lighter = [&](int32_t x, int32_t y) { return weight_[x] != weight_[y] ? weight_[x] < weight_[y] : x < y; };
    // One batch of candidates: each proposes its lightest compensable neighbour, and the pairs
    // are merged lightest first while ids are still needed.
    auto merge_light_pairs = [&](std::vector<int32_t>& candidates) {
      // Read in id order: the sampling numbers clusters by their first vertex in store order, so
      // ascending ids walk the store (and the member index) forwards and each page is read once.
      // In weight order the reads jump across the whole mesh: out of core, a 105M-face store at
      // 2 GiB re-read its pages for every candidate (repair 186 s instead of 31 s).
      std::sort(candidates.begin(), candidates.end());
      for (int32_t a : candidates) {  // each proposes its lightest compensable neighbour
        std::vector<int32_t>& around = round_neighbours_[a];
        neighbour_clusters(a, around);
        for (int32_t b : around)
          if (compensable(b) && (partner_[a] < 0 || lighter(b, partner_[a]))) partner_[a] = b;
      }
      {  // the partners' neighbour lists, in id order too
        std::vector<int32_t> partners;
        for (int32_t a : candidates)
          if (partner_[a] >= 0 && !round_neighbours_.contains(partner_[a])) partners.push_back(partner_[a]);
        dual::sort_unique(partners);
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
        // Nor when the pair and its neighbours are all there is of a small piece: merged, a
        // tetrahedron of clusters (two common neighbours, the link condition met) becomes two
        // faces on the same three clusters. Light clusters are those of small pieces, and count
        // merges picked them first (dragon → 1000: pieces left with two or three clusters,
        // repaired for three rounds each after every count round).
        if (around_a.size() + around_b.size() - common_count(around_a, around_b) < 5) continue;
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
    };
    size_t tried = 0;
    for (size_t batch = 8 * (ids_needed() + keep_free - free_ids.size()) + 16;
         ids_needed() + keep_free > free_ids.size() && tried < eligible.size(); batch *= 4) {
      const size_t end = std::min(eligible.size(), tried + batch);
      std::nth_element(eligible.begin() + std::ptrdiff_t(tried), eligible.begin() + std::ptrdiff_t(end), eligible.end(),
                       lighter);
      std::vector<int32_t> candidates(eligible.begin() + std::ptrdiff_t(tried), eligible.begin() + std::ptrdiff_t(end));
      tried = end;
      merge_light_pairs(candidates);
    }
    used_.clear();
    beside_merge_.clear();
    round_neighbours_.clear();
    while (!to_split.empty() && ids_needed() + keep_free > free_ids.size()) to_split.pop_back();
  }
  // The loop of the first hole c keeps open, or nothing.
  auto hole_loop_of = [&](int32_t c) -> std::span<const uint32_t> {
    auto it = std::lower_bound(open_holes.begin(), open_holes.end(), OpenHole{c, 0});
    if (it == open_holes.end() || it->cluster != c) return {};
    return {loops_.vertices.data() + loops_.offsets[it->loop], loops_.offsets[it->loop + 1] - loops_.offsets[it->loop]};
  };
  auto split = [&](int32_t c, std::span<const int32_t> ids, bool at_defect) {
    std::span<const uint32_t> members = members_of(c);
    const uint32_t made = split_cluster(mesh_, labels_.labels(), members, ids, scratch_, at_defect, ring_of(c),
                                        at_defect ? hole_loop_of(c) : std::span<const uint32_t>());
    for (uint32_t v : members) labels_.note(v, c);
    return made;
  };
  for (int32_t c : to_split) {
    const size_t parts = parts_of(c);
    std::vector<int32_t> ids(free_ids.end() - std::ptrdiff_t(parts - 1), free_ids.end());
    const uint32_t made = split(c, ids, true);
    if (made == 0) continue;
    touched.push_back(c);
    for (uint32_t k = 0; k < made; ++k) touched.push_back(ids[k]);
    // Ids the split could not use (too few far-apart members) stay free.
    free_ids.resize(free_ids.size() - (parts - 1));
    for (uint32_t k = made; k < parts - 1; ++k) free_ids.push_back(ids[k]);
    ++stats.splits;
  }
  // Ids still free (more islands than splits, or more clusters asked for): split the heaviest.
  auto heavier = [&](int32_t x, int32_t y) { return weight_[x] != weight_[y] ? weight_[x] > weight_[y] : x < y; };
  if (free_ids.size() > keep_free)
    visit_in_order(K_, 4 * (free_ids.size() - keep_free) + 16, heavier, [&](int32_t c) {
      if (free_ids.size() <= keep_free) return false;
      // Only clusters untouched this round (whose members are the round's first) are split here;
      // a cluster merged away has none left.
      if (!compensable(c) || std::find(touched.begin(), touched.end(), c) != touched.end() ||
          labels_.index().size(c) < 2)
        return true;
      const int32_t id = free_ids.back();
      if (split(c, {&id, 1}, false) == 0) return true;
      // A farthest-point cut of a cluster on a thin or folded patch can leave a half that
      // rings the other or meets a neighbour twice: a new defect far from the others, found
      // a round later and repaired with its own compensations (crude dragon ×10 → 100,000:
      // 3 of the last 6 rounds). Such a cut is undone and the next heaviest cluster tried.
      if (!touches_boundary_[c] &&
          !parts_are_discs(mesh_, labels_.labels(), members_of(c), std::array{c, id}, fan_scratch_)) {
        for (uint32_t v : members_of(c)) labels_.set(v, c);
        return true;
      }
      free_ids.pop_back();
      touched.push_back(c);
      touched.push_back(id);
      ++stats.splits;
      return true;
    });
  is_defect_.clear();
  near_.clear();
  dual::sort_unique(touched);
  for (int32_t c : defects) repaired_[c] = 1;
  return touched;
}

}  // namespace streamcvd::detail
