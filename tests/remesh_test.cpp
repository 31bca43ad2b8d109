// End-to-end tests of the isotropic remesher (core/remesh.h, streaming/remesh_pipeline.h):
// closed manifold output with the input genus and exactly N vertices, sampling independence
// (paper Fig. 5), determinism, small components, and robustness on open and dirty inputs.
#include "streamcvd/core/remesh.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numeric>
#include <string>
#include <vector>

#include "streamcvd/core/dual/dual_mesh.h"
#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/clustering/item_data.h"
#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/remesh_pipeline.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

void append(MeshBuffers& a, const MeshBuffers& b, float dx, float dy, float dz) {
  const uint32_t offset = a.vertex_count();
  for (size_t i = 0; i < b.positions.size(); i += 3)
    a.positions.insert(a.positions.end(), {b.positions[i] + dx, b.positions[i + 1] + dy, b.positions[i + 2] + dz});
  for (uint32_t i : b.triangles) a.triangles.push_back(i + offset);
}

std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
}

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

TEST(RemeshClosed, CoarseBudgetsStillGiveAValidManifold) {
  // Budgets so coarse that clusters are wider than the tube of a torus or the handles of
  // fertility: the genus is lost, but the output never carries a defect (non-manifold edge or
  // vertex, duplicate face, isolated vertex) and is consistently oriented.
  const MeshBuffers fertility = read_mesh(test::data_path("fertility.off.zst"));
  struct Case {
    std::string name;
    MeshBuffers mesh;
    uint32_t n;
  };
  std::vector<Case> cases;
  cases.push_back({"torus N=20", make_torus(80, 32), 20});
  cases.push_back({"torus N=12", make_torus(80, 32), 12});
  cases.push_back({"fertility N=50", fertility, 50});
  cases.push_back({"fertility N=100", fertility, 100});
  cases.push_back({"elephant N=100", read_mesh(test::data_path("cgal_elephant.off")), 100});
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    MeshStore store = MeshStore::build(c.mesh.view());
    RemeshOptions o;
    o.clustering = test::metric_i_one_thread();
    o.vertices = c.n;
    RemeshResult r;
    try {
      r = remesh(store.view(), o);
    } catch (const InputError& e) {  // no valid surface at this N: a clear error is acceptable
      std::printf("[ coarse   ] %-16s -> InputError: %s\n", c.name.c_str(), e.what());
      continue;
    }
    TopologyStats t = compute_topology_stats(r.mesh.view());
    std::printf("[ coarse   ] %-16s -> V=%u F=%llu components=%llu loops=%llu faces removed=%llu\n", c.name.c_str(),
                r.mesh.vertex_count(), (unsigned long long)t.faces, (unsigned long long)t.components,
                (unsigned long long)t.boundary_loops, (unsigned long long)r.placement.defects_removed.faces_removed);
    EXPECT_EQ(r.placement.defect_vertices, 0u);
    EXPECT_TRUE(find_manifold_defects(r.mesh.view()).empty());
    EXPECT_EQ(t.nonmanifold_edges + t.nonmanifold_vertices + t.duplicate_faces + t.isolated_vertices, 0u);
    EXPECT_TRUE(t.consistently_oriented);
    EXPECT_EQ(r.mesh.vertex_count(), r.clusters - r.placement.defects_removed.vertices_removed);
  }
}

TEST(RemeshClosed, CoarseBudgetsGiveASurfaceOrAClearError) {
  // On a torus (R = 1, r = 0.35) at N = 12 or 20 every cluster wraps the tube; if the repair
  // cannot give a valid surface, remesh says so (InputError naming N) instead of an empty mesh.
  for (uint32_t n : {12u, 20u}) {
    SCOPED_TRACE("N=" + std::to_string(n));
    MeshBuffers torus = make_torus(80, 32);
    MeshStore store = MeshStore::build(torus.view());
    RemeshOptions o;
    o.clustering = test::metric_i_one_thread();
    o.vertices = n;
    try {
      RemeshResult r = remesh(store.view(), o);
      EXPECT_GT(r.mesh.face_count(), 0u);
      EXPECT_TRUE(find_manifold_defects(r.mesh.view()).empty());
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("N=" + std::to_string(n)), std::string::npos) << e.what();
    }
  }
}

// --- sampling independence (paper Fig. 5) ----------------------------------------------------------

// A flat 4×1 plane made of four unit squares side by side; square k is a regular grid of m_k ×
// m_k cells with m_k ≈ m0·√2^k, so its vertex density is 1, 2, 4, 8× that of the first. Squares
// are stitched by a zipper of triangles between the last column of one and the first column of
// the next (conforming, consistently oriented, +z normals).
struct StripPlane {
  MeshBuffers mesh;
  std::vector<uint8_t> region;  // per input vertex
};

StripPlane make_strip_plane(int m0) {
  StripPlane p;
  std::vector<std::vector<std::vector<uint32_t>>> columns(4);  // columns[k][i][j] = vertex id
  for (int k = 0; k < 4; ++k) {
    const int m = int(std::lround(m0 * std::pow(std::sqrt(2.0), k)));
    const int ncols = k == 3 ? m + 1 : m;  // the next square provides the shared border column
    for (int i = 0; i < ncols; ++i) {
      std::vector<uint32_t> col;
      for (int j = 0; j <= m; ++j) {
        col.push_back(p.mesh.vertex_count());
        p.mesh.positions.insert(p.mesh.positions.end(), {float(k) + float(i) / float(m), float(j) / float(m), 0.0f});
        p.region.push_back(uint8_t(k));
      }
      columns[k].push_back(std::move(col));
    }
  }
  auto& T = p.mesh.triangles;
  // Quad strip between two columns of equal length.
  auto grid_strip = [&](const std::vector<uint32_t>& L, const std::vector<uint32_t>& R) {
    for (size_t j = 0; j + 1 < L.size(); ++j) T.insert(T.end(), {L[j], R[j], R[j + 1], L[j], R[j + 1], L[j + 1]});
  };
  // Zipper between two columns of different lengths spanning the same y range.
  auto zipper = [&](const std::vector<uint32_t>& L, const std::vector<uint32_t>& R) {
    auto y = [&](uint32_t v) { return p.mesh.positions[3 * size_t(v) + 1]; };
    size_t i = 0, j = 0;
    while (i + 1 < L.size() || j + 1 < R.size()) {
      bool advance_left = j + 1 == R.size() || (i + 1 < L.size() && y(L[i + 1]) <= y(R[j + 1]));
      if (advance_left) {
        T.insert(T.end(), {L[i], R[j], L[i + 1]});
        ++i;
      } else {
        T.insert(T.end(), {L[i], R[j], R[j + 1]});
        ++j;
      }
    }
  };
  for (int k = 0; k < 4; ++k) {
    for (size_t i = 0; i + 1 < columns[k].size(); ++i) grid_strip(columns[k][i], columns[k][i + 1]);
    if (k < 3) zipper(columns[k].back(), columns[k + 1].front());
  }
  return p;
}

// Per region of the strip plane: clusters lying entirely inside it (no vertex on the plane's
// border or next to another region) and their areas, plus the clusters whose centroid lies in it.
struct RegionFigures {
  uint32_t vertices = 0;
  std::vector<double> interior_areas;
  uint32_t clusters_by_centroid = 0;
};

struct SamplingRun {
  std::vector<RegionFigures> regions = std::vector<RegionFigures>(4);
  double mean_area = 0;  // A / clusters
  uint32_t clusters = 0;  // non-empty clusters: N minus the boundary-strip vertices
  TopologyStats output;
  uint64_t defect_vertices = 0;
};

SamplingRun run_strip_plane(int m0, uint32_t n, uint64_t seed) {
  StripPlane plane = make_strip_plane(m0);
  SamplingRun run;
  MeshStore store = MeshStore::build(plane.mesh.view());
  MeshView view = store.view();
  std::vector<uint8_t> region(view.vertex_count());
  for (uint32_t v = 0; v < view.vertex_count(); ++v) region[v] = plane.region[store.original_vertex_ids()[v]];
  for (uint8_t r : region) ++run.regions[r].vertices;

  RemeshOptions o;

  o.clustering = test::metric_i_one_thread();
  o.vertices = n;
  o.seed = seed;
  RemeshResult r = remesh(view, o);
  run.clusters = uint32_t(r.mesh.vertex_count() - r.dual.boundary_vertices_added);
  run.output = compute_topology_stats(r.mesh.view());
  run.defect_vertices = r.placement.defect_vertices;
  ItemData items = compute_item_data(view);
  std::vector<double> area(r.clusters, 0.0), moment_x(r.clusters, 0.0);
  std::vector<int> region_of_cluster(r.clusters, -1);  // −1 unset, −2 touches a border
  for (uint32_t v = 0; v < view.vertex_count(); ++v) {
    const int32_t c = r.cluster_of_vertex[v];
    if (c < 0) continue;
    area[c] += items.weight[v];
    moment_x[c] += items.weight[v] * view.positions[3 * v];
    bool border = (view.vertex_flags[v] & kVertexBoundary) != 0;
    for (uint32_t nb : view.neighbours(v)) border |= region[nb] != region[v];
    if (border || (region_of_cluster[c] != -1 && region_of_cluster[c] != region[v])) region_of_cluster[c] = -2;
    else if (region_of_cluster[c] == -1) region_of_cluster[c] = region[v];
  }
  for (uint32_t c = 0; c < r.clusters; ++c) {
    if (region_of_cluster[c] >= 0) run.regions[region_of_cluster[c]].interior_areas.push_back(area[c]);
    if (area[c] > 0) ++run.regions[std::clamp(int(moment_x[c] / area[c]), 0, 3)].clusters_by_centroid;
  }
  run.mean_area = items.total_weight / run.clusters;
  return run;
}

double mean_of(const std::vector<double>& x) { return std::accumulate(x.begin(), x.end(), 0.0) / double(x.size()); }

double cv_of(const std::vector<double>& x) {
  const double m = mean_of(x);
  double s2 = 0;
  for (double a : x) s2 += (a - m) * (a - m);
  return std::sqrt(s2 / double(x.size())) / m;
}

TEST(RemeshSampling, PlaneMadeOfFourDensitiesIsAConformingDisc) {
  StripPlane plane = make_strip_plane(12);
  TopologyStats t = compute_topology_stats(plane.mesh.view());
  EXPECT_EQ(t.boundary_loops, 1u);
  EXPECT_EQ(t.euler_characteristic, 1);
  EXPECT_TRUE(t.consistently_oriented);
  EXPECT_EQ(t.degenerate_faces + t.duplicate_faces + t.nonmanifold_edges + t.nonmanifold_vertices, 0u);
  double area = 0;
  for (size_t f = 0; f < plane.mesh.face_count(); ++f) {
    const float* a = &plane.mesh.positions[3 * size_t(plane.mesh.triangles[3 * f])];
    const float* b = &plane.mesh.positions[3 * size_t(plane.mesh.triangles[3 * f + 1])];
    const float* c = &plane.mesh.positions[3 * size_t(plane.mesh.triangles[3 * f + 2])];
    double z = 0.5 * ((double(b[0]) - a[0]) * (double(c[1]) - a[1]) - (double(b[1]) - a[1]) * (double(c[0]) - a[0]));
    EXPECT_GT(z, 0.0) << "face " << f;
    area += z;
  }
  EXPECT_NEAR(area, 4.0, 1e-5);
}

TEST(RemeshSampling, ClusterAreasUniformWithinEachDensityRegion) {
  // Paper Fig. 5: four regions of 1×, 2×, 4×, 8× vertex density; inside each region the
  // clusters have nearly equal areas (coefficient of variation < 0.15).
  const SamplingRun run = run_strip_plane(48, 400, 20080401);
  ASSERT_EQ(run.output.vertices, 400u) << "exactly N output vertices, strip vertices included";
  ASSERT_GT(run.clusters, 300u);
  for (int k = 0; k < 4; ++k) {
    const RegionFigures& g = run.regions[k];
    ASSERT_GE(g.interior_areas.size(), 20u) << "region " << k << " has too few interior clusters to measure";
    const double cv = cv_of(g.interior_areas);
    std::printf("[ sampling ] region %d: %u vertices (density %.2fx), %zu interior clusters, CV of areas %.4f\n", k,
                g.vertices, double(g.vertices) / run.regions[0].vertices, g.interior_areas.size(), cv);
    EXPECT_LT(cv, 0.15) << "region " << k;
  }
  EXPECT_EQ(run.defect_vertices, 0u);
  EXPECT_EQ(run.output.boundary_loops, 1u);
  EXPECT_EQ(run.output.euler_characteristic, 1);
  EXPECT_TRUE(run.output.consistently_oriented);
  EXPECT_EQ(run.output.nonmanifold_edges + run.output.nonmanifold_vertices, 0u);
}

TEST(RemeshSampling, ClusterCountFollowsAreaNotVertexDensity) {
  // Sampling independence across regions: each unit square holds about a quarter of the
  // clusters (N less the strip vertices) and the clusters of every region have about the mean
  // area, whatever its vertex density.
  // Known failure (see report): the initial sampling picks seeds uniformly over *vertices*, so
  // dense regions get more seeds, and the local minimisation does not move clusters across
  // regions afterwards (measured 77-88 clusters in the 1× square, 110-112 in the 8× one).
  for (uint64_t seed : {1ull, 2ull}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const SamplingRun run = run_strip_plane(48, 400, seed);
    for (int k = 0; k < 4; ++k) {
      const RegionFigures& g = run.regions[k];
      const double ratio = mean_of(g.interior_areas) / run.mean_area;
      const double ideal = run.clusters / 4.0;
      std::printf("[ sampling ] seed %llu region %d: %u clusters by centroid (ideal %.0f), interior mean area %.3f of the mean\n",
                  (unsigned long long)seed, k, g.clusters_by_centroid, ideal, ratio);
      EXPECT_NEAR(double(g.clusters_by_centroid), ideal, 0.08 * ideal) << "region " << k;
      EXPECT_NEAR(ratio, 1.0, 0.1) << "region " << k;
    }
  }
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
    return slurp(dir / file);
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
  append(soup, tri, 3, 0, 0);
  append(soup, tri, 3, 1, 0);
  append(soup, tri, 3, 2, 0);
  append(soup, tet, -3, 0, 0);
  append(soup, tet, -3, 1, 0);
  append(soup, make_icosphere(1, 0.05f), 0, 3, 0);  // 42 V: too small for its share, > 16 V
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

// --- open and dirty inputs -------------------------------------------------------------------------------

TEST(RemeshOpen, OpenAndDirtyInputsGiveManifoldOutput) {
  struct Case {
    std::string name;
    MeshBuffers mesh;
    std::vector<uint32_t> budgets;
  };
  std::vector<Case> cases;
  cases.push_back({"grid", make_grid(80, 80), {20, 300, 1000}});
  cases.push_back({"elephant-with-holes", read_mesh(test::data_path("cgal_elephant_with_holes.off")), {200, 500, 1000, 2000}});
  // 150 non-manifold edges, 87 duplicate faces, 25 unreferenced vertices in the input.
  cases.push_back({"bunny", read_mesh(test::data_path("bun_zipper_res2.ply")), {200, 500, 2000}});
  for (const Case& c : cases) {
    const TopologyStats in = compute_topology_stats(c.mesh.view());
    MeshStore store = MeshStore::build(c.mesh.view());
    for (uint32_t n : c.budgets) {
      SCOPED_TRACE(c.name + " N=" + std::to_string(n));
      PipelineOptions o;
      o.remesh.clustering = test::metric_i_one_thread();
      o.remesh.vertices = n;
      PipelineResult r = remesh_store(store, o);
      const TopologyStats& t = r.output_topology;
      std::printf("[ open     ] %-20s N=%-5u -> V=%u (strip vertices %llu) loops %llu -> %llu, holes closed %llu, chi %lld -> %lld, faces removed %llu\n",
                  c.name.c_str(), n, r.remesh.mesh.vertex_count(), (unsigned long long)r.remesh.dual.boundary_vertices_added,
                  (unsigned long long)in.boundary_loops, (unsigned long long)t.boundary_loops,
                  (unsigned long long)r.remesh.dual.holes_closed, (long long)in.euler_characteristic,
                  (long long)t.euler_characteristic, (unsigned long long)r.remesh.placement.defects_removed.faces_removed);
      EXPECT_EQ(r.remesh.placement.defect_vertices, 0u);
      EXPECT_EQ(t.nonmanifold_edges, 0u);
      EXPECT_EQ(t.nonmanifold_vertices, 0u);
      EXPECT_EQ(t.duplicate_faces, 0u);
      EXPECT_EQ(t.isolated_vertices, 0u);
      EXPECT_TRUE(t.consistently_oriented);
      EXPECT_EQ(r.remesh.clusters, n);
      // N vertices, strips included, but where the strips alone need half of N or more (said
      // in the budget note) or the last-resort cleanup deleted some (the dirty bunny).
      EXPECT_EQ(int64_t(r.remesh.mesh.vertex_count()),
                int64_t(n) - r.remesh.dual.vertex_shortfall - int64_t(r.remesh.placement.defects_removed.vertices_removed));
      if (2 * r.remesh.dual.boundary_vertices_added < n && r.remesh.placement.defects_removed.vertices_removed == 0) {
        EXPECT_EQ(r.remesh.mesh.vertex_count(), n);
      } else if (r.remesh.dual.vertex_shortfall != 0) {
        EXPECT_FALSE(r.remesh.budget.note.empty()) << "a missed N must be explained";
      }
      EXPECT_GT(r.remesh.dual.boundary_vertices_added, 0u);
      if (c.name != "bunny") {  // manifold inputs: every hole is either kept or closed by the dual
        EXPECT_EQ(r.remesh.placement.defects_removed.faces_removed, 0u);
        EXPECT_EQ(t.boundary_loops + r.remesh.dual.holes_closed, in.boundary_loops);
        EXPECT_EQ(t.components, 1u);
        // Same genus, g = (2 − χ − loops) / 2 for one orientable component with boundary; a
        // closed hole raises χ by one and removes one loop.
        EXPECT_EQ(2 - t.euler_characteristic - int64_t(t.boundary_loops),
                  2 - in.euler_characteristic - int64_t(in.boundary_loops))
            << "genus changed";
      }
    }
  }
  {
    // The elephant's holes at N = 2000: those narrower than two output edges close (each adds
    // a disc: χ + 1), the others keep their loop, the genus stays.
    MeshBuffers holes = read_mesh(test::data_path("cgal_elephant_with_holes.off"));
    const TopologyStats in = compute_topology_stats(holes.view());
    MeshStore store = MeshStore::build(holes.view());
    PipelineOptions o;
    o.remesh.clustering = test::metric_i_one_thread();
    o.remesh.vertices = 2000;
    PipelineResult r = remesh_store(store, o);
    EXPECT_EQ(r.output_topology.boundary_loops + r.remesh.dual.holes_closed, in.boundary_loops);
    EXPECT_GT(2 * r.output_topology.boundary_loops, in.boundary_loops) << "most holes are wider than two edges";
    EXPECT_EQ(r.output_topology.euler_characteristic, in.euler_characteristic + int64_t(r.remesh.dual.holes_closed));
  }
}

TEST(RemeshOpen, FlatGridOutputHasNoFoldedTriangles) {
  // Every output triangle of a flat +z grid must face +z. Known failure (see report): at a convex
  // boundary corner the §VI-D strip triangle (p_t, p_t+1, b) folds when the centroid of the corner
  // cluster b lies on or beyond the chord p_t p_t+1 (measured: 1-3 folded triangles per run).
  for (uint64_t seed : {1ull, 2ull}) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    MeshBuffers grid = make_grid(80, 80);
    MeshStore store = MeshStore::build(grid.view());
    RemeshOptions o;
    o.clustering = test::metric_i_one_thread();
    o.vertices = 300;
    o.seed = seed;
    RemeshResult r = remesh(store.view(), o);
    const auto& P = r.mesh.positions;
    const auto& T = r.mesh.triangles;
    uint32_t folded = 0;
    for (size_t f = 0; f < T.size(); f += 3) {
      const float *a = &P[3 * size_t(T[f])], *b = &P[3 * size_t(T[f + 1])], *c = &P[3 * size_t(T[f + 2])];
      double z = (double(b[0]) - a[0]) * (double(c[1]) - a[1]) - (double(b[1]) - a[1]) * (double(c[0]) - a[0]);
      folded += z <= 0;
    }
    std::printf("[ open     ] grid 80x80 N=300 seed %llu: %u of %zu output triangles folded\n", (unsigned long long)seed,
                folded, T.size() / 3);
    EXPECT_EQ(folded, 0u);
  }
}

// Eight pieces with boundaries (grids of different sizes and shapes), a closed torus and a
// small sphere in one soup: every metric gives exactly N output vertices, strip vertices included, with each piece kept.
TEST(RemeshExactCount, ManyPiecesWithBoundariesGiveExactlyN) {
  MeshBuffers soup;
  auto append = [&](const MeshBuffers& piece, float dx, float dy) {
    const uint32_t base = soup.vertex_count();
    for (size_t i = 0; i < piece.positions.size(); i += 3) {
      soup.positions.push_back(piece.positions[i] + dx);
      soup.positions.push_back(piece.positions[i + 1] + dy);
      soup.positions.push_back(piece.positions[i + 2]);
    }
    for (uint32_t v : piece.triangles) soup.triangles.push_back(base + v);
  };
  for (int k = 0; k < 8; ++k) append(make_grid(30 + 5 * k, 20 + 3 * k, 1.0f + 0.2f * float(k), 0.6f), 0, 1.2f * float(k));
  append(make_torus(80, 40), 5, 0);
  append(make_icosphere(3, 0.3f), 5, 4);
  MeshStore store = MeshStore::build(soup.view());
  for (Metric m : {Metric::I, Metric::IQ, Metric::A, Metric::AQ}) {
    for (uint32_t n : {600u, 2000u}) {
      SCOPED_TRACE(std::string(metric_name(m)) + " N=" + std::to_string(n));
      PipelineOptions o;
      o.remesh.clustering = test::metric_i_one_thread();
      o.remesh.vertices = n;
      o.remesh.clustering.metric = m;
      PipelineResult r = remesh_store(store, o);
      EXPECT_GT(r.remesh.dual.boundary_vertices_added, 0u);
      EXPECT_EQ(r.remesh.mesh.vertex_count(), n) << r.remesh.budget.note;
      EXPECT_EQ(r.remesh.dual.vertex_shortfall, 0);
      EXPECT_EQ(r.output_topology.components, 10u);
      EXPECT_TRUE(r.remesh.checks.components.ok()) << r.remesh.checks.components.problems.front();
      EXPECT_EQ(r.output_topology.nonmanifold_edges + r.output_topology.nonmanifold_vertices, 0u);
    }
  }
}

}  // namespace
}  // namespace streamcvd
