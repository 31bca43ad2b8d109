// Placement of the output vertices on the input surface, and the per-cluster facts the quality
// pass and the checks need from the V-sized labels. Each is one TBB pass over the input's vertices
// in index order ranges (the store's Hilbert order: a range touches a few chunks) writing K-sized
// or output-sized tables; the result does not depend on the thread count.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "streamcvd/core/clustering/clustering.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

/// Moves each cluster's site z[3c..3c+2] to the closest point of the input surface among the
/// triangles having a corner in the cluster (centroids of curved clusters lie off the surface).
/// The closest triangle is the one of least (float32 distance, face id), so ties are broken the
/// same on any thread count. `selected` (size K, or empty = all) limits it to the clusters
/// marked; the others' sites are left as they are. O(V + F) work, parallel; K-sized scratch
/// (8 bytes per cluster).
void project_onto_clusters(const MeshView& mesh, std::span<const int32_t> labels, std::span<double> z,
                           std::span<const uint8_t> selected = {});

/// For each output vertex of a clustering's dual, an input face near it to start the projection
/// walk from: a face of the input vertex of its cluster closest to it (least (float32 squared
/// distance, vertex id)); UINT32_MAX for vertices without a cluster (cluster_of_output_vertex
/// < 0). O(V_in + V_out) work, parallel; 8 bytes per output vertex of scratch.
std::vector<uint32_t> cluster_anchor_faces(const MeshView& surface, std::span<const int32_t> labels,
                                           std::span<const int32_t> cluster_of_output_vertex,
                                           std::span<const float> output_positions);

/// Output vertices of a clustering's dual that a quality pass may move: cluster vertices
/// outside the small components copied as they are (one cluster per input vertex: their
/// triangles are input geometry). Strip vertices (cluster −1) stay. O(V_in + V_out), parallel.
std::vector<uint8_t> remesh_movable_vertices(std::span<const int32_t> labels, const ComponentBudget& budget,
                                             std::span<const int32_t> cluster_of_output_vertex);

/// Per cluster: 1 when its component holds at least `min_clusters` clusters (the repair's
/// compensating merges and splits stay in such components). O(V), parallel; K bytes.
std::vector<uint8_t> clusters_in_large_components(std::span<const int32_t> labels, const ComponentBudget& budget,
                                                  uint32_t cluster_count, uint32_t min_clusters);

/// Per cluster: the input component its vertices belong to (UINT32_MAX for a cluster with no
/// vertex). O(V), parallel; K-sized.
std::vector<uint32_t> component_of_each_cluster(std::span<const int32_t> labels, const ComponentBudget& budget,
                                                uint32_t cluster_count);

/// What the topology check needs of the input as a whole.
struct InputClosure {
  bool closed = true;          ///< no boundary nor non-manifold vertex
  uint64_t referenced = 0;     ///< vertices on a face
  uint64_t boundary_vertices = 0;
  int64_t euler_characteristic = 0;  ///< referenced − E + F
};

/// Closure and Euler characteristic of the input from its vertex flags and CSR sizes. O(V),
/// parallel.
InputClosure input_closure(const MeshView& mesh);

}  // namespace streamcvd
