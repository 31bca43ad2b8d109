// Algorithm 1 of the paper (boundary-edge FIFO minimisation), the cleaning step and the
// connectivity-constrained pass (§VI-A, §VI-B). The loops themselves are in
// parallel_clustering.cpp (one code path for any thread count).
#include "streamcvd/core/clustering/clustering.h"

#include <cctype>
#include <string>

#include "streamcvd/core/clustering/parallel_clustering.h"

namespace streamcvd {

const char* algorithm_name(ClusteringOptions::Algorithm algorithm) {
  return algorithm == ClusteringOptions::Algorithm::Lloyd ? "lloyd" : "cvd";
}

bool parse_algorithm(std::string_view text, ClusteringOptions::Algorithm& out) {
  std::string lower;
  for (char ch : text) lower.push_back(char(std::tolower(static_cast<unsigned char>(ch))));
  for (auto a : {ClusteringOptions::Algorithm::Cvd, ClusteringOptions::Algorithm::Lloyd})
    if (lower == algorithm_name(a)) {
      out = a;
      return true;
    }
  return false;
}

std::vector<ClusterSums> accumulate_clusters(const ItemData& items, std::span<const int32_t> labels,
                                             uint32_t cluster_count) {
  return make_cluster_state(items, labels, cluster_count, Metric::I).iso;
}

double clustering_energy(const ItemData& items, std::span<const ClusterSums> sums) {
  ClusterState s;
  s.iso.assign(sums.begin(), sums.end());
  return state_energy(items, s);
}

ClusteringReport minimize_clustering(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                                     uint32_t cluster_count, const ClusteringOptions& options) {
  ClusteringReport report;
  LoopOptions pass = options.loops;
  pass.constrained = false;
  // First convergence with centroid sites (I or A: nothing to solve); the Q metrics then embed
  // the QEM sites (§V-C) and converge again before the cleaning.
  const Metric centroids = is_anisotropic(options.metric) ? Metric::A : Metric::I;
  ClusterState state = make_cluster_state(items, labels, cluster_count, centroids);
  report.unconstrained_loops = run_clustering_loops(mesh, items, labels, state, pass, report);
  if (uses_quadrics(options.metric)) {
    state = solved_cluster_state(items, labels, cluster_count, options);
    report.unconstrained_loops += run_clustering_loops(mesh, items, labels, state, pass, report);
  }
  clean_clusters(mesh, items, labels, cluster_count, report, pass.storage ? *pass.storage : ram_storage());
  // Incremental sums drift: rebuild them before the constrained pass (DESIGN.md §3).
  state = solved_cluster_state(items, labels, cluster_count, options);
  pass.constrained = true;
  pass.stop_fraction = 0.0;
  report.constrained_loops = run_clustering_loops(mesh, items, labels, state, pass, report);
  report.metric = state.metric;
  report.final_energy = state_energy(items, state);
  return report;
}

}  // namespace streamcvd
