// The stages of remesh() from the repaired clustering to the output (core/remesh_stages.h): the
// dual, the placement of its vertices, the quality pass, the checks, the carried attributes.
#include <tbb/parallel_invoke.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "streamcvd/core/dual/placement.h"
#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/remesh_stages.h"
#include "streamcvd/core/mesh/triangle_quality.h"

namespace streamcvd::stages {

namespace {

// Each cluster's output vertex at its site z (3 doubles per cluster, stored as float).
void place_output_vertices(DualMesh& dual, std::span<const double> z) {
  for (uint32_t v = 0; v < dual.mesh.vertex_count(); ++v) {
    const int32_t c = dual.cluster_of_output_vertex[v];
    if (c >= 0)
      for (int k = 0; k < 3; ++k) dual.mesh.positions[3 * size_t(v) + k] = float(z[3 * size_t(c) + k]);
  }
}

// QEM sites of three clusters along one straight crease are collinear, and two clusters may
// share a corner: their triangle is a needle or has no area at all. Such a triangle is worse
// than the small approximation gain, so its clusters fall back to their projected centroids.
// The fallbacks (centroids in `fallback`) are projected only for the corners of needles, when
// they are first needed: a projection is a pass over the input's faces, and most runs have no
// needle (dragon ×9 → 300k, IQ: 0.3 s for none). Returns the number of sites reverted.
uint64_t revert_needle_sites(Job& job, const Clusters& c, DualMesh& dual, std::vector<double>& z,
                             std::vector<double>& fallback) {
  constexpr double kNeedleQuality = 1e-4;
  constexpr int kMaxPasses = 9;
  uint64_t reverted = 0;
  const size_t K = z.size() / 3;
  std::vector<uint8_t> done(K, 0), projected(K, 0), wanted(K, 0);
  auto site = [](const std::vector<double>& xyz, int32_t c) {
    return vec3::Vec3{xyz[3 * size_t(c)], xyz[3 * size_t(c) + 1], xyz[3 * size_t(c) + 2]};
  };
  auto moved2 = [&](int32_t c) {
    const vec3::Vec3 d = vec3::sub(site(z, c), site(fallback, c));
    return vec3::dot(d, d);
  };
  const auto& tri = dual.mesh.triangles;
  std::vector<size_t> needles;
  for (int pass = 0; pass < kMaxPasses; ++pass) {
    needles.clear();
    bool more = false;  // corners whose fallback is not projected yet
    for (size_t f = 0; f < tri.size(); f += 3) {
      if (triangle_quality(vec3::point(dual.mesh.positions, tri[f]), vec3::point(dual.mesh.positions, tri[f + 1]),
                           vec3::point(dual.mesh.positions, tri[f + 2])) >= kNeedleQuality)
        continue;
      needles.push_back(f);
      for (int k = 0; k < 3; ++k)
        if (const int32_t cl = dual.cluster_of_output_vertex[tri[f + k]]; cl >= 0 && !done[cl] && !projected[cl])
          wanted[cl] = 1, projected[cl] = 1, more = true;
    }
    if (more && job.options.project_to_surface) {
      project_onto_clusters(job.mesh(), c.labels, fallback, wanted);
      std::fill(wanted.begin(), wanted.end(), 0);
    }
    bool changed = false;
    for (size_t f : needles) {
      // Revert one site per needle and pass: the one that moved least from its fallback (a crease
      // point before a corner), so a corner is kept whenever a crease neighbour can give way.
      int32_t pick = -1;
      double least = std::numeric_limits<double>::infinity();
      for (int k = 0; k < 3; ++k) {
        const int32_t cl = dual.cluster_of_output_vertex[tri[f + k]];
        if (cl < 0 || done[cl]) continue;
        const double d2 = moved2(cl);
        if (d2 < least) {
          least = d2;
          pick = cl;
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

}  // namespace

DualStage build_dual(Job& job, const ItemData& items, Clusters& c, const BoundaryLoops& loops, dual::Triples triples) {
  job.begin("dual");
  DualStage d;
  d.state = solved_cluster_state(items, c.labels, c.K, job.clustering);
  d.report.final_energy = state_energy(items, d.state);
  d.sites = cluster_sites(items, d.state);
  d.dual = build_dual_mesh(job.mesh(), c.labels, c.K, d.sites, c.dual, &loops, std::move(triples));
  d.report.vertex_shortfall = int64_t(job.options.vertices) - int64_t(d.dual.mesh.vertex_count());
  d.report.duplicate_faces_removed = d.dual.duplicate_faces_removed;
  d.report.boundary_vertices_added = d.dual.boundary_vertices_added;
  d.report.holes_closed = d.dual.holes_closed;
  if (d.report.vertex_shortfall != 0 && c.budget.note.empty())
    c.budget.note = "the clusters and the " + std::to_string(d.dual.boundary_vertices_added) +
                    " boundary-strip vertices could not be brought to N exactly within the repair rounds";
  d.defects = find_manifold_defects(d.dual.mesh.view());
  job.seconds.dual += job.elapsed();
  return d;
}

// Final placement (defects do not depend on positions, so it is done once, here). QEM sites
// already lie on the surface's features; centroids are projected onto the surface. Then the
// last-resort cleanup of the defects the repair left.
PlacementReport place_output(Job& job, const ItemData& items, const Clusters& c, DualStage& d) {
  job.begin("placement");
  PlacementReport report;
  const bool project = job.options.project_to_surface;
  if (job.plan.quadrics) {
    d.state.use_offsets = false;  // the centroids themselves, the fallback of needle triangles
    std::vector<double> fallback = cluster_sites(items, d.state);
    place_output_vertices(d.dual, d.sites);
    report.sites_reverted = revert_needle_sites(job, c, d.dual, d.sites, fallback);
  } else {
    if (project) project_onto_clusters(job.mesh(), c.labels, d.sites);
    place_output_vertices(d.dual, d.sites);
  }
  if (!d.defects.empty()) {
    report.defects_removed = remove_manifold_defects(d.dual);
    d.defects = find_manifold_defects(d.dual.mesh.view());
  }
  report.defect_vertices = d.defects.size();
  job.seconds.placement = job.elapsed();
  return report;
}

// The quality post-pass: flips keep V, F, boundary and genus; moves stay on the input. The
// strips are shaped after the interior, once their cluster neighbours have settled.
QualityPassReport improve_quality(Job& job, const Clusters& c, const BoundaryLoops& loops, DualMesh& dual) {
  job.begin("optimize");
  QualityPassReport report;
  const MeshOptimizeOptions& optimize = job.plan.optimize_options;
  const bool relax = optimize.relax_iterations > 0;
  std::vector<uint8_t> movable(dual.mesh.vertex_count(), 0);
  std::vector<uint32_t> anchors(dual.mesh.vertex_count(), UINT32_MAX);
  if (relax) {
    movable = remesh_movable_vertices(c.labels, c.budget, dual.cluster_of_output_vertex);
    anchors = cluster_anchor_faces(job.mesh(), c.labels, dual.cluster_of_output_vertex, dual.mesh.positions);
  }
  report.interior =
      optimize_mesh_quality(dual.mesh.positions, dual.mesh.triangles, movable, &job.mesh(), anchors, optimize);
  if (relax) {
    StripShapeOptions strip;
    strip.keep_surface_offset = optimize.keep_surface_offset;
    strip.strip_spacing = c.dual.strip_spacing;
    report.strips = shape_boundary_strips(dual, job.mesh(), loops, movable, anchors, strip);
  }
  job.seconds.optimize = job.elapsed();
  return report;
}

// The checks: first the safety net for flat faces (collinear float32 vertices: a cluster
// vertex on a strip chord), then the topology of closed inputs (the Euler characteristic and
// closure kept; a change is reported, never silent), one output piece per input component
// with its genus and no new loops, the strip quality and the clusters' connectivity.
OutputChecks check_output(Job& job, const Clusters& c, const BoundaryLoops& loops, const PlacementReport& placement,
                          DualMesh& dual) {
  job.begin("checks");
  const MeshView& mesh = job.mesh();
  OutputChecks checks;
  checks.flat_faces = repair_flat_faces(dual.mesh.positions, dual.mesh.triangles);
  if (dual.mesh.face_count() == 0 && mesh.face_count() > 0)
    throw InputError("cannot build a valid surface with N=" + std::to_string(job.options.vertices) +
                     " vertices: the mesh's features are thinner than a cluster at this budget; use a larger N");
  // The component check (mostly serial) beside the others, which only read.
  tbb::parallel_invoke(
      [&] {
        const std::vector<uint32_t> component_of_cluster = component_of_each_cluster(c.labels, c.budget, c.K);
        const std::vector<ComponentShape> shapes = input_component_shapes(
            mesh, c.budget.component_of_vertex, uint32_t(c.budget.clusters_per_component.size()), loops);
        checks.components =
            check_component_topology(shapes, dual.mesh.view(), dual.cluster_of_output_vertex, component_of_cluster);
      },
      [&] {
        checks.strips = strip_face_quality(dual.mesh.positions, dual.mesh.triangles, dual.cluster_of_output_vertex);
        checks.clusters_connected = clusters_connected(mesh, c.labels, c.K);
      });
  const InputClosure input = input_closure(mesh);
  // Over the components that got clusters: a dropped piece (a small one, a cut sheet) takes its
  // Euler characteristic with it.
  checks.input_euler_characteristic = checks.components.input_euler_characteristic;
  checks.output_euler_characteristic = checks.components.output_euler_characteristic;
  // A deletion fails the check on an open input too: its holes are new, even where the cleaned
  // input has more loops than the output (crude scans: 69 faces deleted at 26M faces, 199,976
  // vertices for 200,000 asked, and "checks all passed").
  checks.topology_changed = placement.defects_removed.faces_removed > 0 ||
                            (input.closed && checks.output_euler_characteristic != checks.input_euler_characteristic);
  job.seconds.checks = job.elapsed();
  return checks;
}

// The carried attributes, after every edit of the output's vertex set, while the labels exist.
std::vector<float> carry_attributes(Job& job, const Clusters& c, const DualMesh& dual) {
  job.begin("attributes");
  const std::vector<float> means = cluster_attribute_means(job.mesh(), c.labels, c.K, job.options.attributes);
  std::vector<float> rows = output_vertex_attributes(means, dual, job.options.attributes);
  job.seconds.attributes = job.elapsed();
  return rows;
}

}  // namespace streamcvd::stages
