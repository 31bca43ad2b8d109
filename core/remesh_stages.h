// The stages of remesh() (core/remesh.h), internal to core/remesh*.cpp: the job every stage reads,
// what the stages hand on to each other, and the stage functions in the order remesh() calls
// them. Each stage starts itself on the display and the clock, and adds its time to StageTimes.
#pragma once

#include <algorithm>
#include <chrono>
#include <optional>
#include <vector>

#include "streamcvd/core/mesh/timer.h"
#include "streamcvd/core/remesh.h"

namespace streamcvd::stages {

// What every stage reads: the view (through the progress reporter when there is a display),
// the options and their plan, the storage of the arrays sized by the input, the clustering
// options as the passes run them, the stage clock and the times.
class Job {
 public:
  Job(const MeshView& input, const RemeshOptions& options, ArrayStorage& storage, StageTimes& seconds)
      : options(options), plan(plan_remesh(options)), storage(storage), seconds(seconds),
        clustering(options.clustering) {
    if (options.progress) progress_.emplace(options.progress, input);
    mesh_ = progress_ ? &progress_->view() : &input;
    clustering.loops.storage = &storage;
    if (progress_)  // the display counts the clustering loops over every pass
      clustering.loops.on_loop = [this, user = options.clustering.loops.on_loop](bool constrained, uint32_t loop,
                                                                                  uint64_t moves) {
        if (user) user(constrained, loop, moves);
        progress_->round(++loops_ + 1, "loop");
      };
  }
  const MeshView& mesh() const { return *mesh_; }
  /// Starts stage `name`: on the display, and on the clock read by elapsed().
  void begin(const char* name) {
    if (progress_) progress_->begin(name);
    started_ = std::chrono::steady_clock::now();
  }
  double elapsed() const { return seconds_since(started_); }
  /// The display's loop count around one clustering pass: the next loop before, the last after.
  void pass_starts() {
    if (progress_) progress_->round(loops_ + 1, "loop");
  }
  void pass_ends() {
    if (progress_) progress_->round(std::max(loops_, 1u), "loop");
  }
  void finish() {
    if (progress_) progress_->finish();
  }

  const RemeshOptions& options;
  const RemeshPlan plan;
  ArrayStorage& storage;
  StageTimes& seconds;
  ClusteringOptions clustering;  ///< the options' clustering with the job's storage and display

 private:
  std::optional<StageReporter> progress_;
  const MeshView* mesh_ = nullptr;
  uint32_t loops_ = 0;
  std::chrono::steady_clock::time_point started_;
};

// Per-vertex fields of the curvature fit: the density ρ (the options' times the eq. 20
// gradation) and, for A/AQ, the metric tensors and the sampling density they imply (× ρ).
struct Fields {
  std::vector<float> density, tensors, sampling_density;
};

// The clustering items (eq. 10, 11): those of the energy, and for A/AQ those the initial
// sampling draws from.
struct Items {
  ItemData energy;
  ItemData sampling;  ///< A/AQ only: weighted by the metric's area factor
};

// The clustering as the passes leave it, and what the dual built from it will be.
struct Clusters {
  LargeArray<int32_t> labels;
  ComponentBudget budget;
  ClusteringReport report;   ///< of the last pass
  uint32_t K = 0;            ///< cluster ids: the budget's at N, plus spare ones up to N for the repair
  DualMeshOptions dual;      ///< strips and closed holes at the spacing of the cluster count used
  uint32_t target = 0;       ///< output vertices the repair aims for (0: N cannot be met)
  uint32_t strips_at_n = 0;  ///< strip vertices on the dual of N clusters
  bool searched = false;     ///< clustered at C < N for the strips: the repair may fall back to N
};

// The dual of the final clustering with its sites (centroid, anisotropic centroid or QEM
// point: computed once, for the dual and for the placement) as vertices, and its defects.
struct DualStage {
  DualMesh dual;
  ClusterState state;
  std::vector<double> sites;
  std::vector<uint32_t> defects;
  DualReport report;
};

/// "curvature" (only when the plan asks for it): Fields of the curvature fit. O(V · ring size).
Fields curvature_fields(Job& job);
/// "items": the clustering items of the energy (with tensors and quadrics as planned) and of
/// the sampling. O(F), parallel.
Items clustering_items(Job& job, const Fields& fields);
/// "sampling" and "clustering", once or a few times: the clustering at the cluster count whose
/// dual has N vertices with its boundary strips (or N, when the strips need N/2 or more).
Clusters cluster_for_vertex_count(Job& job, const Items& items, const BoundaryLoops& loops);
/// "repair": the clustering repaired around the dual's defects (core/dual/repair.h), N
/// clusters again when those found for the strips cannot be repaired. The last run's report.
DefectRepairResult repair_defects(Job& job, const Items& items, const BoundaryLoops& loops, Clusters& c);
/// "dual": the sites (solved once), the dual mesh and its defects, from `triples`, the dual
/// faces of the labels as the repair left them (DefectRepairResult::dual_faces). O(V + D log D).
DualStage build_dual(Job& job, const ItemData& items, Clusters& c, const BoundaryLoops& loops, dual::Triples triples);
/// "placement": output vertices at the projected centroids or the QEM points (needles
/// reverted), then the last-resort removal of defects. O(V + F).
PlacementReport place_output(Job& job, const ItemData& items, const Clusters& c, DualStage& d);
/// "optimize": the quality post-pass on the output, strips after the interior.
QualityPassReport improve_quality(Job& job, const Clusters& c, const BoundaryLoops& loops, DualMesh& dual);
/// "checks": flat faces repaired, then topology, components, strip quality, connectivity.
/// Throws InputError when no face is left of a mesh that has some.
OutputChecks check_output(Job& job, const Clusters& c, const BoundaryLoops& loops, const PlacementReport& placement,
                          DualMesh& dual);
/// "attributes": the carried attributes of every output vertex (options.attributes).
std::vector<float> carry_attributes(Job& job, const Clusters& c, const DualMesh& dual);

}  // namespace streamcvd::stages
