// Per-vertex input data (colours, confidence, intensity...) carried to a remesh output: each
// output vertex of a cluster gets the area-weighted mean of its cluster's vertices, each
// boundary-strip vertex the value interpolated at the point of the input it lies at (an edge's two
// ends at its place along the edge, a corner's vertex, a closed hole's loop: DualMesh::source_of_output_vertex).
// The means are K-sized sums filled range by range from the V-sized labels while they exist, so
// they work out of core like the other per-cluster passes (core/dual/placement.h).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "streamcvd/core/dual/dual_mesh.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

/// The per-vertex values to carry: `values` holds `stride` floats per input vertex (row-major,
/// in the mesh's vertex order), of which the columns `columns` are carried, in that order.
/// Borrowed: the caller keeps `values` alive.
struct VertexAttributeColumns {
  std::span<const float> values;
  uint32_t stride = 0;
  std::vector<uint32_t> columns;
  bool empty() const { return columns.empty(); }
};

/// Per cluster, the mean of each carried column over its vertices weighted by their dual-cell
/// areas (|P_j| of eq. 10, core/clustering/item_data.h); a cluster of zero area takes its first vertex's
/// values, an empty one zeros. Returns columns.size() floats per cluster (double sums).
/// Parallel over fixed vertex ranges (RangeVisit "attributes"), each summing its clusters in
/// vertex order into sparse partial sums that are added in range order: the same floats for
/// any thread count and storage. Memory: K·(columns + 1) doubles of sums, partial sums of about
/// that size in all, 256 KiB of slot table per thread. O(V·columns + F) work. Throws
/// std::invalid_argument when `values` has fewer than V rows or a column is not below stride.
std::vector<float> cluster_attribute_means(const MeshView& mesh, std::span<const int32_t> labels, uint32_t cluster_count,
                                           const VertexAttributeColumns& attributes);

/// The carried columns of each output vertex of `dual`: its cluster's row of `cluster_means`
/// (from cluster_attribute_means), or for a strip vertex the plain mean of its source input
/// vertices' values (an edge midpoint's two ends, a corner's one vertex, a closed hole's loop).
/// columns.size() floats per output vertex, in output order. O(V_out + strip sources), serial.
std::vector<float> output_vertex_attributes(std::span<const float> cluster_means, const DualMesh& dual,
                                            const VertexAttributeColumns& attributes);

}  // namespace streamcvd
