// Tests of core/clustering/clustering.h and core/clustering/item_data.h: item weights, component budget, initial
// sampling (§VI-G), Algorithm 1 energy descent (§VI-A), cleaning and the connectivity-
// constrained pass (§VI-B).
#include "streamcvd/core/clustering/clustering.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <string>
#include <vector>

#include "streamcvd/core/clustering/item_data.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

using Stored = test::StoredMesh;

// Appends `b` to `a` as a separate component.
void append(MeshBuffers& a, const MeshBuffers& b) {
  const uint32_t offset = a.vertex_count();
  a.positions.insert(a.positions.end(), b.positions.begin(), b.positions.end());
  for (uint32_t i : b.triangles) a.triangles.push_back(i + offset);
}

MeshBuffers translated(MeshBuffers m, float dx, float dy, float dz) {
  for (size_t i = 0; i < m.positions.size(); i += 3) {
    m.positions[i] += dx;
    m.positions[i + 1] += dy;
    m.positions[i + 2] += dz;
  }
  return m;
}

MeshBuffers tetrahedron(float size) {
  MeshBuffers m;
  m.positions = {0, 0, 0, size, 0, 0, 0, size, 0, 0, 0, size};
  m.triangles = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  return m;
}

// Connectivity of every cluster checked independently of clusters_connected(): union-find over
// the mesh edges whose two ends share a label, then one root per label.
bool every_cluster_connected_bfs(const MeshView& mesh, const std::vector<int32_t>& labels, uint32_t K) {
  const uint32_t V = mesh.vertex_count();
  std::vector<uint8_t> seen(V, 0);
  std::vector<uint32_t> pieces(K, 0);
  for (uint32_t s = 0; s < V; ++s) {
    if (labels[s] < 0 || seen[s]) continue;
    ++pieces[labels[s]];
    std::vector<uint32_t> stack = {s};
    seen[s] = 1;
    while (!stack.empty()) {
      uint32_t u = stack.back();
      stack.pop_back();
      for (uint64_t f : mesh.faces_of(u))
        for (int k = 0; k < 3; ++k) {
          uint32_t n = mesh.triangles[3 * f + k];
          if (!seen[n] && labels[n] == labels[s]) {
            seen[n] = 1;
            stack.push_back(n);
          }
        }
    }
  }
  for (uint32_t c = 0; c < K; ++c)
    if (pieces[c] > 1) return false;
  return true;
}

// Checks every label lies in [0, K) and every cluster is non-empty; returns the cluster sizes.
std::vector<uint32_t> expect_valid_labels(const MeshView& mesh, const std::vector<int32_t>& labels, uint32_t K) {
  std::vector<uint32_t> size(K, 0);
  EXPECT_EQ(labels.size(), mesh.vertex_count());
  for (uint32_t v = 0; v < labels.size(); ++v) {
    const bool on_face = !mesh.faces_of(v).empty();
    if (!on_face) {
      EXPECT_EQ(labels[v], -1) << "isolated vertex " << v << " got a label";
      continue;
    }
    EXPECT_GE(labels[v], 0) << "vertex " << v;
    EXPECT_LT(labels[v], int32_t(K)) << "vertex " << v;
    if (labels[v] >= 0 && labels[v] < int32_t(K)) ++size[labels[v]];
  }
  for (uint32_t c = 0; c < K; ++c) EXPECT_GT(size[c], 0u) << "cluster " << c << " is empty";
  return size;
}

// energy_per_loop must not increase between consecutive loops of [begin, end).
void expect_non_increasing(const std::vector<double>& energy, size_t begin, size_t end, const std::string& what) {
  for (size_t i = begin + 1; i < end; ++i)
    EXPECT_LE(energy[i], energy[i - 1] * (1.0 + 1e-12) + 1e-300)
        << what << ": energy rose at loop " << i - begin << " (" << energy[i - 1] << " -> " << energy[i] << ")";
}

// --- items -------------------------------------------------------------------------------------

TEST(ClusteringItems, WeightsSumToAreaAndCentroidsMatchSurfaceCentroid) {
  // Grid [0,2]×[0,1]: total area 2, area centroid (1, 0.5, 0).
  Stored m(make_grid(21, 11, 2.0f, 1.0f));
  ItemData items = compute_item_data(m.view);
  ASSERT_EQ(items.weight.size(), m.view.vertex_count());
  EXPECT_NEAR(items.total_weight, 2.0, 1e-9);
  double s[3] = {0, 0, 0};
  for (uint32_t v = 0; v < m.view.vertex_count(); ++v) {
    EXPECT_GT(items.weight[v], 0.0);
    for (int k = 0; k < 3; ++k) s[k] += items.weight[v] * (items.centroid[3 * v + k] + items.origin[k]);
  }
  EXPECT_NEAR(s[0] / items.total_weight, 1.0, 1e-6);
  EXPECT_NEAR(s[1] / items.total_weight, 0.5, 1e-6);
  EXPECT_NEAR(s[2] / items.total_weight, 0.0, 1e-6);
  // A density doubles every weight it is 2 for.
  std::vector<float> rho(m.view.vertex_count(), 2.0f);
  ItemData dense = compute_item_data(m.view, rho);
  EXPECT_NEAR(dense.total_weight, 4.0, 1e-9);
}

// --- component budget and initial sampling (§VI-G) --------------------------------------------

TEST(ClusteringSampling, EveryClusterNonEmptyLabelsInRangeBudgetExact) {
  struct Case {
    std::string name;
    MeshBuffers mesh;
    uint32_t clusters;
  };
  std::vector<Case> cases;
  cases.push_back({"icosphere3", make_icosphere(3), 100});
  cases.push_back({"icosphere3-many", make_icosphere(3), 600});  // 642 V: near one vertex per cluster
  cases.push_back({"torus", make_torus(40, 20), 150});
  cases.push_back({"grid", make_grid(30, 30), 77});
  cases.push_back({"grid-all", make_grid(8, 8), 64});  // exactly one vertex per cluster
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    Stored m(c.mesh);
    ItemData items = compute_item_data(m.view);
    ComponentBudget budget = plan_component_budget(m.view, items, c.clusters, SmallComponents::Keep, ram_storage());
    EXPECT_EQ(budget.total_clusters, c.clusters) << budget.note;
    ASSERT_EQ(budget.clusters_per_component.size(), 1u);
    for (uint64_t seed : {1ull, 2ull, 12345ull}) {
      std::vector<int32_t> labels = test::to_vector(initial_sampling(m.view, items, budget, seed, ram_storage()));
      expect_valid_labels(m.view, labels, budget.total_clusters);
    }
  }
}

TEST(ClusteringSampling, BudgetSplitsOverComponentsInProportionToArea) {
  // Two spheres, radius 1 and 2 (area ratio 1:4), plus three tiny tetrahedra (4 V each).
  MeshBuffers soup = make_icosphere(3, 1.0f);
  append(soup, translated(make_icosphere(3, 2.0f), 5, 0, 0));
  for (int i = 0; i < 3; ++i) append(soup, translated(tetrahedron(0.01f), -3.0f - float(i), 0, 0));
  Stored m(soup);
  ItemData items = compute_item_data(m.view);

  ComponentBudget keep = plan_component_budget(m.view, items, 500, SmallComponents::Keep, ram_storage());
  ASSERT_EQ(keep.clusters_per_component.size(), 5u);
  EXPECT_EQ(keep.total_clusters, 500u) << keep.note;
  EXPECT_EQ(keep.small_components_kept, 3u);
  EXPECT_EQ(keep.components_dropped, 0u);
  std::vector<uint32_t> sorted = keep.clusters_per_component;
  std::sort(sorted.begin(), sorted.end());
  // Tiny tetrahedra are copied as they are (one cluster per vertex), the spheres share the rest 1:4.
  EXPECT_EQ(sorted[0], 4u);
  EXPECT_EQ(sorted[1], 4u);
  EXPECT_EQ(sorted[2], 4u);
  EXPECT_NEAR(double(sorted[3]), 488.0 / 5.0, 2.0);
  EXPECT_NEAR(double(sorted[4]), 488.0 * 4.0 / 5.0, 2.0);
  std::vector<int32_t> labels = test::to_vector(initial_sampling(m.view, items, keep, 7, ram_storage()));
  expect_valid_labels(m.view, labels, keep.total_clusters);
  // Labels never cross components.
  std::vector<int64_t> component_of_label(keep.total_clusters, -1);
  for (uint32_t v = 0; v < m.view.vertex_count(); ++v) {
    int32_t l = labels[v];
    if (l < 0) continue;
    if (component_of_label[l] < 0) component_of_label[l] = keep.component_of_vertex[v];
    EXPECT_EQ(component_of_label[l], int64_t(keep.component_of_vertex[v])) << "label " << l << " spans components";
  }

  ComponentBudget drop = plan_component_budget(m.view, items, 500, SmallComponents::Drop, ram_storage());
  EXPECT_EQ(drop.total_clusters, 500u) << drop.note;
  EXPECT_EQ(drop.components_dropped, 3u);
  EXPECT_EQ(drop.small_components_kept, 0u);
  std::vector<int32_t> dropped = test::to_vector(initial_sampling(m.view, items, drop, 7, ram_storage()));
  for (uint32_t v = 0; v < m.view.vertex_count(); ++v) {
    uint32_t c = drop.component_of_vertex[v];
    if (drop.clusters_per_component[c] == 0) {
      EXPECT_EQ(dropped[v], -1) << "vertex of a dropped component labelled";
    } else {
      EXPECT_GE(dropped[v], 0);
    }
  }
}

TEST(ClusteringSampling, MoreClustersThanVerticesIsCappedWithANote) {
  Stored m(make_grid(5, 5));
  ItemData items = compute_item_data(m.view);
  ComponentBudget b = plan_component_budget(m.view, items, 40, SmallComponents::Keep, ram_storage());
  EXPECT_EQ(b.total_clusters, 25u);
  EXPECT_FALSE(b.note.empty());
  std::vector<int32_t> labels = test::to_vector(initial_sampling(m.view, items, b, 3, ram_storage()));
  std::vector<uint32_t> size = expect_valid_labels(m.view, labels, b.total_clusters);
  for (uint32_t s : size) EXPECT_EQ(s, 1u);
}

TEST(ClusteringSampling, IsolatedVerticesStayUnlabelled) {
  MeshBuffers soup = make_grid(10, 10);
  soup.positions.insert(soup.positions.end(), {5.0f, 5.0f, 5.0f, 6.0f, 6.0f, 6.0f});  // two unreferenced
  Stored m(soup);
  ItemData items = compute_item_data(m.view);
  ComponentBudget b = plan_component_budget(m.view, items, 12, SmallComponents::Keep, ram_storage());
  EXPECT_EQ(b.total_clusters, 12u);
  std::vector<int32_t> labels = test::to_vector(initial_sampling(m.view, items, b, 3, ram_storage()));
  expect_valid_labels(m.view, labels, b.total_clusters);  // checks the isolated ones are −1
  uint32_t unlabelled = uint32_t(std::count(labels.begin(), labels.end(), -1));
  EXPECT_EQ(unlabelled, 2u);
}

TEST(ClusteringSampling, SameSeedSameLabelsDifferentSeedDifferentLabels) {
  Stored m(make_icosphere(3));
  ItemData items = compute_item_data(m.view);
  ComponentBudget b = plan_component_budget(m.view, items, 64, SmallComponents::Keep, ram_storage());
  auto sample = [&](uint64_t seed) { return test::to_vector(initial_sampling(m.view, items, b, seed, ram_storage())); };
  EXPECT_EQ(sample(42), sample(42));
  EXPECT_NE(sample(42), sample(43));
}

// --- Algorithm 1, cleaning, constrained pass ----------------------------------------------------

struct ClusteredMesh {
  std::string name;
  MeshBuffers mesh;
  uint32_t clusters;
};

std::vector<ClusteredMesh> clustering_cases() {
  std::vector<ClusteredMesh> cases;
  cases.push_back({"icosphere4", make_icosphere(4), 150});
  cases.push_back({"torus", make_torus(60, 24), 120});
  cases.push_back({"grid", make_grid(40, 40), 90});
  cases.push_back({"fertility", read_mesh(test::data_path("fertility.off.zst")), 300});
  cases.push_back({"elephant-with-holes", read_mesh(test::data_path("cgal_elephant_with_holes.off")), 250});
  return cases;
}

TEST(ClusteringMinimize, EnergyNeverIncreasesWithinEachPass) {
  for (const ClusteredMesh& c : clustering_cases()) {
    for (uint64_t seed : {11ull, 29ull}) {
      SCOPED_TRACE(c.name + " seed " + std::to_string(seed));
      Stored m(c.mesh);
      ItemData items = compute_item_data(m.view);
      ComponentBudget b = plan_component_budget(m.view, items, c.clusters, SmallComponents::Keep, ram_storage());
      const uint32_t K = b.total_clusters;
      std::vector<int32_t> labels = test::to_vector(initial_sampling(m.view, items, b, seed, ram_storage()));
      const double initial = clustering_energy(items, accumulate_clusters(items, labels, K));

      ClusteringReport report = minimize_clustering(m.view, items, labels, K, test::metric_i_one_thread());
      const auto& e = report.energy_per_loop;
      ASSERT_EQ(e.size(), size_t(report.unconstrained_loops) + report.constrained_loops);
      ASSERT_GE(report.unconstrained_loops, 1u);
      ASSERT_GE(report.constrained_loops, 1u);
      EXPECT_EQ(report.moves_per_loop.size(), e.size());
      EXPECT_EQ(report.moves_per_loop.back(), 0u) << "constrained pass stops when no item moves";
      EXPECT_LE(e.front(), initial * (1 + 1e-12));
      EXPECT_LT(e[report.unconstrained_loops - 1], initial) << "the clustering did not lower the energy";
      expect_non_increasing(e, 0, report.unconstrained_loops, "unconstrained pass");
      expect_non_increasing(e, report.unconstrained_loops, e.size(), "constrained pass");
      // The incrementally updated energy agrees with a fresh recomputation.
      const double fresh = clustering_energy(items, accumulate_clusters(items, labels, K));
      EXPECT_NEAR(e.back(), fresh, 1e-9 * fresh);
      expect_valid_labels(m.view, labels, K);
    }
  }
}

TEST(ClusteringMinimize, PassByPassEnergyMonotoneWithAndWithoutSkip) {
  // The same passes driven one by one, with the §VI-A modified-clusters skip on and off.
  Stored m(make_icosphere(4));
  ItemData items = compute_item_data(m.view);
  ComponentBudget b = plan_component_budget(m.view, items, 200, SmallComponents::Keep, ram_storage());
  const uint32_t K = b.total_clusters;
  for (bool skip : {true, false}) {
    SCOPED_TRACE(skip ? "skip unchanged" : "test every edge");
    std::vector<int32_t> labels = test::to_vector(initial_sampling(m.view, items, b, 5, ram_storage()));
    ClusterState state = make_cluster_state(items, labels, K, Metric::I);
    ClusteringReport free_pass;
    LoopOptions pass;
    pass.threads = 1;
    pass.skip_unchanged = skip;
    uint32_t loops = run_clustering_loops(m.view, items, labels, state, pass, free_pass);
    EXPECT_EQ(loops, free_pass.energy_per_loop.size());
    EXPECT_EQ(free_pass.moves_per_loop.back(), 0u) << "stop_fraction 0 runs to a fixed point";
    expect_non_increasing(free_pass.energy_per_loop, 0, loops, "unconstrained pass");

    clean_clusters(m.view, items, labels, K, free_pass);
    EXPECT_TRUE(clusters_connected(m.view, labels, K));
    state = make_cluster_state(items, labels, K, Metric::I);
    ClusteringReport constrained;
    pass.constrained = true;
    loops = run_clustering_loops(m.view, items, labels, state, pass, constrained);
    expect_non_increasing(constrained.energy_per_loop, 0, loops, "constrained pass");
    EXPECT_TRUE(clusters_connected(m.view, labels, K));
    EXPECT_TRUE(every_cluster_connected_bfs(m.view, labels, K));
  }
}

TEST(ClusteringMinimize, EveryClusterConnectedAfterConstrainedPass) {
  for (const ClusteredMesh& c : clustering_cases()) {
    for (uint64_t seed : {3ull, 4ull, 5ull}) {
      SCOPED_TRACE(c.name + " seed " + std::to_string(seed));
      Stored m(c.mesh);
      ItemData items = compute_item_data(m.view);
      ComponentBudget b = plan_component_budget(m.view, items, c.clusters, SmallComponents::Keep, ram_storage());
      const uint32_t K = b.total_clusters;
      std::vector<int32_t> labels = test::to_vector(initial_sampling(m.view, items, b, seed, ram_storage()));
      minimize_clustering(m.view, items, labels, K, test::metric_i_one_thread());
      expect_valid_labels(m.view, labels, K);
      EXPECT_TRUE(clusters_connected(m.view, labels, K));
      EXPECT_TRUE(every_cluster_connected_bfs(m.view, labels, K));
    }
  }
}

TEST(ClusteringMinimize, InactiveClustersAreNotTested) {
  // With the §VI-A skip, clusters marked stable in `initially_active` are parked: if none is
  // active, an unconverged clustering is left as it is; if all are, it moves.
  Stored m(make_icosphere(3));
  ItemData items = compute_item_data(m.view);
  ComponentBudget b = plan_component_budget(m.view, items, 40, SmallComponents::Keep, ram_storage());
  const uint32_t K = b.total_clusters;
  const std::vector<int32_t> initial = test::to_vector(initial_sampling(m.view, items, b, 8, ram_storage()));
  std::vector<int32_t> labels = initial;
  ClusterState state = make_cluster_state(items, labels, K, Metric::I);
  ClusteringReport none;
  std::vector<uint8_t> inactive(K, 0);
  LoopOptions pass;
  pass.threads = 1;
  pass.max_loops = 100;
  run_clustering_loops(m.view, items, labels, state, pass, none, inactive);
  EXPECT_EQ(none.moves_per_loop.front(), 0u);
  EXPECT_EQ(labels, initial);
  ClusteringReport all;
  std::vector<uint8_t> active(K, 1);
  run_clustering_loops(m.view, items, labels, state, pass, all, active);
  EXPECT_GT(all.moves_per_loop.front(), 0u);
  EXPECT_NE(labels, initial);
}

TEST(ClusteringMinimize, ConvergedClusteringIsAFixedPoint) {
  // After minimize_clustering no single boundary move lowers the energy: another constrained
  // pass moves nothing.
  Stored m(make_torus(50, 20));
  ItemData items = compute_item_data(m.view);
  ComponentBudget b = plan_component_budget(m.view, items, 80, SmallComponents::Keep, ram_storage());
  std::vector<int32_t> labels = test::to_vector(initial_sampling(m.view, items, b, 9, ram_storage()));
  minimize_clustering(m.view, items, labels, b.total_clusters, test::metric_i_one_thread());
  std::vector<int32_t> before = labels;
  ClusterState state = make_cluster_state(items, labels, b.total_clusters, Metric::I);
  ClusteringReport again;
  LoopOptions pass;
  pass.threads = 1;
  pass.constrained = true;
  pass.max_loops = 10;
  pass.skip_unchanged = false;
  run_clustering_loops(m.view, items, labels, state, pass, again);
  ASSERT_FALSE(again.moves_per_loop.empty());
  EXPECT_EQ(again.moves_per_loop.front(), 0u);
  EXPECT_EQ(labels, before);
}

TEST(ClusteringMinimize, ClustersOnAFlatGridAreCompactAndBalanced) {
  // On a uniform grid the converged clusters have similar areas (CVD: near-equal cells).
  Stored m(make_grid(60, 60));
  ItemData items = compute_item_data(m.view);
  ComponentBudget b = plan_component_budget(m.view, items, 36, SmallComponents::Keep, ram_storage());
  std::vector<int32_t> labels = test::to_vector(initial_sampling(m.view, items, b, 1, ram_storage()));
  minimize_clustering(m.view, items, labels, b.total_clusters, test::metric_i_one_thread());
  std::vector<ClusterSums> sums = accumulate_clusters(items, labels, b.total_clusters);
  double lo = 1e300, hi = 0;
  for (const ClusterSums& s : sums) {
    lo = std::min(lo, s.weight);
    hi = std::max(hi, s.weight);
  }
  EXPECT_GT(lo, 0.4 / 36) << "a cluster is far smaller than the mean";
  EXPECT_LT(hi, 2.0 / 36) << "a cluster is far larger than the mean";
}

// --- cleaning and helpers -----------------------------------------------------------------------

TEST(ClusteringClean, KeepsHeaviestPieceAndReabsorbsTheRest) {
  // 10×10 grid, two clusters: 0 = left half, 1 = right half, plus a 2×2 island of label 0
  // inside the right half. Cleaning frees the island, which cluster 1 reabsorbs.
  MeshBuffers g = make_grid(10, 10);
  Stored m(g);
  const MeshView& v = m.view;
  std::vector<int32_t> labels(v.vertex_count());
  std::vector<uint32_t> island;
  for (uint32_t i = 0; i < v.vertex_count(); ++i) {
    float x = v.positions[3 * i], y = v.positions[3 * i + 1];
    int gx = int(std::lround(x * 9)), gy = int(std::lround(y * 9));
    labels[i] = gx < 5 ? 0 : 1;
    if ((gx == 7 || gx == 8) && (gy == 4 || gy == 5)) {
      labels[i] = 0;
      island.push_back(i);
    }
  }
  ASSERT_EQ(island.size(), 4u);
  EXPECT_FALSE(clusters_connected(v, labels, 2));
  EXPECT_FALSE(every_cluster_connected_bfs(v, labels, 2));
  ItemData items = compute_item_data(v);
  ClusteringReport report;
  uint64_t reset = clean_clusters(v, items, labels, 2, report);
  EXPECT_EQ(reset, 4u);
  EXPECT_EQ(report.cleaned_vertices, 4u);
  EXPECT_EQ(report.disconnected_clusters, 1u);
  for (uint32_t i : island) EXPECT_EQ(labels[i], 1);
  EXPECT_TRUE(clusters_connected(v, labels, 2));
}

TEST(ClusteringClean, AbsorbFreeVerticesLabelsEveryReachableVertex) {
  Stored m(make_grid(12, 12));
  const MeshView& v = m.view;
  std::vector<int32_t> labels(v.vertex_count(), -1);
  // Two seeds in opposite corners; everything else free.
  uint32_t a = 0, b = 0;
  for (uint32_t i = 0; i < v.vertex_count(); ++i) {
    if (v.positions[3 * i] == 0.0f && v.positions[3 * i + 1] == 0.0f) a = i;
    if (v.positions[3 * i] == 1.0f && v.positions[3 * i + 1] == 1.0f) b = i;
  }
  labels[a] = 0;
  labels[b] = 1;
  absorb_free_vertices(v, labels);
  for (int32_t l : labels) EXPECT_GE(l, 0);
  EXPECT_TRUE(clusters_connected(v, labels, 2));
  // The corner regions grow at the same speed: each vertex takes the nearer seed in graph distance
  // (vertices near (0,0) → 0, near (1,1) → 1).
  for (uint32_t i = 0; i < v.vertex_count(); ++i) {
    float x = v.positions[3 * i], y = v.positions[3 * i + 1];
    if (x + y < 0.6f) {
      EXPECT_EQ(labels[i], 0);
    }
    if (x + y > 1.4f) {
      EXPECT_EQ(labels[i], 1);
    }
  }
}

TEST(ClusteringHelpers, ClustersConnectedDetectsASplitCluster) {
  Stored m(make_grid(6, 3));
  const MeshView& v = m.view;
  // Label 0 on columns 0 and 5, label 1 between them: cluster 0 has two pieces.
  std::vector<int32_t> labels(v.vertex_count());
  for (uint32_t i = 0; i < v.vertex_count(); ++i) {
    int gx = int(std::lround(v.positions[3 * i] * 5));
    labels[i] = (gx == 0 || gx == 5) ? 0 : 1;
  }
  EXPECT_FALSE(clusters_connected(v, labels, 2));
  for (uint32_t i = 0; i < v.vertex_count(); ++i)
    if (std::lround(v.positions[3 * i] * 5) == 5) labels[i] = 2;
  EXPECT_TRUE(clusters_connected(v, labels, 3));
}

TEST(ClusteringHelpers, EnergyIsZeroForOneVertexPerClusterAndMatchesDefinition) {
  Stored m(make_icosphere(2));
  ItemData items = compute_item_data(m.view);
  const uint32_t V = m.view.vertex_count();
  std::vector<int32_t> singletons(V);
  std::iota(singletons.begin(), singletons.end(), 0);
  EXPECT_NEAR(clustering_energy(items, accumulate_clusters(items, singletons, V)), 0.0, 1e-12);
  // Two clusters (z ≥ 0 and z < 0): energy = Σ_j M_j ‖γ_j − c_i‖² computed directly.
  std::vector<int32_t> halves(V);
  for (uint32_t v = 0; v < V; ++v) halves[v] = m.view.positions[3 * v + 2] >= 0 ? 0 : 1;
  std::vector<ClusterSums> sums = accumulate_clusters(items, halves, 2);
  double direct = 0;
  for (uint32_t v = 0; v < V; ++v) {
    const ClusterSums& s = sums[halves[v]];
    for (int k = 0; k < 3; ++k) {
      double d = items.centroid[3 * v + k] - s.sum[k] / s.weight;
      direct += items.weight[v] * d * d;
    }
  }
  EXPECT_NEAR(clustering_energy(items, sums), direct, 1e-9 * direct);
  EXPECT_GT(direct, 0.0);
}

}  // namespace
}  // namespace streamcvd
