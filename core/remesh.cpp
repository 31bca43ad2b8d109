#include "core/remesh.h"

#include "core/repair.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <chrono>
#include <numeric>
#include <random>

namespace streamcvd {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::vector<double> cluster_centroids(const ItemData& items, std::span<const ClusterSums> sums) {
  std::vector<double> z(3 * sums.size(), 0.0);
  for (size_t c = 0; c < sums.size(); ++c)
    for (int k = 0; k < 3; ++k)
      z[3 * c + k] = items.origin[k] + (sums[c].weight > 0 ? sums[c].sum[k] / sums[c].weight : 0.0);
  return z;
}

}  // namespace

RemeshResult remesh(const MeshView& mesh, const RemeshOptions& options) {
  RemeshResult result;
  auto t = std::chrono::steady_clock::now();
  ItemData items = compute_item_data(mesh, options.density);
  result.seconds.items = seconds_since(t);

  t = std::chrono::steady_clock::now();
  result.budget = plan_component_budget(mesh, items, options.vertices, options.small_components);
  const uint32_t K = result.budget.total_clusters;
  result.clusters = K;
  std::vector<int32_t> labels = initial_sampling(mesh, items, result.budget, options.seed);
  result.seconds.sampling = seconds_since(t);

  t = std::chrono::steady_clock::now();
  result.clustering = minimize_clustering(mesh, items, labels, K, options.clustering);
  result.seconds.clustering = seconds_since(t);

  // Compensating merges/splits of the repair stay in components with many clusters.
  std::vector<uint8_t> adjustable(K, 0);
  for (uint32_t v = 0; v < mesh.vertex_count(); ++v) {
    uint32_t c = result.budget.component_of_vertex[v];
    if (labels[v] >= 0 && c != UINT32_MAX && result.budget.clusters_per_component[c] >= 64) adjustable[labels[v]] = 1;
  }
  DualMeshOptions dual_options;
  dual_options.boundary_strips = options.boundary_strips;
  DualMesh dual;
  std::vector<uint32_t> defects;
  for (uint32_t round = 0;; ++round) {
    t = std::chrono::steady_clock::now();
    std::vector<ClusterSums> sums = accumulate_clusters(items, labels, K);
    result.final_energy = clustering_energy(items, sums);
    dual = build_dual_mesh(mesh, labels, K, cluster_centroids(items, sums), dual_options);
    defects = find_manifold_defects(dual.mesh.view());
    result.seconds.dual += seconds_since(t);
    if (std::getenv("STREAMCVD_DEBUG")) std::fprintf(stderr, "round %u: %zu defect vertices\n", round, defects.size());
    if (defects.empty() || round == options.repair_rounds) break;
    // Re-cluster around each defect: its clusters and their neighbours (a ring more each round).
    t = std::chrono::steady_clock::now();
    // Strip vertices have no cluster: take the clusters of the faces around them instead.
    std::vector<uint8_t> is_defect(dual.mesh.vertex_count(), 0);
    for (uint32_t v : defects) is_defect[v] = 1;
    std::vector<int32_t> bad_clusters;
    const auto& tri = dual.mesh.triangles;
    for (size_t f = 0; f < tri.size(); f += 3)
      if (is_defect[tri[f]] || is_defect[tri[f + 1]] || is_defect[tri[f + 2]])
        for (int k = 0; k < 3; ++k)
          if (dual.cluster_of_output_vertex[tri[f + k]] >= 0) bad_clusters.push_back(dual.cluster_of_output_vertex[tri[f + k]]);
    for (uint32_t v : defects)
      if (dual.cluster_of_output_vertex[v] >= 0) bad_clusters.push_back(dual.cluster_of_output_vertex[v]);
    RepairRoundStats round_stats;
    const std::vector<int32_t> touched = repair_clusters(mesh, items, labels, K, bad_clusters, adjustable, round_stats);
    result.repaired_clusters += touched.size();
    result.repair_splits += round_stats.splits;
    result.repair_merges += round_stats.merges;
    result.repair_islands += round_stats.dissolved_islands;
    // No relaxation after a repair: on a feature thinner than a cluster the energy minimum is
    // the defective clustering itself, and relaxing undoes the split (measured on the dragon:
    // defects do not decrease over rounds with relaxation, and do without).
    ++result.repair_rounds_used;
    result.seconds.repair += seconds_since(t);
  }
  if (std::getenv("STREAMCVD_DEBUG")) {
    std::vector<uint32_t> size(K, 0);
    for (int32_t l : labels)
      if (l >= 0) ++size[l];
    std::vector<uint32_t> degree(dual.mesh.vertex_count(), 0), strip(dual.mesh.vertex_count(), 0);
    for (uint32_t i : dual.mesh.triangles) ++degree[i];
    for (size_t f = 0; f < dual.mesh.triangles.size(); f += 3) {
      bool has_strip = false;
      for (int k = 0; k < 3; ++k) has_strip |= dual.cluster_of_output_vertex[dual.mesh.triangles[f + k]] < 0;
      if (has_strip)
        for (int k = 0; k < 3; ++k) strip[dual.mesh.triangles[f + k]] = 1;
    }
    std::vector<uint32_t> bnd(K, 0), zero(K, 0);
    std::vector<std::vector<int32_t>> nb(K);
    for (uint32_t v = 0; v < mesh.vertex_count(); ++v) {
      int32_t l = labels[v];
      if (l < 0) continue;
      if (mesh.vertex_flags[v] & kVertexBoundary) ++bnd[l];
      if (items.weight[v] == 0) ++zero[l];
      for (uint32_t n : mesh.neighbours(v))
        if (labels[n] >= 0 && labels[n] != l) nb[l].push_back(labels[n]);
    }
    for (uint32_t v : defects) {
      int32_t c = dual.cluster_of_output_vertex[v];
      if (c >= 0) {
        auto& x = nb[c];
        std::sort(x.begin(), x.end());
        x.erase(std::unique(x.begin(), x.end()), x.end());
        std::fprintf(stderr, "  cluster %d: boundary verts %u zero-weight %u neighbour clusters %zu\n", c, bnd[c], zero[c], x.size());
      }
      std::fprintf(stderr, "defect v%u cluster %d size %u faces %u strip %u comp %u\n", v, c, c >= 0 ? size[c] : 0, degree[v], strip[v],
                   c >= 0 ? result.budget.component_of_vertex[std::find(labels.begin(), labels.end(), c) - labels.begin()] : 0);
    }
    const auto& P = dual.mesh.positions;
    const auto& Tr = dual.mesh.triangles;
    for (size_t f = 0; f < Tr.size(); f += 3) {
      double e1[3], e2[3];
      for (int k = 0; k < 3; ++k) {
        e1[k] = P[3 * Tr[f + 1] + k] - P[3 * Tr[f] + k];
        e2[k] = P[3 * Tr[f + 2] + k] - P[3 * Tr[f] + k];
      }
      double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2], cz = e1[0] * e2[1] - e1[1] * e2[0];
      double a = std::sqrt(cx * cx + cy * cy + cz * cz);
      if (a < 1e-12) std::fprintf(stderr, "zero-area face %g (%g %g %g) (%g %g %g) (%g %g %g) %u %u %u clusters %d %d %d\n", a,
                                  P[3*Tr[f]],P[3*Tr[f]+1],P[3*Tr[f]+2],P[3*Tr[f+1]],P[3*Tr[f+1]+1],P[3*Tr[f+1]+2],P[3*Tr[f+2]],P[3*Tr[f+2]+1],P[3*Tr[f+2]+2],
                                  Tr[f], Tr[f + 1], Tr[f + 2],
                                  dual.cluster_of_output_vertex[Tr[f]], dual.cluster_of_output_vertex[Tr[f + 1]],
                                  dual.cluster_of_output_vertex[Tr[f + 2]]);
    }
  }
  if (!defects.empty()) {
    DefectRemoval removal = remove_manifold_defects(dual.mesh, dual.cluster_of_output_vertex);
    result.defect_faces_removed = removal.faces_removed;
    result.defect_vertices_removed = removal.vertices_removed;
    defects = find_manifold_defects(dual.mesh.view());
  }
  result.defect_vertices = defects.size();
  result.duplicate_faces_removed = dual.duplicate_faces_removed;
  result.boundary_vertices_added = dual.boundary_vertices_added;
  result.holes_closed = dual.holes_closed;
  result.clusters_connected = clusters_connected(mesh, labels, K);
  result.mesh = std::move(dual.mesh);
  result.cluster_of_vertex = std::move(labels);
  return result;
}

}  // namespace streamcvd
