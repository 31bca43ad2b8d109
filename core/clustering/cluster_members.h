// The vertices of every cluster, for stages that visit a few clusters at a time (the repair:
// DESIGN.md §6) and must not scan all V labels to find them. A CSR cluster → vertices built
// once by a counting sort of the labels, in parallel over runs of chunks, in a LargeArray of the
// job's storage; later label changes are told to it (moved()) and kept as short per-cluster join
// lists, so a cluster's members are its CSR entries still labelled with it plus the vertices
// that joined it. compact() rebuilds the CSR from the labels once the joins pass V/16.
#pragma once

#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

#include "streamcvd/core/mesh/large_array.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

class ClusterMembers {
 public:
  /// Indexes `labels` (V entries, −1 = in no cluster; the span must outlive this object and
  /// every later change must be told to moved()). O(V) time, TBB-parallel over the chunks'
  /// vertex ranges; memory: 4 bytes per vertex from `storage`, 8 per cluster, and transiently
  /// one 4-byte count per cluster and thread (at most 8). Same index for any threads/storage.
  ClusterMembers(const MeshView& mesh, std::span<const int32_t> labels, uint32_t cluster_count,
                 ArrayStorage& storage);

  /// Records that vertex v went from cluster `from` to `to` (either may be −1); labels[v] must
  /// hold `to` already. O(1). Not thread-safe.
  void moved(uint32_t v, int32_t from, int32_t to);
  /// Rebuilds the CSR when the join lists hold more than V/16 vertices (call where the labels
  /// and the moves told agree). Amortised O(1) per join.
  void compact();

  /// The vertices labelled c, ascending, into `out` (cleared first). O(CSR entries of c +
  /// joins of c); thread-safe against other const calls. Throws std::logic_error when the
  /// count disagrees with size(c) (a change that was not told to moved()).
  void members(int32_t c, std::vector<uint32_t>& out) const;

  uint32_t size(int32_t c) const { return size_[size_t(c)]; }
  /// Vertices per cluster (K entries), kept exact through moved().
  std::span<const uint32_t> sizes() const { return size_; }
  uint32_t cluster_count() const { return uint32_t(size_.size()); }
  /// CSR rebuilds so far (the first build excluded).
  uint32_t rebuilds() const { return rebuilds_; }

  /// Rebuilds the CSR from the current labels and drops the join lists. O(V), parallel.
  void rebuild();

 private:
  const MeshView& mesh_;
  std::span<const int32_t> labels_;
  ArrayStorage& storage_;
  std::vector<uint32_t> offsets_;  // K + 1
  LargeArray<uint32_t> vertices_;  // by cluster, ascending within each
  std::vector<uint32_t> size_;
  std::unordered_map<int32_t, std::vector<uint32_t>> joined_;
  uint64_t joined_total_ = 0;
  uint32_t rebuilds_ = 0;
};

}  // namespace streamcvd
