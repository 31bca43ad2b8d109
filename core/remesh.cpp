#include "streamcvd/core/remesh.h"

#include "streamcvd/core/mesh/bvh.h"
#include "streamcvd/core/fields/curvature.h"
#include "streamcvd/core/dual/dual_topology.h"
#include "streamcvd/core/fields/metric_field.h"
#include "streamcvd/core/dual/placement.h"
#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/mesh/flat_faces.h"
#include "streamcvd/core/dual/strip_shape.h"
#include "streamcvd/core/clustering/lloyd.h"
#include "streamcvd/core/dual/repair.h"
#include "streamcvd/core/mesh/timer.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <ctime>
#include <cmath>
#include <limits>
#include <numeric>
#include <optional>

namespace streamcvd {

namespace {

// CPU seconds used by the whole process so far (all threads).
double process_cpu_seconds() {
  return double(std::clock()) / CLOCKS_PER_SEC;
}

void place_output_vertices(DualMesh& dual, std::span<const double> z) {
  for (uint32_t v = 0; v < dual.mesh.vertex_count(); ++v) {
    const int32_t c = dual.cluster_of_output_vertex[v];
    if (c >= 0)
      for (int k = 0; k < 3; ++k) dual.mesh.positions[3 * size_t(v) + k] = float(z[3 * size_t(c) + k]);
  }
}

// Quality Q = 6/√3 · area / (half-perimeter · longest edge) of an output triangle.
double triangle_quality(const float* a, const float* b, const float* c) {
  double e[3][3], len[3];
  for (int k = 0; k < 3; ++k) {
    e[0][k] = double(b[k]) - a[k];
    e[1][k] = double(c[k]) - b[k];
    e[2][k] = double(a[k]) - c[k];
  }
  for (int i = 0; i < 3; ++i) len[i] = std::sqrt(e[i][0] * e[i][0] + e[i][1] * e[i][1] + e[i][2] * e[i][2]);
  const double cx = e[0][1] * e[1][2] - e[0][2] * e[1][1], cy = e[0][2] * e[1][0] - e[0][0] * e[1][2],
               cz = e[0][0] * e[1][1] - e[0][1] * e[1][0];
  const double area = 0.5 * std::sqrt(cx * cx + cy * cy + cz * cz);
  const double denom = 0.5 * (len[0] + len[1] + len[2]) * std::max({len[0], len[1], len[2]});
  return denom > 0 ? 6.0 / std::sqrt(3.0) * area / denom : 0.0;
}

// QEM sites of three clusters along one straight crease are collinear, and two clusters may
// share a corner: their triangle is a needle or has no area at all. Such a triangle is worse
// than the small approximation gain, so its clusters fall back to their projected centroids.
// Returns the number of sites reverted.
uint64_t revert_needle_sites(DualMesh& dual, std::vector<double>& z, std::span<const double> fallback) {
  constexpr double kNeedleQuality = 1e-4;
  constexpr int kMaxPasses = 9;
  uint64_t reverted = 0;
  std::vector<uint8_t> done(z.size() / 3, 0);
  auto moved2 = [&](int32_t c) {
    double d2 = 0;
    for (int i = 0; i < 3; ++i) d2 += (z[3 * size_t(c) + i] - fallback[3 * size_t(c) + i]) * (z[3 * size_t(c) + i] - fallback[3 * size_t(c) + i]);
    return d2;
  };
  for (int pass = 0; pass < kMaxPasses; ++pass) {
    bool changed = false;
    const auto& tri = dual.mesh.triangles;
    const float* P = dual.mesh.positions.data();
    for (size_t f = 0; f < tri.size(); f += 3) {
      if (triangle_quality(P + 3 * size_t(tri[f]), P + 3 * size_t(tri[f + 1]), P + 3 * size_t(tri[f + 2])) >= kNeedleQuality)
        continue;
      // Revert one site per needle and pass: the one that moved least from its fallback (a crease
      // point before a corner), so a corner is kept whenever a crease neighbour can give way.
      int32_t pick = -1;
      double least = std::numeric_limits<double>::infinity();
      for (int k = 0; k < 3; ++k) {
        const int32_t c = dual.cluster_of_output_vertex[tri[f + k]];
        if (c < 0 || done[c]) continue;
        const double d2 = moved2(c);
        if (d2 < least) {
          least = d2;
          pick = c;
        }
      }
      if (pick < 0) continue;
      done[pick] = 1;
      changed = true;
      ++reverted;
      for (int i = 0; i < 3; ++i) z[3 * size_t(pick) + i] = fallback[3 * size_t(pick) + i];
    }
    if (!changed) break;
    place_output_vertices(dual, z);
  }
  return reverted;
}

// V − E + F of a triangle soup (referenced vertices, distinct undirected edges).
int64_t euler_characteristic(const TriangleSoupView& soup) {
  std::vector<uint64_t> edges;
  edges.reserve(soup.triangles.size());
  std::vector<uint8_t> referenced(soup.vertex_count(), 0);
  for (uint64_t f = 0; f < soup.face_count(); ++f)
    for (int k = 0; k < 3; ++k) {
      uint32_t u = soup.triangles[3 * f + k], v = soup.triangles[3 * f + (k + 1) % 3];
      referenced[u] = 1;
      edges.push_back(uint64_t(std::min(u, v)) << 32 | std::max(u, v));
    }
  std::sort(edges.begin(), edges.end());
  int64_t e = std::unique(edges.begin(), edges.end()) - edges.begin();
  int64_t v = std::count(referenced.begin(), referenced.end(), uint8_t(1));
  return v - e + int64_t(soup.face_count());
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

RemeshResult remesh(const MeshView& input, const RemeshOptions& options, ArrayStorage& storage) {
  // With a display, every range visit of the stages goes through the reporter (per chunk, never
  // per vertex); without one the stages see the caller's view as it is.
  std::optional<StageReporter> progress;
  if (options.progress) progress.emplace(options.progress, input);
  const MeshView& mesh = progress ? progress->view() : input;
  auto stage = [&](const char* name) {
    if (progress) progress->begin(name);
  };
  RemeshResult result;
  auto t = std::chrono::steady_clock::now();
  const Metric metric = options.clustering.metric;
  std::vector<float> density = options.density;
  std::vector<float> sampling_density;  // A/AQ: the metric's area factor, for the initial sampling
  std::vector<float> tensors;
  if (options.gradation != 0 || is_anisotropic(metric)) {
    stage("curvature");
    CurvatureOptions curvature_options;
    curvature_options.rings = options.curvature_rings;
    const Curvature curvature = compute_curvature(mesh, curvature_options);
    result.seconds.curvature = seconds_since(t);
    if (options.gradation != 0) {
      std::vector<float> gradation = gradation_density(mesh, curvature, options.gradation);
      if (density.empty()) density = std::move(gradation);
      else
        for (size_t v = 0; v < density.size(); ++v) density[v] *= gradation[v];
    }
    if (is_anisotropic(metric)) {
      AnisotropicField field = anisotropic_field(mesh, curvature);
      tensors = std::move(field.tensors);
      sampling_density = std::move(field.density);
      if (!density.empty())
        for (size_t v = 0; v < density.size(); ++v) sampling_density[v] *= density[v];
    }
  }
  stage("items");
  t = std::chrono::steady_clock::now();
  // The anisotropic energy is area-weighted (the tensors carry the curvature); the gradation
  // density then only shapes the initial sampling, as in the paper's A/AQ (§VII).
  ItemData items = compute_item_data(mesh, is_anisotropic(metric) ? std::span<const float>() : density, storage);
  ItemData sampling_items;
  if (is_anisotropic(metric)) {
    sampling_items = compute_item_data(mesh, sampling_density, storage);
    attach_tensors(items, large_array_of(std::span<const float>(tensors)));
  }
  if (uses_quadrics(metric)) items.quadric = vertex_quadrics(mesh, items.origin, storage);
  result.seconds.items = seconds_since(t);

  // Sampling (§VI-G) and clustering (Algorithm 1) at `clusters` clusters spread over the
  // components by the budget.
  const bool lloyd = options.clustering.algorithm == ClusteringOptions::Algorithm::Lloyd;
  LargeArray<int32_t> labels;
  ClusteringOptions clustering = options.clustering;
  uint32_t loops = 0;  // over every pass: the display counts the stage's loops
  if (progress)
    clustering.loops.on_loop = [&progress, &loops, user = options.clustering.loops.on_loop](
                                   bool constrained, uint32_t loop, uint64_t moves) {
      if (user) user(constrained, loop, moves);
      progress->round(++loops + 1, "loop");
    };
  auto sample_and_cluster = [&](uint32_t clusters) {
    stage("sampling");
    auto t0 = std::chrono::steady_clock::now();
    result.budget = plan_component_budget(mesh, items, clusters, options.small_components, storage);
    labels.reset();  // a second pass: the first one's labels go before the new ones come
    labels = initial_sampling(mesh, is_anisotropic(metric) ? sampling_items : items, result.budget, options.seed, storage);
    result.seconds.sampling += seconds_since(t0);
    stage("clustering");
    t0 = std::chrono::steady_clock::now();
    const double cpu0 = process_cpu_seconds();
    const uint32_t K = result.budget.total_clusters;
    if (progress) progress->round(loops + 1, "loop");
    result.clustering = lloyd ? lloyd_clustering(mesh, items, labels, K, clustering)
                              : minimize_clustering(mesh, items, labels, K, clustering);
    if (progress) progress->round(std::max(loops, 1u), "loop");  // the last loop ran, no next one
    result.seconds.clustering += seconds_since(t0);
    result.seconds.clustering_cpu += process_cpu_seconds() - cpu0;
  };
  sample_and_cluster(options.vertices);
  // Cluster ids: the budget's, and spare ones up to N for the splits that make the count exact.
  const uint32_t K = std::max(options.vertices, result.budget.total_clusters);
  result.clusters = K;

  const BoundaryLoops boundary_loops = find_boundary_loops(mesh);
  DualMeshOptions dual_options;
  dual_options.boundary_strips = options.boundary_strips;
  // Holes narrower than two output edges close instead of getting sliver strips (dragon → 20k,
  // I: 238 of 407 loops closed, 220 strip vertices, against 223 and 295 for loops shorter than
  // two edges; 1.5 edges: 237 and 223; 3 edges: as 2).
  dual_options.close_hole_diameter = 2.0 * typical_dual_edge(items.total_area, options.vertices);
  dual_options.strip_spacing = typical_dual_edge(items.total_area, options.vertices);  // strip points about an edge apart
  // Repair the clustering around dual-mesh defects (labels only; re-checks just the changed
  // region each round), then build the dual once and check it as a whole.
  DefectRepairOptions repair_options;
  repair_options.max_rounds = options.repair_rounds;
  repair_options.dual = dual_options;
  repair_options.clustering = options.clustering;
  repair_options.relax = !lloyd;  // a Lloyd run's report stays pure Lloyd
  // Exactly N output vertices, strip vertices included. With S strip vertices on the dual of
  // the clustering, a few (S ≤ N/20) are made up by merging clusters off the boundary once the
  // defects are repaired (the repair's splits add some strip vertices too, also made up); more,
  // by clustering again with N − S clusters, since one merge per strip vertex would coarsen
  // the interior in patches. Strips needing half of N or more at the count found would leave the
  // interior too coarse: N is then not met, and the note says why.
  const uint32_t N = options.vertices;
  uint32_t S = strip_vertex_count(mesh, labels, K, boundary_loops, dual_options);
  uint32_t target = N;
  const DualMeshOptions at_n = dual_options;
  const uint32_t s_at_n = S;
  // N not met: the output is the one of N clusters and their strips.
  auto give_up = [&](bool recluster) {
    if (recluster) {
      dual_options = at_n;
      sample_and_cluster(N);
    }
    target = 0;
    result.budget.note = "the boundary strips need " + std::to_string(s_at_n) + " vertices: N = " + std::to_string(N) +
                         " cannot be met without coarsening the interior below half the budget (use a larger N or "
                         "--no-boundary-strips)";
  };
  bool searched = false;
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
      sample_and_cluster(C);
      dual_options.strip_spacing = typical_dual_edge(items.total_area, C);
      dual_options.close_hole_diameter = 2.0 * dual_options.strip_spacing;
      S = strip_vertex_count(mesh, labels, K, boundary_loops, dual_options);
    }
    searched = C != N;
    if (2 * uint64_t(C) < N || 2 * uint64_t(S) >= N) give_up(searched), searched = false;  // interior below N/2
  } else if (S > N / 20) {
    sample_and_cluster(N - S);
  }
  stage("repair");
  auto repair = [&] {
    repair_options.dual = dual_options;
    repair_options.target_vertices = target;
    // Compensating merges/splits of the repair stay in components with many clusters.
    const std::vector<uint8_t> adjustable = clusters_in_large_components(labels, result.budget, K, 64);
    const DefectRepairResult r = repair_dual_defects(mesh, items, labels, K, adjustable, boundary_loops,
                                                     repair_options, result.clustering, storage);
    result.seconds.repair += r.repair_seconds;
    result.seconds.dual += r.check_seconds;
    result.repair_rounds_used = r.rounds;
    result.repair_count_rounds = r.count_rounds;
    result.repaired_clusters = r.repaired_clusters;
    result.repair_splits = r.splits;
    result.repair_merges = r.merges;
    result.repair_islands = r.islands;
    result.repair_relaxed = r.relaxed;
    return r.defect_vertices + r.unjoined_pairs == 0;
  };
  // Clusters coarse enough for the strips may be too coarse for thin parts between holes
  // (elephant_with_holes at N = 800: 400 clusters, the repair could not keep it in one piece):
  // then the N clusters are repaired instead, and N is not met.
  if (!repair() && searched) {
    give_up(true);
    repair();
  }
  sampling_items = ItemData{};
  stage("dual");
  t = std::chrono::steady_clock::now();
  // The sites of the final clustering under its metric: centroid, anisotropic centroid, or
  // QEM point. Computed once, for the dual and for the final placement below.
  ClusterState state = solved_cluster_state(items, labels, K, options.clustering);
  result.final_energy = state_energy(items, state);
  std::vector<double> z = cluster_sites(items, state);
  DualMesh dual = build_dual_mesh(mesh, labels, K, z, dual_options, &boundary_loops);
  result.vertex_shortfall = int64_t(N) - int64_t(dual.mesh.vertex_count());
  if (result.vertex_shortfall != 0 && result.budget.note.empty())
    result.budget.note = "the clusters and the " + std::to_string(dual.boundary_vertices_added) +
                         " boundary-strip vertices could not be brought to N exactly within the repair rounds";
  std::vector<uint32_t> defects = find_manifold_defects(dual.mesh.view());
  result.seconds.dual += seconds_since(t);
  stage("placement");
  t = std::chrono::steady_clock::now();
  // Final placement (defects do not depend on positions, so it is done once, here). QEM sites
  // already lie on the surface's features; centroids are projected onto the surface.
  {
    if (uses_quadrics(metric)) {
      state.use_offsets = false;  // the centroids themselves, the fallback of needle triangles
      std::vector<double> fallback = cluster_sites(items, state);
      if (options.project_to_surface) project_onto_clusters(mesh, labels, fallback);
      place_output_vertices(dual, z);
      result.sites_reverted = revert_needle_sites(dual, z, fallback);
    } else {
      if (options.project_to_surface) project_onto_clusters(mesh, labels, z);
      place_output_vertices(dual, z);
    }
  }
  if (!defects.empty()) {
    DefectRemoval removal = remove_manifold_defects(dual);
    result.defect_faces_removed = removal.faces_removed;
    result.defect_vertices_removed = removal.vertices_removed;
    defects = find_manifold_defects(dual.mesh.view());
  }
  result.defect_vertices = defects.size();
  result.seconds.placement = seconds_since(t);
  if (options.optimize_quality) {  // flips keep V, F, boundary and genus; moves stay on the input
    stage("optimize");
    t = std::chrono::steady_clock::now();
    MeshOptimizeOptions optimize = options.optimize;
    if (!options.project_to_surface) optimize.relax_iterations = 0;  // raw centroids asked for: flips only
    if (uses_quadrics(metric)) {  // QEM points: only nearly flat rings move, keeping their height
      optimize.feature_angle_deg = optimize.qem_feature_angle_deg;
      optimize.keep_surface_offset = true;
    }
    std::vector<uint8_t> movable(dual.mesh.vertex_count(), 0);
    std::vector<uint32_t> anchors(dual.mesh.vertex_count(), UINT32_MAX);
    if (optimize.relax_iterations > 0) {
      movable = remesh_movable_vertices(labels, result.budget, dual.cluster_of_output_vertex);
      anchors = cluster_anchor_faces(mesh, labels, dual.cluster_of_output_vertex, dual.mesh.positions);
    }
    const MeshOptimizeReport q =
        optimize_mesh_quality(dual.mesh.positions, dual.mesh.triangles, movable, &mesh, anchors, optimize);
    result.quality_flips = q.flips;
    result.quality_moves = q.moves;
    if (optimize.relax_iterations > 0) {  // strips after the interior: their cluster neighbours have settled
      StripShapeOptions strip;
      strip.keep_surface_offset = optimize.keep_surface_offset;
      strip.strip_spacing = dual_options.strip_spacing;
      const StripShapeReport sr = shape_boundary_strips(dual, mesh, boundary_loops, movable, anchors, strip);
      result.strip_moves = sr.strip_moves + sr.cluster_moves;
      result.quality_flips += sr.flips;
    }
    result.seconds.optimize = seconds_since(t);
  }
  stage("checks");
  t = std::chrono::steady_clock::now();
  {  // safety net: collinear float32 vertices (a cluster vertex on a strip chord) give flat faces
    const FlatFaceRepair flat = repair_flat_faces(dual.mesh.positions, dual.mesh.triangles);
    result.flat_faces_removed = flat.faces_removed;
    result.flat_face_flips = flat.flips + flat.nudges;
  }
  if (dual.mesh.face_count() == 0 && mesh.face_count() > 0)
    throw InputError("cannot build a valid surface with N=" + std::to_string(options.vertices) +
                     " vertices: the mesh's features are thinner than a cluster at this budget; use a larger N");
  // Topology check for closed inputs: the output must keep the Euler characteristic (genus per
  // component) and stay closed. A change is reported, never silent.
  {
    const InputClosure input = input_closure(mesh);
    result.input_euler_characteristic = input.euler_characteristic;
    result.output_euler_characteristic = euler_characteristic(dual.mesh.view());
    result.topology_changed = input.closed && (result.output_euler_characteristic != result.input_euler_characteristic ||
                                               result.defect_faces_removed > 0);
  }
  {  // Per component: one output piece each, genus kept, no new boundary loops.
    const std::vector<uint32_t> component_of_cluster = component_of_each_cluster(labels, result.budget, K);
    const std::vector<ComponentShape> shapes = input_component_shapes(
        mesh, result.budget.component_of_vertex, uint32_t(result.budget.clusters_per_component.size()), boundary_loops);
    result.components = check_component_topology(shapes, dual.mesh.view(), dual.cluster_of_output_vertex, component_of_cluster);
  }
  {
    const StripQuality sq = strip_face_quality(dual.mesh.positions, dual.mesh.triangles, dual.cluster_of_output_vertex);
    result.strip_faces = sq.strip_faces;
    result.strip_q_min = sq.strip_q_min;
    result.strip_q_avg = sq.strip_q_avg;
    result.other_q_avg = sq.other_q_avg;
  }
  result.duplicate_faces_removed = dual.duplicate_faces_removed;
  result.boundary_vertices_added = dual.boundary_vertices_added;
  result.holes_closed = dual.holes_closed;
  result.clusters_connected = clusters_connected(mesh, labels, K);
  result.seconds.checks = seconds_since(t);
  if (!options.attributes.empty()) {  // after every edit of the output's vertex set, while the labels exist
    stage("attributes");
    t = std::chrono::steady_clock::now();
    const std::vector<float> means = cluster_attribute_means(mesh, labels, K, options.attributes);
    result.vertex_attributes = output_vertex_attributes(means, dual, options.attributes);
    result.seconds.attributes = seconds_since(t);
  }
  result.mesh = std::move(dual.mesh);
  hand_over_vertex_labels(options.keep_vertex_labels, labels, result);
  if (progress) progress->finish();
  return result;
}

}  // namespace streamcvd
