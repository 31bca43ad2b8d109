// The stages of remesh() up to the repaired clustering (core/remesh_stages.h): curvature fields,
// items, sampling and clustering at the cluster count the boundary strips leave, repair.
#include <algorithm>
#include <ctime>
#include <string>

#include "streamcvd/core/clustering/lloyd.h"
#include "streamcvd/core/dual/dual_topology.h"
#include "streamcvd/core/dual/placement.h"
#include "streamcvd/core/fields/curvature.h"
#include "streamcvd/core/fields/metric_field.h"
#include "streamcvd/core/remesh_stages.h"

namespace streamcvd::stages {

namespace {

// CPU seconds used by the whole process so far (all threads).
double process_cpu_seconds() {
  return double(std::clock()) / CLOCKS_PER_SEC;
}

// Vertices the §VI-D strips would add to the dual of `labels` (0 without strips). O(V) for the
// cluster sizes (chunk-parallel) plus O(boundary).
uint32_t strip_vertex_count(const MeshView& mesh, std::span<const int32_t> labels, uint32_t K,
                            const BoundaryLoops& loops, const DualMeshOptions& options) {
  if (!options.boundary_strips || loops.vertices.empty()) return 0;
  const std::vector<uint32_t> sizes = dual::cluster_sizes(mesh, labels, K);
  uint32_t strip_vertices = 0;
  boundary_strip_faces(mesh, loops, labels, K, sizes, options, strip_vertices);
  return strip_vertices;
}

// The dual as built for `clusters` clusters: strip points about an output edge apart; holes
// narrower than two output edges close instead of getting sliver strips (dragon → 20k, I: 238 of
// 407 loops closed, 220 strip vertices, against 223 and 295 for loops shorter than two edges;
// 1.5 edges: 237 and 223; 3 edges: as 2), and so do slits whose sides are closer than half an
// edge, however long (beetle_nonmanifold → 5000: 22 loops instead of 26; with a whole edge, the
// sphere's ragged holes one edge across closed too).
DualMeshOptions dual_options_at(const Job& job, const Items& items, uint32_t clusters) {
  DualMeshOptions dual;
  dual.boundary_strips = job.options.boundary_strips;
  dual.strip_spacing = typical_dual_edge(items.energy.total_area, clusters);
  dual.close_hole_diameter = 2.0 * dual.strip_spacing;
  dual.close_hole_width = 0.5 * dual.strip_spacing;
  return dual;
}

// Sampling (§VI-G) and clustering (Algorithm 1, or Lloyd) at `clusters` clusters spread over the
// components by the budget.
void sample_and_cluster(Job& job, const Items& items, uint32_t clusters, Clusters& c) {
  job.begin("sampling");
  const MeshView& mesh = job.mesh();
  c.budget = plan_component_budget(mesh, items.energy, clusters, job.options.small_components, job.storage,
                                   job.options.drop_cut_sheets);
  c.labels.reset();  // a second pass: the first one's labels go before the new ones come
  c.labels = initial_sampling(mesh, job.plan.tensors ? items.sampling : items.energy, c.budget, job.options.seed,
                              job.storage);
  job.seconds.sampling += job.elapsed();
  job.begin("clustering");
  const double cpu0 = process_cpu_seconds();
  const uint32_t K = c.budget.total_clusters;
  job.pass_starts();
  c.report = job.plan.lloyd ? lloyd_clustering(mesh, items.energy, c.labels, K, job.clustering)
                            : minimize_clustering(mesh, items.energy, c.labels, K, job.clustering);
  job.pass_ends();
  job.seconds.clustering += job.elapsed();
  job.seconds.clustering_cpu += process_cpu_seconds() - cpu0;
}

// N is not met: the output is the one of N clusters and their strips (clustered again when
// the last pass ran at another count), and the budget's note says why.
void give_up_exact_count(Job& job, const Items& items, Clusters& c, bool recluster) {
  const uint32_t N = job.options.vertices;
  if (recluster) {
    c.dual = dual_options_at(job, items, N);
    sample_and_cluster(job, items, N, c);
  }
  c.target = 0;
  c.budget.note = "the boundary strips need " + std::to_string(c.strips_at_n) + " vertices: N = " + std::to_string(N) +
                  " cannot be met without coarsening the interior below half the budget (use a larger N or "
                  "--no-boundary-strips)";
}

// One run of the repair of the clustering around dual-mesh defects (labels only; re-checks
// just the changed region each round); its relaxation loops go into the clustering's report.
DefectRepairResult repair_once(Job& job, const Items& items, const BoundaryLoops& loops, Clusters& c) {
  DefectRepairOptions o;
  o.max_rounds = job.options.repair_rounds;
  o.dual = c.dual;
  o.target_vertices = c.target;
  o.relax = !job.plan.lloyd;  // a Lloyd run's report stays pure Lloyd
  o.clustering = job.clustering;
  // Compensating merges/splits of the repair stay in components with many clusters.
  const std::vector<uint8_t> adjustable = clusters_in_large_components(c.labels, c.budget, c.K, 64);
  DefectRepairResult r =
      repair_dual_defects(job.mesh(), items.energy, c.labels, c.K, adjustable, loops, o, c.report, job.storage);
  job.seconds.repair += r.repair_seconds;
  job.seconds.dual += r.check_seconds;
  return r;
}

}  // namespace

Fields curvature_fields(Job& job) {
  const RemeshOptions& o = job.options;
  Fields f{o.density, {}, {}};
  if (!job.plan.curvature) return f;
  job.begin("curvature");
  CurvatureOptions curvature_options;
  curvature_options.rings = o.curvature_rings;
  const Curvature curvature = compute_curvature(job.mesh(), curvature_options);
  job.seconds.curvature = job.elapsed();
  if (job.plan.gradation) {
    std::vector<float> gradation = gradation_density(job.mesh(), curvature, o.gradation);
    if (f.density.empty()) f.density = std::move(gradation);
    else
      for (size_t v = 0; v < f.density.size(); ++v) f.density[v] *= gradation[v];
  }
  if (job.plan.tensors) {
    AnisotropicField field = anisotropic_field(job.mesh(), curvature);
    f.tensors = std::move(field.tensors);
    f.sampling_density = std::move(field.density);
    if (!f.density.empty())
      for (size_t v = 0; v < f.density.size(); ++v) f.sampling_density[v] *= f.density[v];
  }
  return f;
}

Items clustering_items(Job& job, const Fields& fields) {
  job.begin("items");
  const MeshView& mesh = job.mesh();
  Items items;
  // The anisotropic energy is area-weighted (the tensors carry the curvature); the gradation
  // density then only shapes the initial sampling, as in the paper's A/AQ (§VII).
  items.energy = compute_item_data(mesh, job.plan.tensors ? std::span<const float>() : fields.density, job.storage,
                                   job.plan.quadrics ? ItemQuadrics::per_vertex : ItemQuadrics::none);
  if (job.plan.tensors) {
    items.sampling = compute_item_data(mesh, fields.sampling_density, job.storage);
    attach_tensors(items.energy, large_array_of(std::span<const float>(fields.tensors)));
  }
  job.seconds.items = job.elapsed();
  return items;
}

// Exactly N output vertices, strip vertices included. With S strip vertices on the dual of N
// clusters, a few (S ≤ N/20) are made up by merging clusters off the boundary once the defects
// are repaired (the repair's splits add some strip vertices too, also made up); more, by
// clustering again with N − S clusters, since one merge per strip vertex would coarsen the
// interior in patches. Strips needing half of N or more at the count found would leave the
// interior too coarse: N is then not met, and the note says why.
Clusters cluster_for_vertex_count(Job& job, const Items& items, const BoundaryLoops& loops) {
  const uint32_t N = job.options.vertices;
  Clusters c;
  sample_and_cluster(job, items, N, c);
  c.K = std::max(N, c.budget.total_clusters);
  c.dual = dual_options_at(job, items, N);
  c.target = N;
  uint32_t S = strip_vertex_count(job.mesh(), c.labels, c.K, loops, c.dual);
  c.strips_at_n = S;
  if (S >= N / 2) {
    // Counted on N clusters, S overstates what fewer, larger clusters need (fewer cluster
    // changes along the boundary, more holes closed). Look for the count C with C + S(C) ≈ N
    // (within N/20, which the repair makes up): C goes halfway to N − S each pass, since S(C)
    // grows almost as fast as C (slope ~0.8 on cgal_elephant_with_holes, 106 holes, at N = 1000:
    // C = N − S would swing from side to side). The output's edges are then those of C
    // clusters: the strip spacing and the closing diameter follow them. Up to 4 clusterings.
    uint32_t C = N;
    for (uint32_t pass = 0; pass < 4 && (C + S > N + N / 20 || C + S + N / 20 < N); ++pass) {
      C = (C + (S < N ? N - S : 0)) / 2;
      if (2 * uint64_t(C) < N) break;
      sample_and_cluster(job, items, C, c);
      c.dual = dual_options_at(job, items, C);
      S = strip_vertex_count(job.mesh(), c.labels, c.K, loops, c.dual);
    }
    c.searched = C != N;
    if (2 * uint64_t(C) < N || 2 * uint64_t(S) >= N) {  // interior below N/2
      give_up_exact_count(job, items, c, c.searched);
      c.searched = false;
    }
  } else if (S > N / 20) {
    sample_and_cluster(job, items, N - S, c);
  }
  return c;
}

// The repair stage. Clusters coarse enough for the strips may be too coarse for thin parts
// between holes (elephant_with_holes at N = 800: 400 clusters, the repair could not keep it in
// one piece): then the N clusters are repaired instead, and N is not met.
DefectRepairResult repair_defects(Job& job, const Items& items, const BoundaryLoops& loops, Clusters& c) {
  job.begin("repair");
  DefectRepairResult r = repair_once(job, items, loops, c);
  if (r.defect_vertices + r.unjoined_pairs != 0 && c.searched) {
    give_up_exact_count(job, items, c, true);
    job.begin("repair");
    r = repair_once(job, items, loops, c);
  }
  return r;
}

}  // namespace streamcvd::stages
