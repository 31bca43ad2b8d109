// Tests of core/clustering/cluster_energy.h: the O(1) move test of every metric equals the difference of
// the full energies (eqs. 12-18), the incremental accumulators equal a fresh rebuild, and the
// QEM sites stay within their clusters.
#include "streamcvd/core/clustering/cluster_energy.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

#include "streamcvd/core/clustering/clustering.h"
#include "streamcvd/core/fields/metric_field.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

using Stored = test::StoredMesh;

// Random symmetric positive definite tensors (B Bᵀ + 0.1 I), 6 floats per vertex.
std::vector<float> random_tensors(uint32_t V, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<float> t(6 * size_t(V));
  for (uint32_t v = 0; v < V; ++v) {
    double B[3][3];
    for (auto& row : B)
      for (double& x : row) x = u(rng);
    double K[3][3];
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) K[i][j] = B[i][0] * B[j][0] + B[i][1] * B[j][1] + B[i][2] * B[j][2] + (i == j ? 0.1 : 0.0);
    const double packed[6] = {K[0][0], K[0][1], K[0][2], K[1][1], K[1][2], K[2][2]};
    for (int k = 0; k < 6; ++k) t[6 * size_t(v) + k] = float(packed[k]);
  }
  return t;
}

struct Fixture {
  Stored mesh{make_torus(40, 16)};
  ItemData items;
  std::vector<int32_t> labels;
  uint32_t K = 0;
  Fixture() {
    items = compute_item_data(mesh.view, {}, ram_storage(), ItemQuadrics::per_vertex);
    attach_tensors(items, large_array_of(std::span<const float>(random_tensors(mesh.view.vertex_count(), 7))));
    ComponentBudget b = plan_component_budget(mesh.view, items, 30, SmallComponents::Keep, ram_storage());
    K = b.total_clusters;
    labels = test::to_vector(initial_sampling(mesh.view, items, b, 3, ram_storage()));
  }
};

// For every metric, with and without (frozen) QEM offsets: the predicted energy change of a
// boundary move equals the change of the full energy.
TEST(ClusterEnergy, MoveDeltaEqualsEnergyDifference) {
  Fixture f;
  const MeshView& mesh = f.mesh.view;
  for (Metric metric : {Metric::I, Metric::IQ, Metric::A, Metric::AQ}) {
    for (bool offsets : {false, true}) {
      if (offsets && !uses_quadrics(metric)) continue;
      SCOPED_TRACE(std::string(metric_name(metric)) + (offsets ? " with offsets" : ""));
      std::vector<int32_t> labels = f.labels;
      ClusterState state = make_cluster_state(f.items, labels, f.K, metric);
      ASSERT_EQ(state.metric, metric);
      if (offsets) update_site_offsets(state);
      int tested = 0;
      for (uint32_t v = 0; v < mesh.vertex_count() && tested < 200; v += 7) {
        for (uint32_t n : mesh.neighbours(v)) {
          const int32_t a = labels[v], b = labels[n];
          if (a == b || state.iso[a].count < 2) continue;
          const MoveDelta d = move_delta(f.items, state, v, a, b);
          const double before = state_energy(f.items, state);
          apply_move(f.items, state, v, a, b);
          labels[v] = b;
          const double after = state_energy(f.items, state);
          EXPECT_NEAR(before - after, d.decrease - d.increase, 1e-7 * before) << "vertex " << v;
          ++tested;
          break;
        }
      }
      EXPECT_GE(tested, 50);
      // The incremental sums equal a rebuild from the labels.
      ClusterState fresh = make_cluster_state(f.items, labels, f.K, metric);
      for (uint32_t c = 0; c < f.K; ++c) {
        EXPECT_EQ(state.iso[c].count, fresh.iso[c].count);
        EXPECT_NEAR(state.iso[c].weight, fresh.iso[c].weight, 1e-9 * f.items.total_weight);
        if (is_anisotropic(metric)) {
          for (int k = 0; k < 3; ++k) EXPECT_NEAR(state.aniso[c].centroid[k], fresh.aniso[c].centroid[k], 1e-6);
        }
      }
    }
  }
}

TEST(ClusterEnergy, IsotropicTensorsReduceAnisotropicToIsotropic) {
  // K_j = M_j·I: eq. 17 reduces to eq. 14 (the paper's remark after eq. 18).
  Fixture f;
  std::vector<float> identity(6 * size_t(f.mesh.view.vertex_count()), 0.0f);
  for (size_t v = 0; v < identity.size() / 6; ++v) identity[6 * v] = identity[6 * v + 3] = identity[6 * v + 5] = 1.0f;
  attach_tensors(f.items, large_array_of(std::span<const float>(identity)));
  const ClusterState iso = make_cluster_state(f.items, f.labels, f.K, Metric::I);
  const ClusterState aniso = make_cluster_state(f.items, f.labels, f.K, Metric::A);
  EXPECT_NEAR(state_energy(f.items, iso), state_energy(f.items, aniso), 1e-9 * state_energy(f.items, iso));
  for (uint32_t v = 0; v < 200; ++v)
    for (uint32_t n : f.mesh.view.neighbours(v)) {
      const int32_t a = f.labels[v], b = f.labels[n];
      if (a == b) continue;
      const MoveDelta di = move_delta(f.items, iso, v, a, b), da = move_delta(f.items, aniso, v, a, b);
      EXPECT_NEAR(di.decrease, da.decrease, 1e-9 + 1e-7 * di.decrease);
      EXPECT_NEAR(di.increase, da.increase, 1e-9 + 1e-7 * di.increase);
    }
}

TEST(ClusterEnergy, MetricsWithoutTheirDataAreAnError) {
  // A metric is never swapped for another: items without tensors (A, AQ) or quadrics (IQ, AQ)
  // are refused, and with them the state has the metric asked for.
  Fixture f;
  ItemData plain = compute_item_data(f.mesh.view);
  for (Metric m : {Metric::IQ, Metric::A, Metric::AQ})
    EXPECT_THROW(make_cluster_state(plain, f.labels, f.K, m), std::invalid_argument) << metric_name(m);
  EXPECT_EQ(make_cluster_state(plain, f.labels, f.K, Metric::I).metric, Metric::I);
  plain.quadric = f.items.quadric.clone();
  EXPECT_EQ(make_cluster_state(plain, f.labels, f.K, Metric::IQ).metric, Metric::IQ);
  EXPECT_THROW(make_cluster_state(plain, f.labels, f.K, Metric::AQ), std::invalid_argument);
  EXPECT_EQ(make_cluster_state(f.items, f.labels, f.K, Metric::AQ).metric, Metric::AQ);
}

TEST(ClusterEnergy, QemSitesStayNearTheirClusters) {
  // Offsets are bounded by 0.75·√W, and on a smooth torus they stay small next to the cluster
  // size (QEM points of curved clusters lie on the surface, centroids inside it).
  Fixture f;
  ClusterState s = make_cluster_state(f.items, f.labels, f.K, Metric::IQ);
  update_site_offsets(s);
  ASSERT_TRUE(s.use_offsets);
  double largest = 0;
  for (uint32_t c = 0; c < f.K; ++c) {
    const double* d = &s.offset[3 * size_t(c)];
    const double norm = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    EXPECT_LE(norm, 0.75 * std::sqrt(s.iso[c].weight) * (1 + 1e-9));
    largest = std::max(largest, norm / std::sqrt(s.iso[c].weight));
  }
  EXPECT_GT(largest, 0.0) << "curved clusters must move off their centroid";
  // The IQ energy with QEM sites is the I energy plus Σ W‖d‖² ≥ it.
  const ClusterState i = make_cluster_state(f.items, f.labels, f.K, Metric::I);
  EXPECT_GE(state_energy(f.items, s), state_energy(f.items, i));
}

TEST(ClusterEnergy, AnisotropicPassesNeverRaiseTheEnergy) {
  Fixture f;
  ClusteringOptions o;
  o.metric = Metric::A;
  o.loops.threads = 1;
  std::vector<int32_t> labels = f.labels;
  ClusteringReport r = minimize_clustering(f.mesh.view, f.items, labels, f.K, o);
  EXPECT_EQ(r.metric, Metric::A);
  const auto& e = r.energy_per_loop;
  ASSERT_GE(e.size(), 2u);
  const size_t first = r.unconstrained_loops;
  for (size_t i = 1; i < e.size(); ++i)
    if (i != first) {  // the cleaning between the passes may raise it
      EXPECT_LE(e[i], e[i - 1] * (1 + 1e-12)) << "loop " << i;
    }
  EXPECT_TRUE(clusters_connected(f.mesh.view, labels, f.K));
}

TEST(ClusterEnergy, MetricNames) {
  for (Metric m : {Metric::I, Metric::IQ, Metric::A, Metric::AQ}) {
    Metric parsed = Metric::I;
    ASSERT_TRUE(parse_metric(metric_name(m), parsed));
    EXPECT_EQ(parsed, m);
  }
  Metric m = Metric::I;
  EXPECT_TRUE(parse_metric("aq", m));
  EXPECT_EQ(m, Metric::AQ);
  EXPECT_FALSE(parse_metric("Q", m));
  EXPECT_FALSE(parse_metric("", m));
}

}  // namespace
}  // namespace streamcvd
