// Sampling independence of the remesher (paper Fig. 5): on a plane of four regions of 1×, 2×,
// 4×, 8× vertex density, clusters follow the area, not the vertices.
#include "streamcvd/core/remesh.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <string>
#include <vector>

#include "streamcvd/core/clustering/item_data.h"
#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

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

}  // namespace
}  // namespace streamcvd
