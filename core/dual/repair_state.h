// The label state the parts of the repair loop share (core/dual/repair.cpp drives them): every
// label write goes through a LabelEditor, which keeps the cluster → vertices index current and
// logs (vertex, old label) for the defect tracker (core/dual/defect_tracker.h); ClusterSet is
// the K-sized flag set that the tracker and the repair round clear at the cost of what they set.
// Internal to core/dual. Not thread-safe: one repair loop owns them.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "streamcvd/core/clustering/cluster_members.h"
#include "streamcvd/core/mesh/large_array.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd::detail {

/// A defective cluster whose dual vertex is two or more closed fans: a band round a thin feature
/// (DefectTracker::rings). `sides`: the clusters of its two largest fans, sorted (ids ≥ K are
/// strip vertices).
struct Ring {
  int32_t cluster = -1;
  std::array<std::vector<int32_t>, 2> sides;
};

struct LabelChange {
  uint32_t vertex;
  int32_t old_label;
};

/// Every label the repair writes: the labels themselves, the cluster → vertices index, the log
/// of (vertex, old label) since the last check, and the clusters whose members changed since
/// their per-cluster figures were last refreshed. O(1) per change (amortised); memory: the
/// index (4 bytes per vertex from `storage`) plus K bytes.
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
  /// labels[v] was written by someone else (a split, the relaxation); `old` was its label.
  void note(uint32_t v, int32_t old) {
    const int32_t now = labels_[v];
    if (old == now) return;
    log_.push_back({v, old});
    members_.moved(v, old, now);
    mark_stale(old);
    mark_stale(now);
  }
  /// The changes since the last call, in order (a vertex may appear several times).
  std::vector<LabelChange> take_log() { return std::exchange(log_, {}); }
  /// The clusters whose members changed since the last call.
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

/// A K-sized flag set that lists its members, so that clearing costs what was set. insert and
/// contains O(1); K bytes.
class ClusterSet {
 public:
  explicit ClusterSet(uint32_t K) : in_(K, 0) {}
  /// Adds c (ignored when negative); true when it was not in the set.
  bool insert(int32_t c) {
    if (c < 0 || in_[c]) return false;
    in_[c] = 1;
    list_.push_back(c);
    return true;
  }
  bool contains(int32_t c) const { return in_[c] != 0; }
  /// The members, in insertion order.
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

}  // namespace streamcvd::detail
