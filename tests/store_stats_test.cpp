// compute_topology_stats(MeshView): field by field equal to the soup version on the same mesh,
// for the bundled meshes and generated ones, with stores cut into many chunks so that
// components and boundary loops cross chunk frontiers; known figures where they are known.
#include "streamcvd/core/measure/store_stats.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/cli_runner.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

// Bitwise, so that NaN boxes compare equal to NaN boxes and -0 differs from 0.
bool same_float(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

/// Same vertex order: the box bit for bit. The soup version keeps the first of equal minima
/// (its std::min), so across a renumbering the box is only equal by value: -0 may become 0.
enum class Order { same, renumbered };

void expect_same(const TopologyStats& got, const TopologyStats& want, const std::string& what,
                 Order order = Order::same) {
  SCOPED_TRACE(what);
  EXPECT_EQ(got.vertices, want.vertices);
  EXPECT_EQ(got.faces, want.faces);
  EXPECT_EQ(got.edges, want.edges);
  for (int i = 0; i < 3; ++i) {
    if (order == Order::same) {
      EXPECT_TRUE(same_float(got.bbox_min[i], want.bbox_min[i])) << got.bbox_min[i] << " vs " << want.bbox_min[i];
      EXPECT_TRUE(same_float(got.bbox_max[i], want.bbox_max[i])) << got.bbox_max[i] << " vs " << want.bbox_max[i];
    } else {
      EXPECT_EQ(got.bbox_min[i], want.bbox_min[i]);
      EXPECT_EQ(got.bbox_max[i], want.bbox_max[i]);
    }
  }
  EXPECT_EQ(got.boundary_edges, want.boundary_edges);
  EXPECT_EQ(got.boundary_loops, want.boundary_loops);
  EXPECT_EQ(got.nonmanifold_edges, want.nonmanifold_edges);
  EXPECT_EQ(got.nonmanifold_vertices, want.nonmanifold_vertices);
  EXPECT_EQ(got.duplicate_faces, want.duplicate_faces);
  EXPECT_EQ(got.degenerate_faces, want.degenerate_faces);
  EXPECT_EQ(got.isolated_vertices, want.isolated_vertices);
  EXPECT_EQ(got.components, want.components);
  EXPECT_EQ(got.euler_characteristic, want.euler_characteristic);
  EXPECT_EQ(got.closed_manifold, want.closed_manifold);
  EXPECT_EQ(got.consistently_oriented, want.consistently_oriented);
  EXPECT_EQ(got.genus, want.genus);
}

// Store results for several chunk sizes (the smallest give many chunks, so every component and
// loop of a mesh of a few hundred faces crosses frontiers), with and without the Hilbert order,
// each checked against the soup version on the input and on the store's own soup. Returns the
// figures (all equal by then).
TopologyStats check_store_matches_soup(const MeshBuffers& mesh, const std::string& name) {
  const TopologyStats want = compute_topology_stats(mesh.view());
  const uint64_t f = mesh.face_count();
  for (uint64_t per_chunk : {uint64_t(1), uint64_t(7), std::max<uint64_t>(1, f / 10), uint64_t(1) << 20})
    for (bool hilbert : {true, false}) {
      const MeshStore store = MeshStore::build(mesh.view(), {.faces_per_chunk = per_chunk, .hilbert_order = hilbert, .clean_topology = false});
      const MeshView view = store.view();
      if (per_chunk == 7 && f >= 14) {
        EXPECT_GE(view.chunks.size(), 2u) << name;
      }
      const std::string what = name + ", " + std::to_string(view.chunks.size()) + " chunks" + (hilbert ? "" : ", input order");
      const TopologyStats got = compute_topology_stats(view);
      expect_same(got, compute_topology_stats(view.soup()), what + " (store's soup)");
      expect_same(got, want, what, hilbert ? Order::renumbered : Order::same);
    }
  return want;
}

MeshBuffers soup(std::vector<float> positions, std::vector<uint32_t> triangles) {
  MeshBuffers m;
  m.positions = std::move(positions);
  m.triangles = std::move(triangles);
  return m;
}

// Copies b into a, its indices shifted, optionally moved along x.
void append(MeshBuffers& a, const MeshBuffers& b, float dx = 0) {
  const uint32_t offset = a.vertex_count();
  for (size_t i = 0; i < b.positions.size(); ++i) a.positions.push_back(b.positions[i] + (i % 3 == 0 ? dx : 0.0f));
  for (uint32_t v : b.triangles) a.triangles.push_back(v + offset);
}

// nx × ny grid of unit cells with cells (i, j) in `holes` left out (holes inside the grid:
// each is a boundary loop of its own unless holes touch).
MeshBuffers grid_with_holes(int nx, int ny, const std::vector<std::pair<int, int>>& holes) {
  MeshBuffers g = make_grid(nx + 1, ny + 1, float(nx), float(ny));
  MeshBuffers m;
  m.positions = g.positions;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      if (std::find(holes.begin(), holes.end(), std::make_pair(i, j)) != holes.end()) continue;
      const size_t cell = size_t(j * nx + i) * 6;
      m.triangles.insert(m.triangles.end(), g.triangles.begin() + long(cell), g.triangles.begin() + long(cell + 6));
    }
  return m;
}

TEST(StoreStats, BundledMeshes) {
  struct Known {
    const char* file;
    uint64_t components, boundary_loops, nonmanifold_edges;
    int64_t genus;
  };
  // Figures of tests/data/SOURCES.md (MANIFEST.tsv); genus only for the closed ones.
  const Known known[] = {{"cgal_elephant.off", 1, 0, 0, 3},
                         {"cgal_elephant_with_holes.off", 1, 106, 0, -1},
                         {"cgal_hand.off", 1, 0, 0, -2},
                         {"cgal_fandisk.off.zst", 1, 0, 0, 0},
                         {"fertility.off.zst", 1, 0, 0, 4},
                         {"beetle_nonmanifold.obj", 2, 23, 47, -1},
                         {"bun_zipper_res2.ply", 1, 5, 150, -1}};
  for (const Known& k : known) {
    const MeshBuffers mesh = read_mesh(test::data_path(k.file));
    const TopologyStats s = check_store_matches_soup(mesh, k.file);
    EXPECT_EQ(s.components, k.components) << k.file;
    EXPECT_EQ(s.boundary_loops, k.boundary_loops) << k.file;
    EXPECT_EQ(s.nonmanifold_edges, k.nonmanifold_edges) << k.file;
    if (k.genus != -2) {
      EXPECT_EQ(s.genus, k.genus) << k.file;
    }
  }
  // The bunny's other defects (SOURCES.md): duplicate faces and unreferenced vertices.
  const TopologyStats bunny = compute_topology_stats(read_mesh(test::data_path("bun_zipper_res2.ply")).view());
  EXPECT_GT(bunny.duplicate_faces, 0u);
  EXPECT_GT(bunny.isolated_vertices, 0u);
}

TEST(StoreStats, ClosedShapes) {
  const TopologyStats sphere = check_store_matches_soup(make_icosphere(3), "icosphere");
  EXPECT_EQ(sphere.euler_characteristic, 2);
  EXPECT_EQ(sphere.genus, 0);
  EXPECT_TRUE(sphere.closed_manifold);
  EXPECT_TRUE(sphere.consistently_oriented);
  const TopologyStats torus = check_store_matches_soup(make_torus(40, 16), "torus");
  EXPECT_EQ(torus.euler_characteristic, 0);
  EXPECT_EQ(torus.genus, 1);
  EXPECT_EQ(torus.components, 1u);
  EXPECT_EQ(torus.edges, 3u * 40 * 16);
  const TopologyStats capsule = check_store_matches_soup(make_capsule(12), "capsule");
  EXPECT_EQ(capsule.genus, 0);
}

TEST(StoreStats, GridWithHolesHasOneLoopPerHole) {
  const TopologyStats grid = check_store_matches_soup(make_grid(30, 20), "grid");
  EXPECT_EQ(grid.boundary_loops, 1u);
  EXPECT_EQ(grid.boundary_edges, 2u * (29 + 19));
  EXPECT_EQ(grid.euler_characteristic, 1);
  // Three separate holes, plus two that touch at one vertex (one loop by the convention).
  const TopologyStats holes =
      check_store_matches_soup(grid_with_holes(24, 18, {{3, 3}, {12, 9}, {20, 14}, {6, 12}, {7, 13}}), "grid with holes");
  EXPECT_EQ(holes.boundary_loops, 1u + 3 + 1);
  EXPECT_EQ(holes.components, 1u);
  EXPECT_EQ(holes.nonmanifold_vertices, 1u);  // where the two holes touch
}

TEST(StoreStats, DisjointComponentsAndIsolatedVertices) {
  MeshBuffers m = make_icosphere(2);
  append(m, make_torus(24, 10), 3.0f);
  append(m, make_grid(12, 9), -3.0f);
  m.positions.insert(m.positions.end(), {9, 9, 9, -9, 0, 0});  // two unreferenced vertices
  const TopologyStats s = check_store_matches_soup(m, "sphere + torus + grid");
  EXPECT_EQ(s.components, 3u);
  EXPECT_EQ(s.boundary_loops, 1u);
  EXPECT_EQ(s.isolated_vertices, 2u);
  EXPECT_EQ(s.euler_characteristic, 2 + 0 + 1);
  EXPECT_EQ(s.genus, -1);  // several components
}

TEST(StoreStats, BowtiesAndNonManifoldEdges) {
  // Two grids sharing one corner vertex: a bowtie (one non-manifold vertex, one component, and
  // one boundary loop through the shared vertex).
  MeshBuffers a = make_grid(8, 8);
  MeshBuffers b = make_grid(8, 8);
  for (size_t i = 0; i < b.positions.size(); ++i) b.positions[i] = -b.positions[i];
  const uint32_t offset = a.vertex_count();
  a.positions.insert(a.positions.end(), b.positions.begin(), b.positions.end());
  for (uint32_t v : b.triangles) a.triangles.push_back(v == 0 ? 0 : v + offset);  // share vertex 0
  const TopologyStats bowtie = check_store_matches_soup(a, "grid bowtie");
  EXPECT_EQ(bowtie.nonmanifold_vertices, 1u);
  EXPECT_EQ(bowtie.nonmanifold_edges, 0u);
  EXPECT_EQ(bowtie.components, 1u);
  EXPECT_EQ(bowtie.boundary_loops, 1u);
  EXPECT_EQ(bowtie.isolated_vertices, 1u);  // b's own vertex 0
  // Two closed spheres touching at a vertex: only the corner classes can tell.
  MeshBuffers s = make_icosphere(1);
  const MeshBuffers t = make_icosphere(1);
  const uint32_t n = s.vertex_count();
  for (size_t i = 0; i < t.positions.size(); ++i) s.positions.push_back(t.positions[i] + (i % 3 == 0 ? 2.0f : 0.0f));
  for (uint32_t v : t.triangles) s.triangles.push_back(v == 0 ? 0 : v + n);
  const TopologyStats spheres = check_store_matches_soup(s, "two spheres at a vertex");
  EXPECT_EQ(spheres.nonmanifold_vertices, 1u);
  EXPECT_EQ(spheres.boundary_edges, 0u);
  EXPECT_FALSE(spheres.closed_manifold);
  // A fin: a third face on an edge of cell (2, 2) of a 5 × 5-cell grid (an interior edge).
  MeshBuffers fin = make_grid(6, 6);
  fin.positions.insert(fin.positions.end(), {0.5f, 0.5f, 1.0f});
  const size_t face = (2 * 5 + 2) * 2;
  fin.triangles.insert(fin.triangles.end(), {fin.triangles[3 * face], fin.triangles[3 * face + 1], fin.vertex_count() - 1});
  const TopologyStats finned = check_store_matches_soup(fin, "grid with a fin");
  EXPECT_EQ(finned.nonmanifold_edges, 1u);
  EXPECT_EQ(finned.nonmanifold_vertices, 2u);
}

TEST(StoreStats, DuplicateAndDegenerateFaces) {
  MeshBuffers m = make_grid(10, 10);
  const std::vector<uint32_t> t(m.triangles.begin(), m.triangles.begin() + 12);
  // Duplicates: the same face, reversed, rotated; degenerate ones: repeated indices (a,a,b),
  // (a,b,a) (the same set: a duplicate too), (a,a,a), and a zero-area face on collinear vertices.
  m.triangles.insert(m.triangles.end(), {t[0], t[1], t[2], t[2], t[1], t[0], t[4], t[5], t[3]});
  m.triangles.insert(m.triangles.end(), {t[6], t[6], t[7], t[6], t[7], t[6], t[8], t[8], t[8], 0, 1, 2});
  m.triangles.insert(m.triangles.end(), {t[9], t[9], t[10], t[9], t[10], t[10]});  // {a,a,b} = {a,b,b}
  const TopologyStats s = check_store_matches_soup(m, "duplicates and degenerates");
  EXPECT_EQ(s.duplicate_faces, 5u);
  EXPECT_EQ(s.degenerate_faces, 6u);
  // A flipped face: its edges keep two uses each, in the same direction.
  MeshBuffers flipped = make_grid(10, 10);
  std::swap(flipped.triangles[3 * 40], flipped.triangles[3 * 40 + 1]);
  const TopologyStats f = check_store_matches_soup(flipped, "flipped face");
  EXPECT_FALSE(f.consistently_oriented);
  EXPECT_TRUE(check_store_matches_soup(make_grid(10, 10), "grid").consistently_oriented);
}

TEST(StoreStats, NonFiniteCoordinatesCountDegenerateFacesWithTheExactBox) {
  // An infinite coordinate makes the zero-area threshold infinite (every finite face is then
  // degenerate); NaN at vertex 0 makes the box NaN on that axis (and no face degenerate by
  // area). The chunk boxes skip both, so these take the recount path.
  MeshBuffers inf = make_grid(6, 6);
  inf.positions.insert(inf.positions.end(), {std::numeric_limits<float>::infinity(), 0, 0});
  check_store_matches_soup(inf, "infinite coordinate");
  EXPECT_EQ(compute_topology_stats(inf.view()).degenerate_faces, inf.face_count());
  MeshBuffers nan = make_grid(6, 6);
  nan.positions[1] = std::numeric_limits<float>::quiet_NaN();
  const MeshStore store = MeshStore::build(nan.view(), {.faces_per_chunk = 7, .hilbert_order = false, .clean_topology = false});
  const TopologyStats s = compute_topology_stats(store.view());
  expect_same(s, compute_topology_stats(nan.view()), "NaN at vertex 0");
  EXPECT_TRUE(std::isnan(s.bbox_min[1]));
}

TEST(StoreStats, RandomSoupsWithEveryDefect) {
  // Random faces over few vertices: repeated indices, duplicates, fins, bowties, flipped faces,
  // unreferenced vertices, all at once.
  std::mt19937 rng(11);
  for (int trial = 0; trial < 30; ++trial) {
    const uint32_t nv = 8 + rng() % 60, nf = 1 + rng() % 150;
    MeshBuffers m;
    for (uint32_t v = 0; v < nv; ++v)
      for (int k = 0; k < 3; ++k) m.positions.push_back(float(rng() % 5));  // coincident points too
    for (uint32_t f = 0; f < nf; ++f) {
      const uint32_t a = rng() % nv, spread = 1 + rng() % 6;
      for (int k = 0; k < 3; ++k) m.triangles.push_back(rng() % 8 == 0 ? a : (a + rng() % spread) % nv);
    }
    check_store_matches_soup(m, "random soup " + std::to_string(trial));
  }
}

TEST(StoreStats, EmptyAndTinyStores) {
  check_store_matches_soup(MeshBuffers{}, "empty");
  check_store_matches_soup(soup({0, 0, 0, 1, 0, 0, 0, 1, 0}, {}), "vertices only");
  const TopologyStats one = check_store_matches_soup(soup({0, 0, 0, 1, 0, 0, 0, 1, 0}, {0, 1, 2}), "one triangle");
  EXPECT_EQ(one.boundary_loops, 1u);
}

TEST(StoreStats, WrongFaceListsThrow) {
  const MeshBuffers mesh = make_icosphere(1);
  const MeshStore store = MeshStore::build(mesh.view(), {.faces_per_chunk = 7, .clean_topology = false});
  MeshView view = store.view();
  // A vertex→face list naming a face that does not hold the vertex.
  std::vector<uint32_t> vf(view.vertex_face.begin(), view.vertex_face.end());
  const uint32_t v = 5;
  uint32_t alien = 0;
  while (std::find(view.faces_of(v).begin(), view.faces_of(v).end(), alien) != view.faces_of(v).end()) ++alien;
  vf[view.vertex_face_offsets[v]] = alien;
  std::sort(vf.begin() + long(view.vertex_face_offsets[v]), vf.begin() + long(view.vertex_face_offsets[v + 1]));
  view.vertex_face = vf;
  EXPECT_THROW(compute_topology_stats(view), InputError);
  // A face listed twice, apart: ascending order is what makes a repeat visible.
  std::vector<uint32_t> vf2(store.view().vertex_face.begin(), store.view().vertex_face.end());
  const uint64_t first = store.view().vertex_face_offsets[v];
  ASSERT_GE(store.view().faces_of(v).size(), 3u);
  vf2[first + 2] = vf2[first];
  MeshView repeated = store.view();
  repeated.vertex_face = vf2;
  EXPECT_THROW(compute_topology_stats(repeated), InputError);
  // Chunks that leave a vertex out.
  MeshView gap = store.view();
  std::vector<Chunk> chunks(gap.chunks.begin(), gap.chunks.end());
  ASSERT_GE(chunks.size(), 2u);
  chunks[1].vertex_begin += 1;
  gap.chunks = chunks;
  EXPECT_THROW(compute_topology_stats(gap), InputError);
  EXPECT_NO_THROW(compute_topology_stats(store.view()));
}

// `streamcvd info` on a store directory (the store version) prints what it prints for the mesh
// file (the soup version), line for line but the path.
TEST(StoreStats, InfoOnAStoreMatchesInfoOnTheFile) {
  if (!test::cli_available()) GTEST_SKIP() << "CLI not built";
  const std::string mesh = test::data_path("bun_zipper_res2.ply");
  const std::filesystem::path dir = test::temp_dir("store_stats_info");
  const std::string store = (dir / "bunny.store").string();
  const test::CliResult ingest = test::run_cli({"ingest", mesh, store, "--faces-per-chunk", "1000"});
  ASSERT_EQ(ingest.exit_code, 0) << ingest.describe();
  ASSERT_GE(MeshStore::open(store).view().chunks.size(), 10u);
  const test::CliResult from_store = test::run_cli({"info", "--json", store});
  const test::CliResult from_file = test::run_cli({"info", "--json", mesh});
  ASSERT_EQ(from_store.exit_code, 0) << from_store.describe();
  ASSERT_EQ(from_file.exit_code, 0) << from_file.describe();
  auto without_path = [](std::string json, const std::string& path) {
    const size_t at = json.find(path);
    return at == std::string::npos ? json : json.erase(at, path.size());
  };
  EXPECT_EQ(without_path(from_store.out, store), without_path(from_file.out, mesh));
  EXPECT_NE(from_store.out.find("\"duplicate_faces\": 87"), std::string::npos) << from_store.out;
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace streamcvd
