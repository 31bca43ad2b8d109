// The connected pieces of the clusters, by the chunk-wise union-find (core/mesh/chunked_components.h):
// the cleaning step (§VI-B, Fig. 6: each cluster keeps its heaviest piece) and the connectivity
// check. Memory: one range of the mesh per thread plus one component id per vertex from the
// caller's storage; no V-sized union-find in RAM.
#include <atomic>

#include "streamcvd/core/mesh/chunked_components.h"
#include "streamcvd/core/clustering/clustering.h"
#include "streamcvd/core/clustering/parallel_clustering.h"

namespace streamcvd {
namespace {

std::vector<VertexRange> ranges_of(const MeshView& mesh) {
  if (!mesh.chunks.empty()) return chunk_ranges(mesh.chunks);
  if (mesh.vertex_count() == 0) return {};
  return {VertexRange{0, mesh.vertex_count()}};
}

// Joins every labelled vertex of the range to its same-label neighbours: the pieces.
RangeFill same_label_joins(const MeshView& mesh, std::span<const int32_t> labels) {
  return [&mesh, labels](size_t, VertexRange range, RangePieceBuilder& b) {
    const RangeVisit visit(mesh, "cleaning", range, kReadsNeighbours);
    for (uint32_t v = range.begin; v < range.end; ++v) {
      const int32_t l = labels[v];
      if (l < 0) continue;
      b.add(v);
      for (uint32_t n : mesh.neighbours(v))
        if (labels[n] == l && !(n < v && range.contains(n))) b.join(v, n);  // inside: once per edge
    }
  };
}

}  // namespace

uint64_t clean_clusters(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                        uint32_t cluster_count, ClusteringReport& report, ArrayStorage& storage,
                        std::vector<uint8_t>* changed) {
  const std::vector<VertexRange> ranges = ranges_of(mesh);
  LargeArray<uint32_t> piece(mesh.vertex_count(), storage, "cluster pieces");
  const ComponentTable table = chunked_component_labels(ranges, same_label_joins(mesh, labels), piece.span());
  // Weights in vertex order (the same sums for any thread count); each cluster keeps its
  // heaviest piece, the first in vertex order on a tie (pieces are numbered by their first vertex).
  std::vector<double> weight(table.components, 0.0);
  std::vector<int32_t> cluster_of_piece(table.components, -1);
  for (uint32_t v = 0; v < mesh.vertex_count(); ++v)
    if (labels[v] >= 0) weight[piece[v]] += items.weight[v], cluster_of_piece[piece[v]] = labels[v];
  std::vector<uint32_t> best(cluster_count, UINT32_MAX), pieces(cluster_count, 0);
  for (uint32_t p = 0; p < table.components; ++p) {
    const int32_t l = cluster_of_piece[p];
    if (l < 0) continue;
    ++pieces[l];
    if (best[l] == UINT32_MAX || weight[p] > weight[best[l]]) best[l] = p;
  }
  for (uint32_t c = 0; c < cluster_count; ++c) report.disconnected_clusters += pieces[c] > 1;
  std::vector<uint32_t> freed;  // the vertices reset (a few per thousand)
  for (uint32_t v = 0; v < mesh.vertex_count(); ++v)
    if (labels[v] >= 0 && best[labels[v]] != piece[v]) {
      if (changed) (*changed)[labels[v]] = 1;
      labels[v] = -1;
      freed.push_back(v);
    }
  if (!freed.empty()) absorb_free_vertices(mesh, labels);
  if (changed)
    for (uint32_t v : freed)
      if (labels[v] >= 0) (*changed)[labels[v]] = 1;
  report.cleaned_vertices += freed.size();
  return freed.size();
}

bool clusters_connected(const MeshView& mesh, std::span<const int32_t> labels, uint32_t cluster_count) {
  const std::vector<VertexRange> ranges = ranges_of(mesh);
  const ComponentTable table = chunked_components(ranges, same_label_joins(mesh, labels));
  std::vector<uint8_t> used(cluster_count, 0);
  uint64_t non_empty = 0;
  for (uint32_t v = 0; v < mesh.vertex_count(); ++v)
    if (labels[v] >= 0 && !used[labels[v]]) used[labels[v]] = 1, ++non_empty;
  return table.components == non_empty;  // one piece per non-empty cluster
}

}  // namespace streamcvd
