// The remeshing pipeline on a mesh view, stage by stage: curvature fields → items → component
// budget, initial sampling and clustering (at the cluster count the boundary strips leave) →
// repair of the dual's defects → dual mesh → placement of the output vertices → quality pass →
// checks → carried attributes. What the metric asks of each stage is decided once (RemeshPlan).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "streamcvd/core/clustering/clustering.h"
#include "streamcvd/core/dual/dual_mesh.h"
#include "streamcvd/core/dual/mesh_optimize.h"
#include "streamcvd/core/dual/repair.h"
#include "streamcvd/core/dual/strip_shape.h"
#include "streamcvd/core/dual/component_topology.h"
#include "streamcvd/core/dual/flat_faces.h"
#include "streamcvd/core/mesh/large_array.h"
#include "streamcvd/core/mesh/mesh_buffers.h"
#include "streamcvd/core/mesh/mesh_view.h"
#include "streamcvd/core/mesh/progress.h"
#include "streamcvd/core/mesh/vertex_attributes.h"

namespace streamcvd {

struct RemeshOptions {
  uint32_t vertices = 10000;   ///< N: output vertex budget (clusters)
  uint64_t seed = 20080401;    ///< RNG seed of the initial sampling; same seed, same output
  SmallComponents small_components = SmallComponents::Keep;  ///< components too small for one cluster
  /// Drop the sheets a topology cleaning cut off (pieces below the output resolution that touch
  /// another at a vertex: plan_component_budget's drop_touching_small), whatever
  /// small_components says. remesh_store sets it for a store the cleaning rebuilt.
  bool drop_cut_sheets = false;
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

/// What the options ask of the stages, decided once from the metric and the options at the
/// start of remesh() (plan_remesh); no stage looks at the metric itself.
struct RemeshPlan {
  Metric metric = Metric::IQ;  ///< options.clustering.metric
  bool lloyd = false;          ///< Lloyd instead of Algorithm 1; the repair then keeps the clusters as Lloyd left them
  bool curvature = false;      ///< the curvature fit runs: for the gradation density or the tensors
  bool gradation = false;      ///< ρ multiplied by the eq. 20 curvature factor
  /// A/AQ: item tensors of the curvature (eq. 16, area-weighted energy); the initial sampling
  /// uses items of its own, weighted by the metric's area factor (and ρ).
  bool tensors = false;
  /// IQ/AQ: vertex quadrics; the sites are QEM points (§V-C), those of needle triangles revert
  /// to the centroids, and the quality pass keeps their offset from the surface.
  bool quadrics = false;
  bool optimize = true;        ///< the quality pass runs (options.optimize_quality)
  /// The quality pass as it runs: for QEM points the feature angle qem_feature_angle_deg and the
  /// surface offset kept; without projection onto the surface, flips only.
  MeshOptimizeOptions optimize_options;
};

/// The plan of `options`. Throws std::invalid_argument for the Lloyd algorithm with A or AQ (only
/// I and IQ are implemented). O(1), pure.
RemeshPlan plan_remesh(const RemeshOptions& options);

/// The dual stage: the dual of the repaired clustering with its sites as vertices.
struct DualReport {
  double final_energy = 0;               ///< energy − ΣA_j of the final clustering under its metric
  /// N minus the dual's vertices after the repair (clusters + strip vertices): 0 when the
  /// output has exactly N vertices; < 0 when the budget could not shrink that far.
  int64_t vertex_shortfall = 0;
  uint64_t duplicate_faces_removed = 0;
  uint64_t boundary_vertices_added = 0;  ///< §VI-D strip vertices
  uint64_t holes_closed = 0;             ///< boundary loops below the output resolution, closed
};

/// The placement stage: output vertices at the sites, then the last-resort defect cleanup.
struct PlacementReport {
  uint64_t sites_reverted = 0;  ///< Q metrics: QEM sites of needle triangles moved back to the centroid
  /// Faces deleted by the last-resort cleanup (holes opened) and vertices deleted with them
  /// (the output then has fewer than N).
  DefectRemoval defects_removed;
  uint64_t defect_vertices = 0;  ///< output vertices still on a defect at the end (0 = valid)
};

/// The quality post-pass (core/dual/mesh_optimize.h, core/dual/strip_shape.h).
struct QualityPassReport {
  MeshOptimizeReport interior;  ///< flips and tangential moves over the whole output
  StripShapeReport strips;      ///< strip slides, moves of their cluster neighbours, flips (with relaxation only)
  uint64_t flips() const { return interior.flips + strips.flips; }
  uint64_t strip_moves() const { return strips.strip_moves + strips.cluster_moves; }
};

/// The checks stage: the flat-face safety net, then what the output is checked for.
struct OutputChecks {
  FlatFaceRepair flat_faces;  ///< zero-area faces along strips removed, flipped or nudged (core/dual/flat_faces.h)
  /// Q of the faces with a corner at a boundary-strip vertex (count, Qmin, Qav) and of the others.
  StripQuality strips;
  bool clusters_connected = false;
  int64_t input_euler_characteristic = 0, output_euler_characteristic = 0;
  /// Faces deleted by the last-resort cleanup (any input: each deletion opens a hole the input
  /// has not), or a closed input whose output lost or gained handles: the budget is too coarse
  /// for a feature. Reported, never silent (a failed check).
  bool topology_changed = false;
  /// Each input component with clusters is one output component, same genus, no more loops.
  ComponentCheck components;
};

/// The result of remesh(): the output and, stage by stage, what each stage reported.
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
  ClusteringReport clustering;       ///< the last clustering pass, then the repair's relaxation loops
  StageTimes seconds;
  DefectRepairResult repair;         ///< the last repair run (rounds, splits, merges, islands, relaxed)
  DualReport dual;
  PlacementReport placement;
  QualityPassReport quality;         ///< zero when the quality pass is off
  OutputChecks checks;
};

/// Remeshes `mesh` to `options.vertices` clusters under options.clustering.metric (I, IQ, A,
/// AQ; §V). The output vertex of each cluster is its site: the centroid projected onto the
/// surface (I, A) or the QEM point (IQ, AQ); strips add vertices along boundaries. Checks the dual for
/// non-manifold edges/vertices, isolated vertices and duplicate faces, and repairs the
/// clustering around each defect (core/dual/repair.h, up to repair_rounds). Deterministic for a
/// seed with clustering.loops.threads = 1 or clustering.loops.deterministic (any thread count);
/// otherwise (the default: all cores) the parallel clustering may differ between runs
/// (core/clustering/parallel_clustering.h). Arrays sized by the input come from `storage` (RAM,
/// or the pipeline's work files), the clustering's included (clustering.loops.storage is not
/// read). The stages, in order: curvature, items, sampling and clustering, repair, dual,
/// placement, optimize, checks, attributes. Throws InputError when no valid surface can be built
/// at this N; std::invalid_argument as plan_remesh.
RemeshResult remesh(const MeshView& mesh, const RemeshOptions& options, ArrayStorage& storage = ram_storage());

}  // namespace streamcvd
