#include "streamcvd/core/mesh/vertex_attributes.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <stdexcept>
#include <string>

#include "streamcvd/core/clustering/item_data.h"

namespace streamcvd {

namespace {

// Vertices per range: the unit of the sums' order (fixed, never the thread count's choice).
constexpr uint32_t kRange = 1u << 14;
constexpr uint32_t kNoSlot = UINT32_MAX;

// The sums of one range: the clusters it met (in order of their first vertex), for each its
// first vertex, and (area, area·value per column) per cluster.
struct RangeSums {
  std::vector<uint32_t> clusters, first;
  std::vector<double> sums;
};

// Cluster id → its slot in the sums of the range being summed: open addressing over twice the
// most clusters a range can meet, so a thread's table is 256 KiB whatever K is (a K-sized table
// per thread would be 4 MiB each at K = 1M). Cleared after each range through the clusters met.
class SlotTable {
 public:
  static constexpr uint32_t kSize = 2 * kRange;  // a power of two
  SlotTable() : key_(kSize, kNoSlot), slot_(kSize) {}
  /// The slot of cluster c; `next` (and inserted = true) when c is new.
  uint32_t find_or_insert(uint32_t c, uint32_t next, bool& inserted) {
    uint32_t at = (c * 0x9E3779B1u) >> (32 - kLog2Size);  // Fibonacci hashing
    while (key_[at] != kNoSlot && key_[at] != c) at = (at + 1) & (kSize - 1);
    inserted = key_[at] == kNoSlot;
    if (inserted) key_[at] = c, slot_[at] = next;
    return slot_[at];
  }
  /// Empties the table that holds exactly `clusters`. Entries never move, so each is found by
  /// walking its probe chain past the ones already emptied.
  void clear(std::span<const uint32_t> clusters) {
    for (uint32_t c : clusters) {
      uint32_t at = (c * 0x9E3779B1u) >> (32 - kLog2Size);
      while (key_[at] != c) at = (at + 1) & (kSize - 1);
      key_[at] = kNoSlot;
    }
  }

 private:
  static constexpr uint32_t kLog2Size = 15;
  static_assert(kSize == 1u << kLog2Size);
  std::vector<uint32_t> key_, slot_;
};

// What a thread reuses from range to range: the slot table and the range's growing sums.
struct Scratch {
  SlotTable slots;
  RangeSums sums;
};

}  // namespace

std::vector<float> cluster_attribute_means(const MeshView& mesh, std::span<const int32_t> labels, uint32_t cluster_count,
                                           const VertexAttributeColumns& attributes) {
  const size_t A = attributes.columns.size(), row = A + 1;
  std::vector<float> means(cluster_count * A, 0.0f);
  if (A == 0 || cluster_count == 0) return means;
  const uint32_t V = uint32_t(std::min<size_t>(mesh.vertex_count(), labels.size()));
  if (attributes.values.size() < size_t(V) * attributes.stride ||
      *std::max_element(attributes.columns.begin(), attributes.columns.end()) >= attributes.stride)
    throw std::invalid_argument("vertex attributes: " + std::to_string(attributes.values.size()) + " values for " +
                                std::to_string(V) + " vertices of " + std::to_string(attributes.stride) +
                                " columns, or a column out of range");
  const uint32_t ranges = (V + kRange - 1) / kRange;
  const float* values = attributes.values.data();
  const size_t stride = attributes.stride;
  const uint32_t* columns = attributes.columns.data();
  const double origin[3] = {0, 0, 0};  // areas only: they depend on corner differences, not on the frame

  std::vector<RangeSums> partial(ranges);
  tbb::enumerable_thread_specific<Scratch> scratch;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, ranges, 1), [&](const tbb::blocked_range<uint32_t>& r) {
    Scratch& s = scratch.local();
    for (uint32_t i = r.begin(); i != r.end(); ++i) {
      const VertexRange range{i * kRange, std::min(V, (i + 1) * kRange)};
      const RangeVisit visit(mesh, "attributes", range, kReadsPositions | kReadsTriangles | kReadsVertexFaces);
      RangeSums& local = s.sums;
      local.clusters.clear();
      local.first.clear();
      local.sums.clear();
      for (uint32_t v = range.begin; v != range.end; ++v) {
        const int32_t c = labels[v];
        if (c < 0 || uint32_t(c) >= cluster_count) continue;
        bool inserted = false;
        const uint32_t slot = s.slots.find_or_insert(uint32_t(c), uint32_t(local.clusters.size()), inserted);
        if (inserted) {  // capacity kept from earlier ranges: growth is rare
          local.clusters.push_back(uint32_t(c));
          local.first.push_back(v);
          local.sums.resize(local.sums.size() + row, 0.0);
        }
        double area = 0;
        for_each_dual_cell_part(mesh, v, origin, [&](double cell, const double*, const double*, const double*,
                                                     const double*) { area += cell; });
        double* sum = &local.sums[size_t(slot) * row];
        sum[0] += area;
        const float* x = values + size_t(v) * stride;
        for (size_t k = 0; k < A; ++k) sum[1 + k] += area * double(x[columns[k]]);
      }
      s.slots.clear(local.clusters);
      partial[i] = local;  // one copy per range, sized by the clusters it met
    }
  });

  // Ranges in order, each cluster's partial sums added in that order.
  std::vector<double> total(cluster_count * row, 0.0);
  std::vector<uint32_t> first(cluster_count, kNoSlot);
  for (RangeSums& p : partial) {
    for (size_t j = 0; j < p.clusters.size(); ++j) {
      const uint32_t c = p.clusters[j];
      if (first[c] == kNoSlot) first[c] = p.first[j];
      for (size_t k = 0; k < row; ++k) total[c * row + k] += p.sums[j * row + k];
    }
    p = RangeSums{};
  }
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, cluster_count, kRange), [&](const tbb::blocked_range<uint32_t>& r) {
    for (uint32_t c = r.begin(); c != r.end(); ++c) {
      const double w = total[c * row];
      for (size_t k = 0; k < A; ++k) {
        if (w > 0) means[c * A + k] = float(total[c * row + 1 + k] / w);
        else if (first[c] != kNoSlot) means[c * A + k] = values[size_t(first[c]) * stride + columns[k]];
      }
    }
  });
  return means;
}

std::vector<float> output_vertex_attributes(std::span<const float> cluster_means, const DualMesh& dual,
                                            const VertexAttributeColumns& attributes) {
  const size_t A = attributes.columns.size();
  const uint32_t V_out = dual.mesh.vertex_count();
  std::vector<float> rows(V_out * A, 0.0f);
  if (A == 0) return rows;
  for (uint32_t o = 0; o < V_out; ++o) {
    float* out = &rows[size_t(o) * A];
    const int32_t c = dual.cluster_of_output_vertex[o];
    if (c >= 0) {
      std::copy_n(&cluster_means[size_t(c) * A], A, out);
      continue;
    }
    const VertexSource s = dual.source_of_output_vertex[o];
    auto value = [&](uint32_t i, size_t k) {
      return double(attributes.values[size_t(dual.source_vertices[s.begin + i]) * attributes.stride + attributes.columns[k]]);
    };
    for (size_t k = 0; k < A; ++k) {
      if (s.count == 2) {  // a point of a boundary edge, at t along it
        out[k] = float((1.0 - s.t) * value(0, k) + s.t * value(1, k));
        continue;
      }
      double sum = 0;
      for (uint32_t i = 0; i < s.count; ++i) sum += value(i, k);
      out[k] = s.count > 0 ? float(sum / s.count) : 0.0f;
    }
  }
  return rows;
}

}  // namespace streamcvd
