// Parallel boundary-edge clustering (DESIGN.md §4). See core/clustering/parallel_clustering.h.
//
// Why the parallel loop converges (both modes). Sites are fixed during a loop (Q offsets are
// only re-solved between loops, for at most offset_update_loops loops, as in the serial loop).
// At fixed sites the energy is a sum of per-cluster terms, and a move of one vertex from a to b
// changes only L_a + L_b. A move is committed only while its thread holds both clusters
// exclusively (both locked, or owned by its region, or one of each), after re-reading both
// labels under that hold, and it is evaluated on the accumulators of exactly those two clusters:
// so the evaluated ΔE is the true change of the total energy, and move_gain() only accepts a
// decrease larger than a relative margin. Moves of other threads touch other clusters and
// commute with it. Hence every committed move strictly lowers the energy; the energy is bounded
// below (≥ 0) and there are finitely many labellings, so only finitely many moves can be
// committed and some loop commits none: the pass stops. Nothing is evaluated against a stale
// snapshot of a cluster (no Jacobi-style batch moves), which could raise the energy.
//
// Visits (DESIGN.md §4). A round visits every region with candidates; a visit sweeps the
// region's candidate vertices again and again until a sweep moves nothing (or kMaxSweeps), so a
// region converges while its data is hot in the caches (and, out of core, resident) instead of
// being swept once per global loop. Moves that list vertices of other regions go to those
// regions' lists between rounds. Rounds repeat until a round moves fewer than stop_fraction·V
// items. The modified-clusters skip is kept through stamps: a vertex is tested in a sweep only if
// its cluster changed since its region's previous sweep began. Default mode stamps changes with
// the global sweep clock (conservative: a change is never missed); deterministic mode with
// per-phase, per-region sweep numbers, which depend on nothing but the region's own work.
//
// Holding a cluster: label[v] changes only while both its old and its new cluster are held, so
// a thread holding cluster a sees a fixed member set of a. That is also what the constrained
// pass's 1-ring test needs: it asks which neighbours of v are in a (held); moves between other
// clusters cannot change the answer.
#include "streamcvd/core/clustering/parallel_clustering.h"

#include <tbb/global_control.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <thread>

#include "streamcvd/core/clustering/connectivity_check.h"
#include "streamcvd/core/clustering/loop_regions.h"
#include "streamcvd/core/clustering/parallel_blocks.h"
#include "streamcvd/core/mesh/timer.h"

namespace streamcvd {

namespace {

using detail::allocate_partition;
using detail::Census;
using detail::for_each_block;
using detail::for_each_region;
using detail::make_census;
using detail::mark_vertex;
using detail::Partition;
using detail::region_bounds;
using detail::shifted_bounds;
using detail::tls_threads;

constexpr int32_t kShared = -1;  // owner of a cluster that no single region holds alone
constexpr uint32_t kNone = UINT32_MAX;
constexpr size_t kSerialBelow = 2048;  // candidate vertices below which a sweep runs on one thread

// Labels are read outside the locks by other threads: every access is atomic (relaxed; the
// cluster locks order the accumulators, and a label is re-read after locking).
inline int32_t load_label(int32_t* labels, uint32_t v) {
  return std::atomic_ref<int32_t>(labels[v]).load(std::memory_order_relaxed);
}
inline void store_label(int32_t* labels, uint32_t v, int32_t c) {
  std::atomic_ref<int32_t>(labels[v]).store(c, std::memory_order_relaxed);
}

// One spin lock per cluster, alone on its cache line so that two threads locking neighbouring
// cluster ids do not contend on one line. Only try_lock: a busy cluster postpones the edge.
struct alignas(64) ClusterLock {
  std::atomic<uint8_t> held{0};
  bool try_lock() {
    return held.load(std::memory_order_relaxed) == 0 && held.exchange(1, std::memory_order_acquire) == 0;
  }
  void unlock() { held.store(0, std::memory_order_release); }
};

// The work of one region in one phase.
struct RegionWork {
  std::vector<uint32_t> cand;       // candidates in the region's range; after the phase, the kept ones
  std::vector<uint32_t> outbox;     // vertices of other regions to put on the candidate list
  std::vector<uint32_t> postponed;  // vertices with an edge left for the serial pass
  uint32_t last_sweep = 1;          // stamp of the region's previous sweep (see the skip rule)
  uint64_t moves = 0;               // moves of the current visit
  uint32_t sweeps = 0;              // sweeps of the current visit
};

// Sweeps of one visit at most: a region that still moves after this many waits for the next
// round (its neighbours' frontiers have changed meanwhile anyway).
constexpr uint32_t kMaxSweeps = 64;
// A visit testing fewer than 1/kSparseVisit of its region's vertices reads their pages on demand.
// (Candidates lie along the clusters that moved: 1/2048 read 25% more at 105M faces.)
constexpr size_t kSparseVisit = 32;

template <bool kAniso, bool kOffsets>
class ParallelLoop {
 public:
  ParallelLoop(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels, ClusterState& state,
               const LoopOptions& options, ArrayStorage& storage)
      : mesh_(mesh), items_(items), labels_(labels.data()), state_(state), options_(options), storage_(storage),
        K_(state.cluster_count()), changed_in_(K_), owner_(K_), listed_(mesh.vertex_count(), storage, "candidate marks") {
    if (!options.deterministic) locks_ = std::vector<ClusterLock>(K_);
  }

  uint32_t run(ClusteringReport& report, std::span<const uint8_t> initially_active, uint32_t threads,
               std::vector<uint8_t>* unsettled);

 private:
  MoveDelta delta(uint32_t item, int32_t from, int32_t to) const {
    if constexpr (kAniso) return aniso_move_delta<kOffsets>(items_, state_, item, from, to);
    else return iso_move_delta<kOffsets>(items_, state_, item, from, to);
  }

  // Stamp of a change made now by a sweep stamped `sweep` (see the file comment).
  uint32_t change_stamp(uint32_t sweep) const {
    return options_.deterministic ? sweep : clock_.load(std::memory_order_relaxed);
  }

  // The edge test of Algorithm 1 on (v, k) with a = label(v) ≠ b = label(k), both clusters held
  // by the caller: the same evaluation as the serial loop (F1: k joins a, F2: v joins b).
  // Returns the moved vertex or kNone; `blocked` when the better move was not allowed.
  [[gnu::flatten]] uint32_t test_edge(uint32_t v, uint32_t k, int32_t a, int32_t b, uint32_t sweep, bool k_may_join_a,
                                      bool v_may_join_b, bool& blocked) {
    auto label_of = [this](uint32_t u) { return load_label(labels_, u); };
    double gain1 = 0, gain2 = 0;
    if (state_.iso[b].count > 1) gain1 = move_gain(delta(k, b, a));
    if (state_.iso[a].count > 1) gain2 = move_gain(delta(v, a, b));
    if (options_.constrained) {
      if (gain1 > 0 && !detail::removal_keeps_connected(mesh_, label_of, k, b)) gain1 = 0;
      if (gain2 > 0 && !detail::removal_keeps_connected(mesh_, label_of, v, a)) gain2 = 0;
    }
    if (gain1 <= 0 && gain2 <= 0) return kNone;
    const bool move_k = gain1 >= gain2;
    if (move_k ? !k_may_join_a : !v_may_join_b) {
      blocked = true;
      return kNone;
    }
    if (move_k) {
      apply_move(items_, state_, k, b, a);
      store_label(labels_, k, a);
    } else {
      apply_move(items_, state_, v, a, b);
      store_label(labels_, v, b);
    }
    for (size_t i = 0; i < partitions_.size(); ++i)
      census_[i].move(partitions_[i], move_k ? k : v, move_k ? b : a, move_k ? a : b);
    const uint32_t stamp = change_stamp(sweep);
    changed_in_[a].store(stamp, std::memory_order_relaxed);
    changed_in_[b].store(stamp, std::memory_order_relaxed);
    return move_k ? k : v;
  }

  void compute_owners(const Census& census);
  uint64_t sweep_region(const Partition& p, uint32_t r, RegionWork& w, uint32_t sweep);
  void visit_region(const Partition& p, uint32_t r, RegionWork& w);
  uint64_t serial_pass(uint32_t sweep);
  void list_serially(uint32_t u);
  void rebucket(size_t target);

  const MeshView& mesh_;
  const ItemData& items_;
  int32_t* labels_;
  ClusterState& state_;
  const LoopOptions& options_;
  ArrayStorage& storage_;
  const uint32_t K_;
  std::vector<std::atomic<uint32_t>> changed_in_;  // stamp of the cluster's last change
  std::vector<std::atomic<int32_t>> owner_;        // region owning the cluster, or kShared
  std::vector<ClusterLock> locks_;                 // default mode only
  LargeArray<uint8_t> listed_;                     // on the candidate list; written by the vertex's region
  std::atomic<uint32_t> clock_{2};                 // default mode: stamps of sweeps (1 = initially active)
  uint32_t phase_base_ = 0;                        // deterministic mode: stamps of this phase start here
  std::vector<RegionWork> works_;                  // candidate lists by region of partitions_[current_]
  size_t current_ = 0;
  std::vector<Partition> partitions_;              // one (default) or two (deterministic)
  std::vector<Census> census_;                     // per partition; updated under the cluster holds
};

// owner[c] = r when every vertex of c is interior to region r, else kShared: O(K) from the
// census, the same whatever the thread count.
template <bool kAniso, bool kOffsets>
void ParallelLoop<kAniso, kOffsets>::compute_owners(const Census& census) {
  auto owner_of = [&](uint32_t c) {
    const uint64_t n = state_.iso[c].count;
    int32_t owner = kShared;
    if (n > 0 && census.boundary[c] == 0 && census.sum[c] % n == 0) {
      const uint64_t r = census.sum[c] / n;
      if (census.sum2[c] == n * r * r) owner = int32_t(r);
    }
    owner_[c].store(owner, std::memory_order_relaxed);
  };
  // A fork-join costs more than ~10^5 of these O(1) tests.
  if (K_ < (1u << 17)) {
    for (uint32_t c = 0; c < K_; ++c) owner_of(c);
  } else {
    for_each_block(K_, 1u << 14, owner_of);
  }
}

// One sweep of region r over its candidates, stamped `sweep`: a candidate is tested when its
// cluster changed since the region's previous sweep began (w.last_sweep), else parked. Returns
// the moves.
template <bool kAniso, bool kOffsets>
uint64_t ParallelLoop<kAniso, kOffsets>::sweep_region(const Partition& p, uint32_t r, RegionWork& w, uint32_t sweep) {
  const uint32_t first = p.begin[r], last = p.begin[r + 1];
  const int32_t me = int32_t(r);
  uint64_t moves = 0;
  auto list_vertex = [&](uint32_t u) {
    if (u < first || u >= last) w.outbox.push_back(u);
    else if (!listed_[u]) {
      listed_[u] = 1;
      w.cand.push_back(u);
    }
  };
  size_t kept = 0;
  // Vertices appended during this sweep are tested in it too (as Algorithm 1's FIFO does).
  for (size_t i = 0; i < w.cand.size(); ++i) {
    const uint32_t v = w.cand[i];
    const int32_t a0 = load_label(labels_, v);
    if (a0 < 0) {
      listed_[v] = 0;
      continue;
    }
    if (options_.skip_unchanged && changed_in_[a0].load(std::memory_order_relaxed) < w.last_sweep) {
      w.cand[kept++] = v;  // parked: its cluster did not change since the previous sweep began
      continue;
    }
    bool boundary = false, postpone = false;
    for (uint32_t k : mesh_.neighbours(v)) {
      const int32_t a = load_label(labels_, v), b = load_label(labels_, k);
      if (b < 0 || a == b) continue;
      boundary = true;
      const int32_t oa = owner_[a].load(std::memory_order_relaxed), ob = owner_[b].load(std::memory_order_relaxed);
      const bool own_a = oa == me, own_b = ob == me;
      // Deterministic: only edges between two clusters of this region. Default: clusters of
      // other regions are theirs alone (cannot happen while ownership holds; kept as a guard).
      if (options_.deterministic ? !(own_a && own_b) : ((oa != me && oa != kShared) || (ob != me && ob != kShared))) {
        postpone = true;
        continue;
      }
      // Lock the shared clusters in id order; never wait (a busy cluster postpones the edge).
      ClusterLock* held[2] = {nullptr, nullptr};
      if (!own_a || !own_b) {
        int32_t lo = own_a ? b : own_b ? a : std::min(a, b), hi = own_a || own_b ? -1 : std::max(a, b);
        if (!locks_[lo].try_lock()) {
          postpone = true;
          continue;
        }
        held[0] = &locks_[lo];
        if (hi >= 0) {
          if (!locks_[hi].try_lock()) {
            held[0]->unlock();
            postpone = true;
            continue;
          }
          held[1] = &locks_[hi];
        }
      }
      bool blocked = false;
      uint32_t moved = kNone;
      // Re-read under the locks: another thread may have moved v or k meanwhile (it then put
      // them back on the candidate lists itself).
      if (load_label(labels_, v) == a && load_label(labels_, k) == b)
        // An owned cluster only takes region-interior vertices, so it stays owned: no other
        // region ever sees it.
        moved = test_edge(v, k, a, b, sweep, !own_a || p.interior[k], !own_b || p.interior[v], blocked);
      if (held[1]) held[1]->unlock();
      if (held[0]) held[0]->unlock();
      postpone |= blocked;
      if (moved != kNone) {
        ++moves;
        list_vertex(moved);
        for (uint32_t n : mesh_.neighbours(moved)) list_vertex(n);
      }
    }
    if (postpone) w.postponed.push_back(v);
    if (boundary) w.cand[kept++] = v;
    else listed_[v] = 0;
  }
  w.cand.resize(kept);
  w.last_sweep = sweep;
  return moves;
}

// A visit: sweeps until one moves nothing (the region is quiet) or kMaxSweeps.
template <bool kAniso, bool kOffsets>
void ParallelLoop<kAniso, kOffsets>::visit_region(const Partition& p, uint32_t r, RegionWork& w) {
  w.outbox.clear();
  w.moves = 0;
  w.sweeps = 0;
  if (w.cand.empty()) return;
  // Read ahead the region's adjacency only when enough of its candidates will be tested: a
  // visit whose candidates are nearly all parked (the repair's relaxation, the late rounds)
  // reads a few pages, and out of core the read-ahead made it read the whole region (dragon
  // ×121 in 2 GiB: 63 GB read by the repair). Residency only: the work is the same.
  size_t live = 0;
  for (uint32_t v : w.cand) {
    const int32_t a = load_label(labels_, v);
    live += a >= 0 && (!options_.skip_unchanged || changed_in_[a].load(std::memory_order_relaxed) >= w.last_sweep);
  }
  const bool sparse = live * kSparseVisit < size_t(p.begin[r + 1] - p.begin[r]);
  const RangeVisit visit(mesh_, "clustering", {p.begin[r], p.begin[r + 1]}, sparse ? 0 : kReadsNeighbours);
  // Deterministic mode sweeps once per visit: its regions leave the clusters they share to the
  // other partition and the serial pass, so iterating them alone to quiet would converge the
  // interiors and stop the rounds before the frontiers have.
  const uint32_t max_sweeps = options_.deterministic ? 1 : kMaxSweeps;
  for (uint32_t local = 1; local <= max_sweeps; ++local) {
    const uint32_t sweep =
        options_.deterministic ? phase_base_ + local : clock_.fetch_add(1, std::memory_order_relaxed) + 1;
    const uint64_t moves = sweep_region(p, r, w, sweep);
    w.moves += moves;
    ++w.sweeps;
    if (moves == 0) break;
  }
}

// Puts u on the candidate list of its region (serial code only).
template <bool kAniso, bool kOffsets>
void ParallelLoop<kAniso, kOffsets>::list_serially(uint32_t u) {
  if (!listed_[u]) {
    listed_[u] = 1;
    works_[partitions_[current_].region[u]].cand.push_back(u);
  }
}

// Postponed vertices, region by region in list order, on one thread (no locks needed: nothing
// else runs): the fixed order keeps the deterministic mode deterministic.
template <bool kAniso, bool kOffsets>
uint64_t ParallelLoop<kAniso, kOffsets>::serial_pass(uint32_t sweep) {
  uint64_t moves = 0;
  for (size_t r = 0; r < works_.size(); ++r) {
    std::vector<uint32_t> postponed = std::move(works_[r].postponed);
    works_[r].postponed.clear();
    for (uint32_t v : postponed)
      for (uint32_t k : mesh_.neighbours(v)) {
        const int32_t a = labels_[v], b = labels_[k];
        if (a < 0 || b < 0 || a == b) continue;
        bool blocked = false;
        const uint32_t moved = test_edge(v, k, a, b, sweep, true, true, blocked);
        if (moved == kNone) continue;
        ++moves;
        list_serially(moved);
        for (uint32_t n : mesh_.neighbours(moved)) list_serially(n);
      }
  }
  return moves;
}

// Re-buckets the candidate lists by the regions of partitions_[target], keeping their order
// (deterministic mode: the two partitions alternate). Each target region reads the lists of
// the source regions its range overlaps.
template <bool kAniso, bool kOffsets>
void ParallelLoop<kAniso, kOffsets>::rebucket(size_t target) {
  const Partition& from = partitions_[current_];
  const Partition& to = partitions_[target];
  std::vector<RegionWork> next(to.size());
  for_each_region(to.size(), [&](uint32_t r) {
    const uint32_t first = to.begin[r], last = to.begin[r + 1];
    if (first == last) return;
    uint32_t stamp = ~0u;  // the oldest previous sweep among the source lists: never skips too much
    for (uint32_t s = from.region[first]; s <= from.region[last - 1]; ++s) {
      stamp = std::min(stamp, works_[s].last_sweep);
      for (uint32_t v : works_[s].cand)
        if (v >= first && v < last) next[r].cand.push_back(v);
    }
    next[r].last_sweep = stamp == ~0u ? 1 : stamp;
  });
  works_ = std::move(next);
  current_ = target;
}

template <bool kAniso, bool kOffsets>
uint32_t ParallelLoop<kAniso, kOffsets>::run(ClusteringReport& report, std::span<const uint8_t> initially_active,
                                            uint32_t threads, std::vector<uint8_t>* unsettled) {
  const uint32_t V = mesh_.vertex_count();
  const auto t0 = std::chrono::steady_clock::now();
  // Region size: several regions per thread for load balance; in deterministic mode a function
  // of V only, so that the result does not depend on the thread count, and larger: every
  // region border postpones edges to the serial pass.
  uint32_t length = options_.region_vertices;
  if (length == 0)
    length = options_.deterministic ? std::max<uint32_t>(16384, V / 1024) : std::max<uint32_t>(1024, V / (16 * threads));
  std::vector<Partition>& partitions = partitions_;
  partitions.push_back(allocate_partition(V, region_bounds(mesh_, length), storage_));
  if (options_.deterministic) partitions.push_back(allocate_partition(V, shifted_bounds(partitions[0].begin), storage_));
  for (uint32_t c = 0; c < K_; ++c)
    changed_in_[c].store(initially_active.empty() || initially_active[c] ? 1 : 0, std::memory_order_relaxed);
  // One pass over the neighbour lists, by region of the first partition, marks the vertices'
  // regions and lists the initial candidates: every vertex on a cluster boundary. (Out of core
  // each pass over the lists reads them from disk: 1.7 GB at 105M faces.)
  works_.assign(partitions[0].size(), RegionWork{});
  for_each_region(partitions[0].size(), [&](uint32_t r) {
    const uint32_t first = partitions[0].begin[r], last = partitions[0].begin[r + 1];
    const RangeVisit visit(mesh_, "clustering", {first, last}, kReadsNeighbours);
    uint32_t shifted = 0;  // region of the second partition holding v
    if (partitions.size() > 1)
      while (partitions[1].begin[shifted + 1] <= first) ++shifted;
    for (uint32_t v = first; v < last; ++v) {
      const auto nb = mesh_.neighbours(v);
      mark_vertex(partitions[0], r, v, nb);
      if (partitions.size() > 1) {
        while (partitions[1].begin[shifted + 1] <= v) ++shifted;
        mark_vertex(partitions[1], shifted, v, nb);
      }
      const int32_t a = labels_[v];
      if (a < 0) continue;
      for (uint32_t n : nb)
        if (labels_[n] >= 0 && labels_[n] != a) {
          works_[r].cand.push_back(v);
          listed_[v] = 1;
          break;
        }
    }
  });
  for (const Partition& p : partitions) census_.push_back(make_census(mesh_, p, std::span<const int32_t>(labels_, V), K_));

  uint32_t rounds = 0;
  phase_base_ = 2;  // deterministic stamps: 0 stable, 1 initially active, then phase_base_ + sweep
  uint32_t previous_round_start = 1;
  uint64_t last_moves = 0;
  for (; rounds < options_.max_loops;) {
    ++rounds;
    const uint32_t round_start = options_.deterministic ? phase_base_ : clock_.load(std::memory_order_relaxed);
    uint64_t moves = 0;
    for (size_t i = 0; i < partitions.size(); ++i) {
      if (current_ != i) rebucket(i);
      compute_owners(census_[i]);
      // Deterministic: a vertex is tested when its cluster changed in this round or the previous
      // one, in both phases (its clusters may have been another partition's to change).
      if (options_.deterministic)
        for (RegionWork& w : works_) w.last_sweep = previous_round_start;
      size_t pending = 0;
      for (const RegionWork& w : works_) pending += w.cand.size();
      auto visit = [&](uint32_t r) { visit_region(partitions[i], r, works_[r]); };
      // A short list (the late rounds) is not worth waking the other threads.
      if (pending < kSerialBelow) {
        for (uint32_t r = 0; r < works_.size(); ++r) visit(r);
      } else {
        for_each_region(uint32_t(works_.size()), visit);
      }
      // Outboxes in region order (deterministic): the next round tests them.
      for (RegionWork& w : works_) {
        moves += w.moves;
        for (uint32_t u : w.outbox) list_serially(u);
        w.outbox.clear();
      }
      if (options_.deterministic) phase_base_ += kMaxSweeps + 2;
    }
    const uint32_t serial_stamp = options_.deterministic ? phase_base_++ : clock_.fetch_add(1) + 1;
    moves += serial_pass(serial_stamp);
    report.moves_per_loop.push_back(moves);
    report.energy_per_loop.push_back(state_energy(items_, state_));
    if (kOffsets && moves > 0 && rounds < options_.offset_update_loops) {
      for_each_block(K_, 1024, [&](uint32_t c) {
        if (changed_in_[c].load(std::memory_order_relaxed) >= round_start) update_site_offset(state_, c);
      });
    }
    report.seconds_per_loop.push_back(seconds_since(t0));
    if (options_.on_loop) options_.on_loop(options_.constrained, rounds, moves);
    previous_round_start = round_start;
    last_moves = moves;
    if (moves == 0 || double(moves) < options_.stop_fraction * double(V)) break;
  }
  if (unsettled) {  // the clusters the last round changed: their boundaries were not tested since
    unsettled->assign(K_, 0);
    if (last_moves > 0)
      for (uint32_t c = 0; c < K_; ++c)
        (*unsettled)[c] = changed_in_[c].load(std::memory_order_relaxed) >= previous_round_start;
  }
  return rounds;
}

template <bool kAniso, bool kOffsets>
uint32_t run_loops(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels, ClusterState& state,
                   const LoopOptions& options, ClusteringReport& report, std::span<const uint8_t> initially_active,
                   uint32_t threads, std::vector<uint8_t>* unsettled) {
  ParallelLoop<kAniso, kOffsets> loop(mesh, items, labels, state, options,
                                      options.storage ? *options.storage : ram_storage());
  return loop.run(report, initially_active, threads, unsettled);
}

}  // namespace

uint32_t run_clustering_loops(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                              ClusterState& state, const LoopOptions& options, ClusteringReport& report,
                              std::span<const uint8_t> initially_active, std::vector<uint8_t>* unsettled) {
  const uint32_t threads = clustering_thread_count(options.threads);
  tbb::task_arena arena(int(std::min<uint32_t>(threads, 4096)));
  const ScatteredReads scattered(mesh);  // after the first round only candidates' pages are read
  uint32_t loops = 0;
  tls_threads = threads;
  arena.execute([&] {
    // One instantiation per (anisotropic, Q offsets) pair, chosen from the state.
    auto run = [&]<bool kAniso, bool kOffsets>() {
      return run_loops<kAniso, kOffsets>(mesh, items, labels, state, options, report, initially_active, threads,
                                         unsettled);
    };
    const bool aniso = !state.aniso.empty(), offsets = state.use_offsets;
    if (aniso)
      loops = offsets ? run.operator()<true, true>() : run.operator()<true, false>();
    else
      loops = offsets ? run.operator()<false, true>() : run.operator()<false, false>();
  });
  return loops;
}

}  // namespace streamcvd
