// remesh() (core/remesh.h) as its sequence of stages (core/remesh_stages.h), and the plan that
// decides once what the metric and the options ask of them.
#include "streamcvd/core/remesh.h"

#include <stdexcept>
#include <string>

#include "streamcvd/core/remesh_stages.h"

namespace streamcvd {

namespace {

// The V-sized labels for the caller: in RAM (the job's work space ends with the job), or none.
void hand_over_vertex_labels(bool keep, LargeArray<int32_t>& labels, RemeshResult& result) {
  LargeArray<uint32_t>& components = result.budget.component_of_vertex;
  if (!keep) {
    labels.reset();
    components.reset();
    return;
  }
  result.cluster_of_vertex = &labels.storage() == &ram_storage() ? std::move(labels) : large_array_of(labels.span());
  if (&components.storage() != &ram_storage()) components = large_array_of(components.span());
}

}  // namespace

RemeshPlan plan_remesh(const RemeshOptions& options) {
  RemeshPlan plan;
  plan.metric = options.clustering.metric;
  plan.lloyd = options.clustering.algorithm == ClusteringOptions::Algorithm::Lloyd;
  if (plan.lloyd && is_anisotropic(plan.metric))
    throw std::invalid_argument(std::string("remesh: the Lloyd algorithm implements the metrics I and IQ, not ") +
                                metric_name(plan.metric));
  plan.gradation = options.gradation != 0;
  plan.tensors = is_anisotropic(plan.metric);
  plan.quadrics = uses_quadrics(plan.metric);
  plan.curvature = plan.gradation || plan.tensors;
  plan.optimize = options.optimize_quality;
  plan.optimize_options = options.optimize;
  if (!options.project_to_surface) plan.optimize_options.relax_iterations = 0;  // raw centroids asked for: flips only
  if (plan.quadrics) {  // QEM points: only nearly flat rings move, keeping their height
    plan.optimize_options.feature_angle_deg = plan.optimize_options.qem_feature_angle_deg;
    plan.optimize_options.keep_surface_offset = true;
  }
  return plan;
}

RemeshResult remesh(const MeshView& input, const RemeshOptions& options, ArrayStorage& storage) {
  using namespace stages;
  RemeshResult result;
  Job job(input, options, storage, result.seconds);
  Items items = clustering_items(job, curvature_fields(job));
  const BoundaryLoops loops = find_boundary_loops(job.mesh());
  Clusters clusters = cluster_for_vertex_count(job, items, loops);
  result.repair = repair_defects(job, items, loops, clusters);
  items.sampling = ItemData{};  // no pass samples again
  DualStage dual = build_dual(job, items.energy, clusters, loops, std::move(result.repair.dual_faces));
  result.placement = place_output(job, items.energy, clusters, dual);
  if (job.plan.optimize) result.quality = improve_quality(job, clusters, loops, dual.dual);
  result.checks = check_output(job, clusters, loops, result.placement, dual.dual);
  if (!options.attributes.empty()) result.vertex_attributes = carry_attributes(job, clusters, dual.dual);
  result.dual = dual.report;
  result.mesh = std::move(dual.dual.mesh);
  result.clusters = clusters.K;
  result.budget = std::move(clusters.budget);
  result.clustering = std::move(clusters.report);
  hand_over_vertex_labels(options.keep_vertex_labels, clusters.labels, result);
  job.finish();
  return result;
}

}  // namespace streamcvd
