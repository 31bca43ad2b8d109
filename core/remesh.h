// The remeshing pipeline on a mesh view: items → component budget → initial sampling →
// clustering (unconstrained, clean, constrained) → dual mesh → manifold check and local repair.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "streamcvd/core/clustering/clustering.h"
#include "streamcvd/core/mesh/component_topology.h"
#include "streamcvd/core/dual/dual_mesh.h"
#include "streamcvd/core/mesh/large_array.h"
#include "streamcvd/core/mesh/mesh_buffers.h"
#include "streamcvd/core/dual/mesh_optimize.h"
#include "streamcvd/core/mesh/mesh_view.h"
#include "streamcvd/core/mesh/progress.h"
#include "streamcvd/core/mesh/vertex_attributes.h"

namespace streamcvd {

struct RemeshOptions {
  uint32_t vertices = 10000;   ///< N: output vertex budget (clusters)
  uint64_t seed = 20080401;    ///< RNG seed of the initial sampling; same seed, same output
  SmallComponents small_components = SmallComponents::Keep;  ///< components too small for one cluster
  bool boundary_strips = true; ///< §VI-D triangle strips along input boundaries
  /// Output vertex = the cluster centroid moved to the closest point of the input surface (among
  /// the triangles around the cluster). false = the raw centroid z_i of eq. 15, as in the paper.
  bool project_to_surface = true;
  /// Split/merge rounds around dual-mesh defects before the cleanup. Dragon at N = 20000:
  /// some seeds need 13–32 rounds (a round fixes most defects but its splits make new ones);
  /// 12 left those to the cleanup, which deletes faces and vertices. Rounds cost O(V) each.
  uint32_t repair_rounds = 40;
  ClusteringOptions clustering;  ///< metric, algorithm and loops; the defaults are the CLI's (IQ, all cores)
  std::vector<float> density;  ///< optional ρ per vertex (size V), empty = uniform
  /// Gradation γ of eq. 20: ρ_j multiplied by the clamped curvature magnitude to the power γ
  /// (0 = uniform). With A/AQ it shapes only the initial sampling, as in the paper.
  double gradation = 0;
  /// Rings of the curvature fit (gradation, A, AQ): 3 as in the paper; noisy scans want more
  /// (8 keeps k1, k2 within 10 % on a sphere with 1 % noise).
  int curvature_rings = 3;
  /// Quality post-pass on the output (core/dual/mesh_optimize.h): flips between nearly coplanar
  /// triangles and tangential relaxation of vertices off features, re-projected onto the input.
  bool optimize_quality = true;
  MeshOptimizeOptions optimize;
  /// Return the V-sized labels (RemeshResult::cluster_of_vertex, budget.component_of_vertex),
  /// copied into RAM when the job's storage is a work space; a job that only writes the output
  /// mesh turns this off, so nothing V-sized outlives the clustering.
  bool keep_vertex_labels = true;
  /// Per-vertex values (colours, scalars) carried to the output as area-weighted cluster means
  /// (core/mesh/vertex_attributes.h); empty: none.
  VertexAttributeColumns attributes;
  /// Stage by stage progress (core/mesh/progress.h): each stage's start and end, the chunks it has
  /// visited, the clustering's loops. Empty = none, and no cost.
  ProgressCallback progress;
};

struct StageTimes {
  double curvature = 0, items = 0, sampling = 0, clustering = 0, repair = 0, dual = 0, optimize = 0;
  double placement = 0;  ///< sites projected onto the input, output vertices placed, dual defects removed
  double checks = 0;     ///< flat-face safety net, topology and per-component checks, cluster connectivity
  double attributes = 0; ///< cluster means of the carried vertex attributes and the output rows
  double clustering_cpu = 0;  ///< CPU seconds of all threads during the clustering stage
};

struct RemeshResult {
  MeshBuffers mesh;                  ///< output vertices (cluster representatives) and triangles
  /// options.attributes.columns.size() floats per output vertex (in mesh order): the carried
  /// attributes, cluster means or, for strip vertices, means of the input vertices they lie at.
  std::vector<float> vertex_attributes;
  LargeArray<int32_t> cluster_of_vertex;  ///< final label of each input vertex (in RAM; empty unless keep_vertex_labels)
  /// Cluster ids: the budget's (after components), plus spare ones up to N that splits making
  /// the vertex count exact may take. The output has one vertex per non-empty cluster.
  uint32_t clusters = 0;
  ComponentBudget budget;
  ClusteringReport clustering;
  StageTimes seconds;
  double final_energy = 0;           ///< energy − ΣA_j of the final clustering under its metric
  uint32_t repair_rounds_used = 0;
  uint32_t repair_count_rounds = 0;  ///< of repair_rounds_used, rounds for the vertex target only
  uint64_t repaired_clusters = 0;    ///< clusters touched by the repair
  uint64_t repair_splits = 0, repair_merges = 0, repair_islands = 0;
  bool repair_relaxed = false;
  /// N minus the dual's vertices after the repair (clusters + strip vertices): 0 when the
  /// output has exactly N vertices; < 0 when the budget could not shrink that far.
  int64_t vertex_shortfall = 0;
  uint64_t sites_reverted = 0;       ///< Q metrics: QEM sites of needle triangles moved back to the centroid       ///< the repaired region was relaxed without new defects
  uint64_t defect_vertices = 0;      ///< output vertices still on a defect at the end (0 = valid)
  uint64_t defect_faces_removed = 0;   ///< faces deleted by the last-resort cleanup (holes opened)
  uint64_t defect_vertices_removed = 0;  ///< vertices deleted with them (output has fewer than N)
  uint64_t flat_faces_removed = 0;   ///< zero-area faces dropped along the boundary (core/mesh/flat_faces.h)
  uint64_t flat_face_flips = 0;      ///< zero-area faces removed by an edge flip or a few-ulp vertex move
  uint64_t duplicate_faces_removed = 0;
  uint64_t boundary_vertices_added = 0;
  uint64_t holes_closed = 0;
  uint64_t quality_flips = 0, quality_moves = 0;  ///< edits of the quality post-pass
  uint64_t strip_moves = 0;  ///< strip and strip-adjacent vertex moves of the quality pass (core/dual/strip_shape.h)
  /// Faces with a corner at a boundary-strip vertex: count, Qmin, Qav (and the others' Qav).
  uint64_t strip_faces = 0;
  double strip_q_min = 0, strip_q_avg = 0, other_q_avg = 0;
  bool clusters_connected = false;
  int64_t input_euler_characteristic = 0, output_euler_characteristic = 0;
  /// Closed input whose output lost or gained handles, or had holes opened by the last-resort
  /// cleanup: the budget is too coarse for a feature. Reported, never silent.
  bool topology_changed = false;
  /// Each input component with clusters is one output component, same genus, no more loops.
  ComponentCheck components;
};

/// Remeshes `mesh` to `options.vertices` clusters under options.clustering.metric (I, IQ, A,
/// AQ; §V). The output vertex of each cluster is its site: the centroid projected onto the
/// surface (I, A) or the QEM point (IQ, AQ); strips add vertices along boundaries. Checks the dual for
/// non-manifold edges/vertices, isolated vertices and duplicate faces, and repairs the
/// clustering around each defect (core/dual/repair.h, up to repair_rounds). Deterministic for a
/// seed with clustering.loops.threads = 1 or clustering.loops.deterministic (any thread count);
/// otherwise (the default: all cores) the parallel clustering may differ between runs
/// (core/clustering/parallel_clustering.h).
/// Arrays sized by the input come from `storage` (RAM, or the pipeline's work files).
RemeshResult remesh(const MeshView& mesh, const RemeshOptions& options, ArrayStorage& storage = ram_storage());

}  // namespace streamcvd
