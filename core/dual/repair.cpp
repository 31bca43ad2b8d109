// The repair loop (core/dual/repair.h) and its final relaxation, with K-sized state. The
// vertices of the clusters a round touches come from a cluster → vertices index
// (core/clustering/cluster_members.h) built once; every label the repair writes goes through a
// change log of (vertex, old label) (core/dual/repair_state.h), which updates the index and tells
// the defect tracker (core/dual/defect_tracker.h) where the dual may have changed; the edits are
// core/dual/cluster_repair.h. Per round: O(vertices of the touched clusters + their faces) plus a
// few O(K) scans of byte and weight arrays (candidates of the compensating merges) and
// O(boundary) for the strips; never O(V).
#include "streamcvd/core/dual/repair.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <numeric>
#include <optional>

#include "streamcvd/core/dual/cluster_repair.h"
#include "streamcvd/core/dual/defect_tracker.h"
#include "streamcvd/core/dual/dual_topology.h"
#include "streamcvd/core/dual/repair_state.h"
#include "streamcvd/core/mesh/timer.h"
#include "streamcvd/core/mesh/union_find.h"

namespace streamcvd {

namespace {

// Undoes the moves (vertex, label before) of `moved` whose group holds a cluster of `bad`, or,
// with `strips_changed`, a move of a boundary vertex (the number of strip vertices changed: the
// count would be off). The groups are the clusters joined by a move between them. Returns the
// defects re-checked. O(K + moves + the check of the undone changes).
std::vector<int32_t> undo_moves_of_groups(const MeshView& mesh, const std::vector<std::vector<detail::LabelChange>>& moved,
                                          std::span<const int32_t> bad, bool strips_changed, uint32_t K,
                                          detail::LabelEditor& editor,
                                          detail::DefectTracker& tracker, std::span<int32_t> labels) {
  DisjointSets<uint32_t> groups(K);
  for (const auto& m : moved)
    for (const detail::LabelChange& ch : m) groups.unite(uint32_t(ch.old_label), uint32_t(labels[ch.vertex]));
  std::vector<uint8_t> undo(K, 0);
  for (int32_t c : bad)
    if (c >= 0 && uint32_t(c) < K) undo[groups.find(uint32_t(c))] = 1;
  if (strips_changed)
    for (const auto& m : moved)
      for (const detail::LabelChange& ch : m)
        if (mesh.vertex_flags[ch.vertex] & kVertexBoundary) undo[groups.find(uint32_t(ch.old_label))] = 1;
  for (const auto& m : moved)
    for (const detail::LabelChange& ch : m)
      if (labels[ch.vertex] != ch.old_label && undo[groups.find(uint32_t(ch.old_label))])
        editor.set(ch.vertex, ch.old_label);
  return tracker.check_changes(labels, editor.take_log());
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
  detail::LabelEditor editor(mesh, labels, K, storage);
  detail::DefectTracker tracker(mesh, loops, K, options.dual, editor.index());
  std::vector<int32_t> bad = tracker.check_all(labels);
  result.defects_per_round.push_back(uint32_t(bad.size()));
  // Output vertices wanted minus those the dual of the current labels has (non-empty clusters
  // plus strip vertices), when a vertex target is set; O(K).
  auto count_change_with = [&](uint32_t strip_vertices) -> int64_t {
    if (options.target_vertices == 0) return 0;
    const std::span<const uint32_t> size = editor.index().sizes();
    const int64_t used = std::count_if(size.begin(), size.end(), [](uint32_t n) { return n > 0; });
    return int64_t(options.target_vertices) - used - int64_t(strip_vertices);
  };
  auto count_change = [&] { return count_change_with(tracker.strip_vertices()); };
  int64_t change = count_change();
  // A cluster that meets a hole below the output resolution in two stretches keeps it open
  // with a strip of slivers (no disc closes a ring with a repeated cluster). Such clusters are
  // cut between their two longest stretches along the hole, so that each part meets it once
  // and the ring can close (crude dragon ×10 → 100,000, --deterministic, seeds 1 and 3: 102
  // and 103 output loops → 9 and 11; ×20 → 200,000 at default threads, seeds 11 and 12: 271
  // and 298 → 18 and 14; a farthest-point cut often left both stretches in one part). They
  // are split with the round's defects, at most twice each and only in the first rounds: the
  // halves can meet the hole twice again, and chasing them made the repair longer than the
  // defects did. Dragon, IQ, --deterministic, strip Qav before → after: 5k 0.425 → 0.560,
  // 10k 0.408 → 0.481, 20k 0.442 → 0.492, 40k 0.511 → 0.521; rounds 8, 7, 7, 5 → 8, 6, 6, 5
  // (with no round limit: up to 9 rounds on the dragon at 10k).
  constexpr uint32_t kHoleSplitRounds = 4;
  std::vector<uint8_t> hole_splits(K, 0);
  auto open_holes = [&] {
    std::vector<int32_t> split;
    if (result.rounds >= kHoleSplitRounds) return split;
    for (const OpenHole& h : tracker.open_holes())
      if (h.cluster >= 0 && uint32_t(h.cluster) < K && hole_splits[h.cluster] < 2 && editor.index().size(h.cluster) >= 2)
        split.push_back(h.cluster);
    dual::sort_unique(split);
    return split;
  };
  std::vector<int32_t> holes = open_holes();
  result.check_seconds += seconds_since(t);
  if (bad.empty() && change == 0 && holes.empty()) {
    result.defect_vertices = tracker.defect_vertices();
    result.unjoined_pairs = tracker.unjoined_pairs();
    result.dual_faces = tracker.take_triples();
    return result;
  }
  t = std::chrono::steady_clock::now();
  detail::ClusterRepair repair(mesh, items, editor, K, adjustable, loops);
  result.repair_seconds += seconds_since(t);
  // Vertices of the clusters repaired around a defect, and of their neighbours: the region the
  // final relaxation leaves alone (relaxing it tends to rebuild the thin-feature clusters).
  std::vector<uint32_t> near_defect, members;
  size_t near_unique = 0;
  // A round reads around its defects' clusters only: out of core, a fault should read its page,
  // not 8 MB around it (20 GB of the repair's reads at 105M faces inside 2 GiB).
  std::optional<ScatteredReads> scattered(std::in_place, mesh);
  while ((!bad.empty() || change != 0 || !holes.empty()) && result.rounds < options.max_rounds) {
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
      dual::sort_unique(near_defect);
      near_unique = near_defect.size();
    }
    detail::RepairRoundStats stats;
    // The count is set right in every round, with merges and splits away from the defects and
    // from every cluster an earlier round repaired (ClusterRepair::round), and again after the
    // round's cuts (below): the last defect round then needs no count round after it. (Merges
    // next to a defect's splits made the two chase each other: dragon 36 rounds instead of 12;
    // the repaired clusters are kept out.)
    const int64_t asked = change;
    std::vector<int32_t> round_defects = bad;
    for (int32_t c : holes) ++hole_splits[c], round_defects.push_back(c);
    dual::sort_unique(round_defects);
    std::vector<int32_t> touched =
        repair.round(round_defects, tracker.rings(), tracker.open_holes(), asked, options.target_vertices != 0, stats);
    // The round's cuts of clusters at the boundary changed the strips, so the count is off
    // again: set it now, away from what the round changed, so that a round after the last
    // defect round is not needed only for the count (crude dragon ×20 → 200,000: 12 rounds,
    // the last one a count round).
    if (options.target_vertices != 0 && !touched.empty())
      if (const int64_t left = count_change_with(tracker.strip_vertices_now(labels)); left != 0) {
        const std::vector<int32_t> more = repair.compensate(left, touched, stats);
        touched.insert(touched.end(), more.begin(), more.end());
        dual::sort_unique(touched);
      }
    // Clusters merged for the count are relaxed too: left as they are, the merged pairs are
    // twice the area of their neighbours (strip plane, N = 400: CV of the cluster areas 0.20
    // instead of 0.07). Spread over the surface, they make the relaxation visit most chunks.
    for (int32_t c : touched) result.touched[c] = 1;
    result.repaired_clusters += touched.size();
    result.splits += stats.splits;
    result.merges += stats.merges;
    result.islands += stats.dissolved_islands;
    ++result.rounds;
    if (asked != 0 && bad.empty()) ++result.count_rounds;
    result.repair_seconds += seconds_since(t);
    t = std::chrono::steady_clock::now();
    bad = tracker.check_changes(labels, editor.take_log());
    result.defects_per_round.push_back(uint32_t(bad.size()));
    change = count_change();
    holes = open_holes();
    result.check_seconds += seconds_since(t);
    // A count round that found nothing to merge or split: N cannot be reached (e.g. the strips
    // alone need more than N vertices); more rounds would find nothing either.
    if (asked != 0 && stats.merges + stats.splits + stats.dissolved_islands == 0) break;
  }
  scattered.reset();
  result.defect_vertices = tracker.defect_vertices();
  result.unjoined_pairs = tracker.unjoined_pairs();
  if (!bad.empty() || result.rounds == 0 || !options.relax) {
    result.dual_faces = tracker.take_triples();
    return result;
  }
  // The repair leaves split halves and merged pairs unrelaxed. Relax the touched clusters once
  // (constrained) with the clusters around the repaired defects frozen (their vertices hidden
  // as free, so nothing moves into or out of them): relaxing those rebuilds the thin-feature
  // clusters (measured on the dragon: an unfrozen relaxation always brought defects back).
  // The relaxation is kept only when the dual stays defect-free.
  t = std::chrono::steady_clock::now();
  std::vector<uint8_t> active = result.touched;
  // Whole clusters are frozen, so the 1-ring connectivity test stays exact for the others.
  detail::ClusterSet frozen(K);
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
  const std::vector<VertexRange> ranges = chunk_vertex_blocks(mesh);
  LargeArray<int32_t> before(labels.size(), storage, "labels before the relaxation");
  tbb::parallel_for(tbb::blocked_range<size_t>(0, ranges.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i)
      std::copy(labels.begin() + ranges[i].begin, labels.begin() + ranges[i].end, before.begin() + ranges[i].begin);
  });
  for (size_t k = 0; k < frozen_list.size(); ++k) {
    active[frozen_list[k]] = 0;
    for (uint32_t i = hidden_begin[k]; i < hidden_begin[k + 1]; ++i) labels[hidden[i]] = -1;
  }
  ClusterState state = solved_cluster_state(items, labels, K, options.clustering);
  LoopOptions relax = options.clustering.loops;
  relax.constrained = true;
  relax.stop_fraction = 0.0;
  // A few loops: they even out the split halves and merged pairs; more only shave the energy,
  // and each visits every chunk holding a touched cluster (out of core: a read of the store).
  relax.max_loops = 4;
  relax.on_loop = {};
  run_clustering_loops(mesh, items, labels, state, relax, report, active);
  for (size_t k = 0; k < frozen_list.size(); ++k)
    for (uint32_t i = hidden_begin[k]; i < hidden_begin[k + 1]; ++i) labels[hidden[i]] = frozen_list[k];
  std::vector<std::vector<detail::LabelChange>> moved(ranges.size());
  tbb::parallel_for(tbb::blocked_range<size_t>(0, ranges.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i)
      for (uint32_t v = ranges[i].begin; v < ranges[i].end; ++v)
        if (labels[v] != before[v]) moved[i].push_back({v, before[v]});
  });
  before.reset();
  for (const auto& m : moved)
    for (const detail::LabelChange& ch : m) editor.note(ch.vertex, ch.old_label);
  // The check of the relaxation's moves reads around the touched clusters, which lie all over
  // the mesh: scattered reads again, as in the rounds (dragon ×121 → 1M inside 2 GiB: the check
  // read 5.3 GB with the kernel's read-around, 0.2 GB without, in the same 3.3 s).
  scattered.emplace(mesh);
  std::vector<int32_t> relax_bad = tracker.check_changes(labels, editor.take_log());
  // Where the relaxation made a defect, its moves are undone, group by group: the clusters
  // joined by moves between them form a group, and a group with a defective cluster goes back
  // to its members before the relaxation, whole (so every cluster stays as connected as it was).
  // Undoing it all made every split half and merged pair keep its unrelaxed shape whenever one
  // defect appeared anywhere (crude dragon subdivided 8x8 -> 100,000: relaxation always
  // refused).
  for (int attempt = 0; attempt < 4 && (!relax_bad.empty() || count_change() != change); ++attempt)
    relax_bad = undo_moves_of_groups(mesh, moved, relax_bad, count_change() != change, K, editor, tracker, labels);
  if (relax_bad.empty() && count_change() == change) {
    result.relaxed = true;
  } else {
    for (const auto& m : moved)
      for (const detail::LabelChange& ch : m)
        if (labels[ch.vertex] != ch.old_label) editor.set(ch.vertex, ch.old_label);
    tracker.check_changes(labels, editor.take_log());
  }
  result.defect_vertices = tracker.defect_vertices();
  result.unjoined_pairs = tracker.unjoined_pairs();
  result.dual_faces = tracker.take_triples();
  result.repair_seconds += seconds_since(t);
  return result;
}

}  // namespace streamcvd
