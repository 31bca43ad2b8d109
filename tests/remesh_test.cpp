// End-to-end tests of the remesher (core/remesh.h, streaming/remesh_pipeline.h) on closed inputs:
// closed manifold output with the input genus and exactly N vertices, for every metric;
// coarse budgets; determinism; small components. Sampling independence (paper Fig. 5) is in
// remesh_sampling_test.cpp, open and dirty inputs in remesh_open_test.cpp.
#include "streamcvd/core/remesh.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "streamcvd/core/dual/dual_mesh.h"
#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/remesh_pipeline.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/cli_runner.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

// --- closed inputs: manifold, oriented, same genus, exactly N vertices ---------------------------

struct ClosedCase {
  std::string name;
  MeshBuffers mesh;
  int64_t genus;
  std::vector<uint32_t> budgets;
  int subdivide = -1;                 // PipelineOptions::subdivide
  std::vector<uint64_t> seeds = {20080401};
  Metric metric = Metric::I;
};

void check_closed_remesh(const ClosedCase& c) {
  MeshStore store = MeshStore::build(c.mesh.view());
  TopologyStats input = compute_topology_stats(c.mesh.view());
  ASSERT_TRUE(input.closed_manifold) << c.name;
  ASSERT_EQ(input.genus, c.genus) << c.name << ": test input has an unexpected genus";
  for (uint32_t n : c.budgets)
    for (uint64_t seed : c.seeds) {
      SCOPED_TRACE(c.name + " N=" + std::to_string(n) + " seed " + std::to_string(seed));
      PipelineOptions o;
      o.remesh.clustering = test::metric_i_one_thread();
      o.remesh.vertices = n;
      o.remesh.seed = seed;
      o.remesh.clustering.metric = c.metric;
      o.subdivide = c.subdivide;
      PipelineResult r = remesh_store(store, o);
      const TopologyStats t = compute_topology_stats(r.remesh.mesh.view());
      std::printf("[ closed   ] %-9s V=%-6u N=%-5u seed=%-9llu subdiv=%d -> V=%u F=%llu genus=%lld defects=%llu repaired=%llu\n",
                  c.name.c_str(), c.mesh.vertex_count(), n, (unsigned long long)seed, r.subdivision_levels,
                  r.remesh.mesh.vertex_count(), (unsigned long long)t.faces, (long long)t.genus,
                  (unsigned long long)r.remesh.placement.defect_vertices, (unsigned long long)r.remesh.repair.repaired_clusters);
      EXPECT_EQ(r.remesh.placement.defect_vertices, 0u);
      EXPECT_EQ(r.remesh.placement.defects_removed.faces_removed, 0u);
      EXPECT_TRUE(t.closed_manifold);
      EXPECT_TRUE(t.consistently_oriented);
      EXPECT_EQ(t.duplicate_faces, 0u);
      EXPECT_EQ(t.degenerate_faces, 0u);
      EXPECT_EQ(t.isolated_vertices, 0u);
      EXPECT_EQ(t.nonmanifold_edges, 0u);
      EXPECT_EQ(t.nonmanifold_vertices, 0u);
      EXPECT_EQ(t.components, 1u);
      EXPECT_EQ(t.genus, c.genus);
      EXPECT_EQ(t.faces, 2 * uint64_t(n) + 4 * uint64_t(c.genus) - 4);  // closed: F = 2V − 2χ
      // Exactly N output vertices, one per cluster.
      EXPECT_EQ(r.remesh.clusters, n);
      EXPECT_EQ(r.remesh.mesh.vertex_count(), n);
      EXPECT_EQ(r.remesh.dual.boundary_vertices_added, 0u);
      EXPECT_TRUE(r.remesh.checks.clusters_connected);
      // The pipeline's own summary agrees.
      EXPECT_TRUE(r.output_topology.closed_manifold);
      EXPECT_EQ(r.output_topology.genus, c.genus);
    }
}

const std::vector<uint32_t> kBudgets = {200, 500, 1000, 2000};

TEST(RemeshClosed, SphereKeepsGenusZeroAndExactCount) {
  check_closed_remesh({"sphere", make_icosphere(5), 0, kBudgets, -1, {20080401, 2}});
}

TEST(RemeshClosed, TorusKeepsGenusOneAndExactCount) {
  check_closed_remesh({"torus", make_torus(160, 64), 1, kBudgets, -1, {20080401, 2}});
}

TEST(RemeshClosed, EveryMetricKeepsTheGuarantees) {
  // IQ, A and AQ move the sites (QEM points, anisotropic centroids) and reshape the clusters:
  // the output guarantees must hold for each of them as for I.
  const MeshBuffers fertility = read_mesh(test::data_path("fertility.off.zst"));
  for (Metric m : {Metric::IQ, Metric::A, Metric::AQ}) {
    SCOPED_TRACE(metric_name(m));
    check_closed_remesh({"sphere", make_icosphere(4), 0, {300, 1000}, -1, {20080401}, m});
    check_closed_remesh({"torus", make_torus(160, 64), 1, {500, 2000}, -1, {20080401}, m});
    check_closed_remesh({"fertility", fertility, 4, {1000, 2000}, -1, {20080401}, m});
  }
}

TEST(RemeshClosed, FertilityKeepsGenusFourAndExactCount) {
  // Auto subdivision (N = 500 and up subdivide the 4,494 V input) and, without subdivision,
  // N up to half the input vertex count.
  const MeshBuffers fertility = read_mesh(test::data_path("fertility.off.zst"));
  check_closed_remesh({"fertility", fertility, 4, kBudgets, -1, {20080401, 2}});
  check_closed_remesh({"fertility", fertility, 4, kBudgets, 0, {1, 2, 3}});
}

TEST(RemeshClosed, ElephantKeepsGenusThreeAndExactCount) {
  const MeshBuffers elephant = read_mesh(test::data_path("cgal_elephant.off"));
  check_closed_remesh({"elephant", elephant, 3, {400, 500, 1000, 2000}, -1, {20080401, 2}});
  // Without subdivision, 5.5 input vertices per cluster at N = 500 is below the ~10 that auto
  // subdivision guarantees, and some seeds lose a handle there: test from N = 1000 up.
  check_closed_remesh({"elephant", elephant, 3, {1000, 1380}, 0, {1, 2, 3}});
}

TEST(RemeshClosed, ElephantAtN200ReportsEveryGenusChange) {
  // Known limitation: at N = 200 the elephant's thin handles are narrower than a cluster, and
  // for some seeds the output loses a handle or the last-resort cleanup opens holes. At N = 400
  // every seed keeps genus 3 (test above). What must hold at any N: the output is a valid
  // manifold, and a topology change is reported (topology_changed), never silent.
  const MeshBuffers elephant = read_mesh(test::data_path("cgal_elephant.off"));
  MeshStore store = MeshStore::build(elephant.view());
  for (uint64_t seed : {1, 2, 3, 4, 5, 6}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    PipelineOptions o;
    o.remesh.clustering = test::metric_i_one_thread();
    o.remesh.vertices = 200;
    o.remesh.seed = seed;
    PipelineResult r = remesh_store(store, o);
    const TopologyStats& t = r.output_topology;
    EXPECT_EQ(t.nonmanifold_edges + t.nonmanifold_vertices + t.duplicate_faces + t.isolated_vertices, 0u);
    EXPECT_TRUE(t.consistently_oriented);
    const bool kept = t.closed_manifold && t.genus == 3 && r.remesh.placement.defects_removed.faces_removed == 0;
    EXPECT_EQ(r.remesh.checks.topology_changed, !kept);
    EXPECT_EQ(r.remesh.checks.output_euler_characteristic, t.euler_characteristic);
  }
}

TEST(RemeshClosed, HandAndFandisk) {
  check_closed_remesh({"hand", read_mesh(test::data_path("cgal_hand.off")), 0, {300, 590}, 0, {1, 2}});
  check_closed_remesh({"fandisk", read_mesh(test::data_path("cgal_fandisk.off.zst")), 0, {500, 3000}, 0, {1, 2}});
}

TEST(RemeshClosed, OutputVerticesProjectedOntoTheSurface) {
  // Sphere of radius 1 (icosphere level 4: its triangles lie at most ~1e-3 inside the sphere).
  // Projected representatives sit on the input surface; raw centroids of curved clusters sit
  // inside it (by about r²/2 for a cluster of radius r ≈ 0.14 at N = 200).
  MeshBuffers sphere = make_icosphere(4);
  MeshStore store = MeshStore::build(sphere.view());
  auto radii = [&](bool project) {
    RemeshOptions o;
    o.clustering = test::metric_i_one_thread();
    o.vertices = 200;
    o.project_to_surface = project;
    RemeshResult r = remesh(store.view(), o);
    EXPECT_EQ(r.mesh.vertex_count(), 200u);
    std::vector<double> rad;
    for (uint32_t v = 0; v < r.mesh.vertex_count(); ++v) {
      const float* p = &r.mesh.positions[3 * size_t(v)];
      rad.push_back(std::sqrt(double(p[0]) * p[0] + double(p[1]) * p[1] + double(p[2]) * p[2]));
    }
    return rad;
  };
  const std::vector<double> projected = radii(true), raw = radii(false);
  for (double r : projected) {
    EXPECT_GT(r, 0.997);
    EXPECT_LT(r, 1.0 + 1e-5);
  }
  EXPECT_LT(*std::max_element(raw.begin(), raw.end()), 0.998);
  std::printf("[ project  ] sphere N=200: radius min %.5f (projected) vs max %.5f (raw centroids)\n",
              *std::min_element(projected.begin(), projected.end()), *std::max_element(raw.begin(), raw.end()));
}

TEST(RemeshClosed, CoarseBudgetsGiveAValidManifoldOrAClearError) {
  // Budgets so coarse that clusters are wider than the tube of a torus or the handles of
  // fertility: the genus is lost, but the output never carries a defect (non-manifold edge or
  // vertex, duplicate face, isolated vertex) and is consistently oriented. At N = 12 on the
  // torus (R = 1, r = 0.35) every cluster wraps the tube and the repair cannot give a valid
  // surface: remesh says so (InputError naming N) instead of returning an empty mesh. The
  // outcome of each case is that of metric I on one thread (reproducible), as measured.
  const MeshBuffers fertility = read_mesh(test::data_path("fertility.off.zst"));
  struct Case {
    std::string name;
    MeshBuffers mesh;
    uint32_t n;
    bool no_surface;  // InputError expected
  };
  std::vector<Case> cases;
  cases.push_back({"torus N=20", make_torus(80, 32), 20, false});
  cases.push_back({"torus N=12", make_torus(80, 32), 12, true});
  cases.push_back({"fertility N=50", fertility, 50, false});
  cases.push_back({"fertility N=100", fertility, 100, false});
  cases.push_back({"elephant N=100", read_mesh(test::data_path("cgal_elephant.off")), 100, false});
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    MeshStore store = MeshStore::build(c.mesh.view());
    RemeshOptions o;
    o.clustering = test::metric_i_one_thread();
    o.vertices = c.n;
    if (c.no_surface) {
      try {
        remesh(store.view(), o);
        ADD_FAILURE() << "a surface was built: expected the InputError of a budget too coarse";
      } catch (const InputError& e) {
        std::printf("[ coarse   ] %-16s -> InputError: %s\n", c.name.c_str(), e.what());
        EXPECT_NE(std::string(e.what()).find("N=" + std::to_string(c.n)), std::string::npos) << e.what();
      }
      continue;
    }
    const RemeshResult r = remesh(store.view(), o);
    TopologyStats t = compute_topology_stats(r.mesh.view());
    std::printf("[ coarse   ] %-16s -> V=%u F=%llu components=%llu loops=%llu faces removed=%llu\n", c.name.c_str(),
                r.mesh.vertex_count(), (unsigned long long)t.faces, (unsigned long long)t.components,
                (unsigned long long)t.boundary_loops, (unsigned long long)r.placement.defects_removed.faces_removed);
    EXPECT_GT(r.mesh.face_count(), 0u);
    EXPECT_EQ(r.placement.defect_vertices, 0u);
    EXPECT_TRUE(find_manifold_defects(r.mesh.view()).empty());
    EXPECT_EQ(t.nonmanifold_edges + t.nonmanifold_vertices + t.duplicate_faces + t.isolated_vertices, 0u);
    EXPECT_TRUE(t.consistently_oriented);
    EXPECT_EQ(r.mesh.vertex_count(), r.clusters - r.placement.defects_removed.vertices_removed);
  }
}

// --- the plan and the defaults -------------------------------------------------------------------

TEST(RemeshPlan, TheMetricDecidesWhatEachStageDoes) {
  RemeshOptions o;
  for (Metric m : {Metric::I, Metric::IQ, Metric::A, Metric::AQ}) {
    SCOPED_TRACE(metric_name(m));
    o.clustering.metric = m;
    const RemeshPlan plan = plan_remesh(o);
    EXPECT_EQ(plan.tensors, m == Metric::A || m == Metric::AQ);
    EXPECT_EQ(plan.curvature, plan.tensors);  // no gradation asked
    EXPECT_EQ(plan.quadrics, m == Metric::IQ || m == Metric::AQ);
    EXPECT_FALSE(plan.lloyd);
    // QEM points: only nearly flat rings move, keeping their height above the surface.
    EXPECT_EQ(plan.optimize_options.keep_surface_offset, plan.quadrics);
    EXPECT_EQ(plan.optimize_options.feature_angle_deg,
              plan.quadrics ? o.optimize.qem_feature_angle_deg : o.optimize.feature_angle_deg);
  }
  o.clustering.metric = Metric::I;
  o.gradation = 1;
  o.project_to_surface = false;
  const RemeshPlan graded = plan_remesh(o);
  EXPECT_TRUE(graded.curvature && graded.gradation);
  EXPECT_EQ(graded.optimize_options.relax_iterations, 0u) << "raw centroids asked for: flips only";
  o.clustering.algorithm = ClusteringOptions::Algorithm::Lloyd;
  EXPECT_TRUE(plan_remesh(o).lloyd);
  o.clustering.metric = Metric::AQ;
  EXPECT_THROW(plan_remesh(o), std::invalid_argument) << "Lloyd implements I and IQ only";
}

TEST(RemeshDefaults, TheCliRunsTheLibraryDefaults) {
  // One default for the library and the CLI: `streamcvd remesh` without options runs
  // RemeshOptions{} (metric IQ, the clustering on all cores), as its report says.
  const RemeshOptions d;
  EXPECT_EQ(d.clustering.metric, Metric::IQ);
  EXPECT_EQ(d.clustering.loops.threads, 0u);
  ASSERT_TRUE(test::cli_available()) << "STREAMCVD_CLI not built";
  const std::filesystem::path dir = test::temp_dir("remesh_defaults");
  const std::string input = (dir / "sphere.ply").string(), report = (dir / "report.json").string();
  write_mesh(input, make_icosphere(3).view());
  const test::CliResult r =
      test::run_cli({"remesh", input, "-o", (dir / "out.ply").string(), "-n", "100", "-q", "--report", report});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const nlohmann::json j = nlohmann::json::parse(test::slurp(report));
  const nlohmann::json& o = j["options"];
  EXPECT_EQ(o["metric"], metric_name(d.clustering.metric));
  EXPECT_EQ(o["algorithm"], algorithm_name(d.clustering.algorithm));
  EXPECT_EQ(o["threads"], d.clustering.loops.threads);
  EXPECT_EQ(o["deterministic"], d.clustering.loops.deterministic);
  EXPECT_EQ(o["seed"], d.seed);
  EXPECT_EQ(o["gradation"], d.gradation);
  EXPECT_EQ(o["curvature_rings"], d.curvature_rings);
  EXPECT_EQ(o["qem_threshold"], d.clustering.qem_threshold);
  EXPECT_EQ(o["small_components"], small_components_name(d.small_components));
  EXPECT_EQ(o["boundary_strips"], d.boundary_strips);
  EXPECT_EQ(j["quality_pass"]["enabled"], d.optimize_quality);
  std::filesystem::remove_all(dir);
}

// --- determinism -------------------------------------------------------------------------------------

TEST(RemeshDeterminism, SameSeedSameBytesDifferentSeedDifferentBytes) {
  const MeshBuffers elephant = read_mesh(test::data_path("cgal_elephant.off"));
  const auto dir = test::temp_dir("remesh_determinism");
  auto run = [&](uint64_t seed, const std::string& file) {
    MeshStore store = MeshStore::build(elephant.view());  // a fresh store each run
    RemeshOptions o;
    o.clustering = test::metric_i_one_thread();
    o.vertices = 300;
    o.seed = seed;
    RemeshResult r = remesh(store.view(), o);
    write_mesh((dir / file).string(), r.mesh.view());
    return test::slurp((dir / file).string());
  };
  const std::string a = run(7, "a.ply"), b = run(7, "b.ply"), c = run(8, "c.ply");
  ASSERT_GT(a.size(), 300u * 12);
  EXPECT_TRUE(a == b) << "same seed, different output bytes";
  EXPECT_FALSE(a == c) << "different seed, same output";
  {
    // The result does not depend on the number of threads.
    tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
    const std::string d = run(7, "d.ply");
    EXPECT_TRUE(a == d) << "single-threaded run differs";
  }
  std::filesystem::remove_all(dir);
}

// --- small components ----------------------------------------------------------------------------------

TEST(RemeshComponents, SmallComponentsKeptOrDropped) {
  MeshBuffers soup = make_icosphere(4);  // the large component
  MeshBuffers tri;
  tri.positions = {0, 0, 0, 0.02f, 0, 0, 0, 0.02f, 0};
  tri.triangles = {0, 1, 2};
  MeshBuffers tet;
  tet.positions = {0, 0, 0, 0.02f, 0, 0, 0, 0.02f, 0, 0, 0, 0.02f};
  tet.triangles = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  test::append_shifted(soup, tri, 3, 0, 0);
  test::append_shifted(soup, tri, 3, 1, 0);
  test::append_shifted(soup, tri, 3, 2, 0);
  test::append_shifted(soup, tet, -3, 0, 0);
  test::append_shifted(soup, tet, -3, 1, 0);
  test::append_shifted(soup, make_icosphere(1, 0.05f), 0, 3, 0);  // 42 V: too small for its share, > 16 V
  const uint64_t small = 6;
  MeshStore store = MeshStore::build(soup.view());
  ASSERT_EQ(compute_topology_stats(soup.view()).components, 1 + small);

  RemeshOptions o;

  o.clustering = test::metric_i_one_thread();
  o.vertices = 300;
  o.small_components = SmallComponents::Keep;
  RemeshResult keep = remesh(store.view(), o);
  TopologyStats kt = compute_topology_stats(keep.mesh.view());
  EXPECT_EQ(keep.budget.small_components_kept, small);
  EXPECT_EQ(keep.budget.components_dropped, 0u);
  EXPECT_EQ(kt.components, 1 + small) << "a kept component is missing from the output";
  EXPECT_EQ(keep.clusters, 300u) << keep.budget.note;
  EXPECT_EQ(keep.mesh.vertex_count(), 300u);
  EXPECT_EQ(keep.placement.defect_vertices, 0u);
  EXPECT_EQ(kt.nonmanifold_edges + kt.nonmanifold_vertices + kt.duplicate_faces + kt.isolated_vertices, 0u);
  EXPECT_TRUE(kt.consistently_oriented);
  // Faces: sphere (closed, F = 2V − 4) + 3 triangles + 2 tetrahedra (4 each) + a tetrahedron for
  // the small sphere (4 clusters) → boundary only from the three triangles.
  EXPECT_EQ(kt.boundary_loops, 3u);

  o.small_components = SmallComponents::Drop;
  RemeshResult drop = remesh(store.view(), o);
  TopologyStats dt = compute_topology_stats(drop.mesh.view());
  EXPECT_EQ(drop.budget.components_dropped, small);
  EXPECT_EQ(drop.budget.small_components_kept, 0u);
  EXPECT_EQ(dt.components, 1u);
  EXPECT_EQ(drop.clusters, 300u);
  EXPECT_EQ(drop.mesh.vertex_count(), 300u);
  EXPECT_TRUE(dt.closed_manifold);
  EXPECT_EQ(dt.genus, 0);
  for (uint32_t v = 0; v < store.view().vertex_count(); ++v)
    if (drop.budget.clusters_per_component[drop.budget.component_of_vertex[v]] == 0) {
      EXPECT_EQ(drop.cluster_of_vertex[v], -1);
    }
}

}  // namespace
}  // namespace streamcvd
