// Degenerate geometry through the whole remeshing job (issue 7): zero-area faces, coincident
// vertices, slivers, isolated vertices, a single triangle, tiny and huge budgets, more
// components than clusters, flat and needle shapes, extreme coordinates. Each run must end
// (bounded loops), never crash, and either produce a valid mesh or throw a clear InputError.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/remesh_pipeline.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

void append(MeshBuffers& a, const MeshBuffers& b, float dx = 0, float dy = 0, float dz = 0, float scale = 1) {
  const uint32_t offset = a.vertex_count();
  for (size_t i = 0; i < b.positions.size(); i += 3)
    a.positions.insert(a.positions.end(),
                       {b.positions[i] * scale + dx, b.positions[i + 1] * scale + dy, b.positions[i + 2] * scale + dz});
  for (uint32_t i : b.triangles) a.triangles.push_back(i + offset);
}

MeshBuffers single_triangle() {
  MeshBuffers m;
  m.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  m.triangles = {0, 1, 2};
  return m;
}

MeshBuffers tetrahedron() {
  MeshBuffers m;
  m.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  m.triangles = {0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3};
  return m;
}

/// Grid whose every other row of faces has collapsed onto a line (zero area, distinct indices),
/// plus faces with a repeated index.
MeshBuffers grid_with_zero_area_faces() {
  MeshBuffers m = make_grid(20, 20);
  for (uint32_t v = 0; v < m.vertex_count(); ++v)
    if ((v / 20) % 2 == 1) m.positions[3 * v + 1] = m.positions[3 * (v - 20) + 1];  // row onto the previous
  for (uint32_t f = 0; f < 40; ++f) m.triangles.insert(m.triangles.end(), {f, f, f + 1});
  return m;
}

/// Sphere whose vertices are duplicated: the faces of each vertex alternate between two copies
/// at the same position (a crack everywhere, many coincident vertices).
MeshBuffers sphere_with_coincident_vertices() {
  MeshBuffers m = make_icosphere(2);
  const uint32_t v0 = m.vertex_count();
  m.positions.insert(m.positions.end(), m.positions.begin(), m.positions.end());
  for (size_t i = 0; i < m.triangles.size(); i += 6) m.triangles[i] += v0;
  return m;
}

/// Every vertex at the origin: no area at all.
MeshBuffers all_vertices_coincident() {
  MeshBuffers m = make_icosphere(1);
  std::fill(m.positions.begin(), m.positions.end(), 0.0f);
  return m;
}

MeshBuffers slivers() {
  MeshBuffers m = make_grid(60, 4, 1.0f, 1e-6f);
  return m;
}

MeshBuffers sphere_with_isolated_vertices() {
  MeshBuffers m = make_icosphere(2);
  for (int i = 0; i < 300; ++i) m.positions.insert(m.positions.end(), {5.0f + i, 0.0f, 0.0f});
  return m;
}

/// A torus with a minor radius 10^4 times smaller than the major one and 3 segments around:
/// a closed needle-thin ring.
MeshBuffers needle() { return make_torus(400, 3, 1.0f, 1e-4f); }

/// One sphere and many tiny tetrahedra: most components are far below one cluster.
MeshBuffers mostly_tiny_components() {
  MeshBuffers m = make_icosphere(3);
  for (int i = 0; i < 400; ++i) append(m, tetrahedron(), 3.0f + float(i % 20), float(i / 20), 0.0f, 1e-3f);
  return m;
}

MeshBuffers many_components() {
  MeshBuffers m;
  for (int i = 0; i < 60; ++i) append(m, make_icosphere(1), 3.0f * float(i), 0, 0);
  return m;
}

MeshBuffers bowtie_and_double_sided() {
  MeshBuffers m;
  m.positions = {0, 0, 0, 1, 0, 0, 1, 1, 0, -1, 0, 0, -1, -1, 0, 0, 0, 1};
  m.triangles = {0, 1, 2, 0, 3, 4,   // bowtie: two triangles sharing only vertex 0
                 0, 1, 5, 0, 5, 1};  // the same triangle in both orientations
  return m;
}

MeshBuffers huge_coordinates() {
  MeshBuffers m = make_icosphere(3, 1e30f);
  return m;
}

MeshBuffers tiny_coordinates() {
  MeshBuffers m = make_icosphere(3, 1e-30f);
  return m;
}

MeshBuffers far_from_origin() {
  MeshBuffers m = make_icosphere(3, 1.0f);
  for (size_t i = 0; i < m.positions.size(); i += 3) m.positions[i] += 1e7f;
  return m;
}

MeshBuffers only_degenerate_faces() {
  MeshBuffers m;
  m.positions = {0, 0, 0, 1, 0, 0, 2, 0, 0, 3, 0, 0};
  m.triangles = {0, 1, 2, 1, 2, 3, 0, 0, 1, 3, 3, 3};
  return m;
}

struct DegenerateCase {
  const char* name;
  std::function<MeshBuffers()> make;
  std::vector<uint32_t> budgets;
};

const std::vector<DegenerateCase>& cases() {
  static const std::vector<DegenerateCase> all = {
      {"SingleTriangle", single_triangle, {1, 2, 3, 4, 100}},
      {"Tetrahedron", tetrahedron, {1, 2, 3, 4, 5, 50}},
      {"SphereTinyBudgets", [] { return make_icosphere(3); }, {1, 2, 3, 4}},
      {"SphereBudgetAtAndAboveV", [] { return make_icosphere(1); }, {41, 42, 43, 200, 5000}},
      {"GridBudgetAboveV", [] { return make_grid(5, 5); }, {25, 26, 400}},
      {"FlatPlane", [] { return make_grid(60, 60); }, {3, 10, 100, 1000}},
      {"ZeroAreaFaces", grid_with_zero_area_faces, {4, 50, 200}},
      {"CoincidentVertices", sphere_with_coincident_vertices, {4, 50, 150}},
      {"AllVerticesCoincident", all_vertices_coincident, {1, 4, 20}},
      {"Slivers", slivers, {3, 20, 100}},
      {"IsolatedVertices", sphere_with_isolated_vertices, {4, 60, 500}},
      {"Needle", needle, {3, 10, 100, 1000}},
      {"FewerClustersThanComponents", many_components, {1, 10, 59, 60, 61, 300}},
      {"MostlyTinyComponents", mostly_tiny_components, {1, 20, 200}},
      {"BowtieAndDoubleSided", bowtie_and_double_sided, {1, 3, 6, 20}},
      {"HugeCoordinates", huge_coordinates, {4, 100}},
      {"TinyCoordinates", tiny_coordinates, {4, 100}},
      {"FarFromOrigin", far_from_origin, {4, 100}},
      {"OnlyDegenerateFaces", only_degenerate_faces, {1, 3, 10}},
      {"NoFacesAtAll", [] { MeshBuffers m; m.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0}; return m; }, {1, 3}},
  };
  return all;
}

/// The output contract of a run that did not throw: indices in range, finite coordinates, no
/// non-manifold edge or vertex, no duplicate face, no face with a repeated index.
void expect_valid_output(const PipelineResult& r, const std::string& what) {
  const MeshBuffers& out = r.remesh.mesh;
  ASSERT_EQ(out.positions.size() % 3, 0u) << what;
  ASSERT_EQ(out.triangles.size() % 3, 0u) << what;
  for (float x : out.positions) ASSERT_TRUE(std::isfinite(x)) << what << ": non-finite output coordinate";
  for (size_t f = 0; f < out.triangles.size(); f += 3) {
    const uint32_t* t = &out.triangles[f];
    ASSERT_TRUE(t[0] < out.vertex_count() && t[1] < out.vertex_count() && t[2] < out.vertex_count()) << what;
    ASSERT_TRUE(t[0] != t[1] && t[1] != t[2] && t[0] != t[2]) << what << ": face " << f / 3 << " repeats an index";
  }
  const TopologyStats s = compute_topology_stats(out.view());
  EXPECT_GT(s.faces, 0u) << what << ": an empty result must be an InputError";
  EXPECT_EQ(s.nonmanifold_edges, 0u) << what;
  EXPECT_EQ(s.nonmanifold_vertices, 0u) << what;
  EXPECT_EQ(s.duplicate_faces, 0u) << what;
  EXPECT_EQ(s.isolated_vertices, 0u) << what;
  EXPECT_EQ(r.remesh.placement.defect_vertices, 0u) << what;
  EXPECT_EQ(r.output_topology.faces, s.faces) << what;
}

class DegenerateRemesh : public ::testing::TestWithParam<size_t> {};

TEST_P(DegenerateRemesh, EndsWithValidMeshOrInputError) {
  const DegenerateCase& c = cases()[GetParam()];
  const MeshBuffers mesh = c.make();
  for (uint32_t n : c.budgets)
    for (SmallComponents small : {SmallComponents::Keep, SmallComponents::Drop}) {
      const std::string what = std::string(c.name) + " N=" + std::to_string(n) +
                               (small == SmallComponents::Keep ? " keep" : " drop");
      SCOPED_TRACE(what);
      PipelineOptions options;
      options.remesh.clustering = test::metric_i_one_thread();
      options.remesh.vertices = n;
      options.remesh.small_components = small;
      try {
        MeshStore store = MeshStore::build(mesh.view());
        const PipelineResult r = remesh_store(store, options);
        if (std::getenv("STREAMCVD_DEGENERATE_VERBOSE"))
          std::printf("%s: V %llu F %llu clusters %u loops %u+%u repair %u defects %llu removed %llu\n", what.c_str(),
                      (unsigned long long)r.output_topology.vertices, (unsigned long long)r.output_topology.faces,
                      r.remesh.clusters, r.remesh.clustering.unconstrained_loops, r.remesh.clustering.constrained_loops,
                      r.remesh.repair.rounds, (unsigned long long)r.remesh.placement.defect_vertices,
                      (unsigned long long)r.remesh.placement.defects_removed.faces_removed);
        expect_valid_output(r, what);
        // Loops are bounded by the options, whatever the input.
        EXPECT_LE(r.remesh.clustering.unconstrained_loops, options.remesh.clustering.loops.max_loops) << what;
        EXPECT_LE(r.remesh.clustering.constrained_loops, options.remesh.clustering.loops.max_loops) << what;
        EXPECT_LE(r.remesh.repair.rounds, options.remesh.repair_rounds) << what;
      } catch (const InputError& e) {
        // Acceptable: a clear one-line message.
        const std::string msg = e.what();
        if (std::getenv("STREAMCVD_DEGENERATE_VERBOSE")) std::printf("%s: InputError %s\n", what.c_str(), msg.c_str());
        EXPECT_FALSE(msg.empty()) << what;
        EXPECT_EQ(msg.find('\n'), std::string::npos) << what << ": " << msg;
      }
    }
}

INSTANTIATE_TEST_SUITE_P(Cases, DegenerateRemesh, ::testing::Range<size_t>(0, cases().size()),
                         [](const auto& info) { return std::string(cases()[info.param].name); });

// Specific outcomes, beyond "valid or InputError".

PipelineResult run(const MeshBuffers& mesh, uint32_t n, SmallComponents small = SmallComponents::Keep) {
  PipelineOptions options;
  options.remesh.clustering = test::metric_i_one_thread();
  options.remesh.vertices = n;
  options.remesh.small_components = small;
  MeshStore store = MeshStore::build(mesh.view());
  return remesh_store(store, options);
}

TEST(DegenerateRemesh, SingleTriangleStaysOneDisc) {
  for (uint32_t n : {3u, 10u}) {
    const PipelineResult r = run(single_triangle(), n);
    const TopologyStats s = compute_topology_stats(r.remesh.mesh.view());
    EXPECT_EQ(s.components, 1u) << n;
    EXPECT_EQ(s.boundary_loops, 1u) << n;
    EXPECT_EQ(s.euler_characteristic, 1) << n;
  }
}

TEST(DegenerateRemesh, EmptyResultIsAnInputError) {
  // Every component below its minimum share and dropped; a needle thinner than any cluster; a
  // mesh without faces.
  MeshBuffers no_faces;
  no_faces.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  for (const auto& [mesh, small] : {std::pair{many_components(), SmallComponents::Drop},
                                    std::pair{needle(), SmallComponents::Keep},
                                    std::pair{tetrahedron(), SmallComponents::Drop},
                                    std::pair{no_faces, SmallComponents::Keep}}) {
    try {
      run(mesh, 2, small);
      ADD_FAILURE() << "no error for a mesh of " << mesh.vertex_count() << " vertices";
    } catch (const InputError& e) {
      const std::string msg = e.what();
      EXPECT_FALSE(msg.empty());
      EXPECT_EQ(msg.find('\n'), std::string::npos) << msg;
    }
  }
}

TEST(DegenerateRemesh, ClosedSphereAtFourClustersStaysClosed) {
  const PipelineResult r = run(make_icosphere(3), 4);
  const TopologyStats s = compute_topology_stats(r.remesh.mesh.view());
  EXPECT_TRUE(s.closed_manifold);
  EXPECT_EQ(s.euler_characteristic, 2);
}

TEST(DegenerateRemesh, ManyEqualComponentsAllSurvive) {
  const PipelineResult r = run(many_components(), 300);
  const TopologyStats s = compute_topology_stats(r.remesh.mesh.view());
  EXPECT_EQ(s.components, 60u);
  EXPECT_TRUE(s.closed_manifold);
  EXPECT_EQ(s.euler_characteristic, 120);
}

TEST(DegenerateRemesh, IsolatedVerticesGetNoOutputVertex) {
  const PipelineResult r = run(sphere_with_isolated_vertices(), 60);
  const TopologyStats s = compute_topology_stats(r.remesh.mesh.view());
  EXPECT_EQ(s.isolated_vertices, 0u);
  EXPECT_TRUE(s.closed_manifold);
}

}  // namespace
}  // namespace streamcvd
