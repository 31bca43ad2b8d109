// Algorithm 1 of the paper (boundary-edge FIFO minimisation), the cleaning step and the
// connectivity-constrained pass (§VI-A, §VI-B). The loops themselves are in
// parallel_clustering.cpp (one code path for any thread count).
#include "streamcvd/core/clustering/clustering.h"

#include <cctype>
#include <cmath>
#include <numbers>
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

namespace {

// Marks the clusters whose site moved by more than 1e-6 of the mean cluster radius: what the
// drift of incremental sums (or Q offsets frozen after offset_update_loops) left behind.
void mark_moved_sites(std::span<const double> before, std::span<const double> after, double area,
                      std::vector<uint8_t>& marks) {
  const size_t K = marks.size();
  const double radius = K > 0 ? std::sqrt(area / (double(K) * std::numbers::pi)) : 0.0;
  const double tolerance2 = 1e-12 * radius * radius;
  for (size_t c = 0; c < K; ++c) {
    const double dx = after[3 * c] - before[3 * c], dy = after[3 * c + 1] - before[3 * c + 1],
                 dz = after[3 * c + 2] - before[3 * c + 2];
    if (!(dx * dx + dy * dy + dz * dz <= tolerance2)) marks[c] = 1;
  }
}

}  // namespace

ClusteringReport minimize_clustering(const MeshView& mesh, const ItemData& items, std::span<int32_t> labels,
                                     uint32_t cluster_count, const ClusteringOptions& options) {
  ClusteringReport report;
  LoopOptions pass = options.loops;
  pass.constrained = false;
  // First convergence with centroid sites (I or A: nothing to solve); the Q metrics then embed
  // the QEM sites (§V-C) and converge again before the cleaning.
  const Metric centroids = is_anisotropic(options.metric) ? Metric::A : Metric::I;
  ClusterState state = make_cluster_state(items, labels, cluster_count, centroids);
  // The clusters whose boundaries the next pass must test: the constrained pass goes on where
  // the unconstrained one stopped (at stop_fraction), so it starts from those the last loop
  // changed, those the cleaning changed and those whose site the rebuilt sums moved; the
  // others are stable. (Starting from every cluster cost a full sweep: dragon ×9 → 300k, I,
  // 0.19 s of 1.2 s.)
  std::vector<uint8_t> unsettled;
  report.unconstrained_loops = run_clustering_loops(mesh, items, labels, state, pass, report, {}, &unsettled);
  if (uses_quadrics(options.metric)) {
    state = solved_cluster_state(items, labels, cluster_count, options);
    report.unconstrained_loops += run_clustering_loops(mesh, items, labels, state, pass, report, {}, &unsettled);
  }
  clean_clusters(mesh, items, labels, cluster_count, report, pass.storage ? *pass.storage : ram_storage(), &unsettled);
  // Incremental sums drift: rebuild them before the constrained pass (DESIGN.md §3).
  const std::vector<double> sites_before = cluster_sites(items, state);
  state = solved_cluster_state(items, labels, cluster_count, options);
  mark_moved_sites(sites_before, cluster_sites(items, state), items.total_area, unsettled);
  pass.constrained = true;
  pass.stop_fraction = 0.0;
  report.constrained_loops = run_clustering_loops(mesh, items, labels, state, pass, report, unsettled);
  report.metric = state.metric;
  report.final_energy = state_energy(items, state);
  return report;
}

}  // namespace streamcvd
