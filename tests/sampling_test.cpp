// Tests of the chunk-wise component budget, initial sampling and absorption (core/clustering/sampling.cpp):
// the budget of the former global implementation, exact cluster totals when components cross
// many chunks, parts lighter than a cluster, connected clusters, and the same labels for any
// thread count and any storage.
#include <gtest/gtest.h>
#include <tbb/global_control.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cstdio>
#include <numeric>
#include <set>
#include <string>
#include <vector>

#include "streamcvd/core/clustering/clustering.h"
#include "streamcvd/core/clustering/item_data.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/store/store.h"
#include "streamcvd/streaming/schedule/work_space.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

void append(MeshBuffers& a, const MeshBuffers& b) {
  const uint32_t offset = a.vertex_count();
  a.positions.insert(a.positions.end(), b.positions.begin(), b.positions.end());
  for (uint32_t i : b.triangles) a.triangles.push_back(i + offset);
}

MeshBuffers moved(MeshBuffers m, float scale, float dx, float dy, float dz) {
  for (size_t i = 0; i < m.positions.size(); i += 3) {
    m.positions[i] = m.positions[i] * scale + dx;
    m.positions[i + 1] = m.positions[i + 1] * scale + dy;
    m.positions[i + 2] = m.positions[i + 2] * scale + dz;
  }
  return m;
}

// A sphere, a torus, 40 small spheres and 25 small open grids: 67 components, most of them
// small, of many sizes (the budget's small-component rules and its cap all act on it).
MeshBuffers specks() {
  MeshBuffers s = make_icosphere(4, 1.0f);
  for (int i = 0; i < 40; ++i) append(s, moved(make_icosphere(1 + i % 2), 0.02f + 0.01f * float(i % 7), 3.0f + float(i), 0, 0));
  for (int i = 0; i < 25; ++i) append(s, moved(make_grid(2 + i % 4, 3), 0.05f + 0.02f * float(i % 5), 0, 3.0f + float(i), 0));
  append(s, moved(make_torus(30, 12), 1.0f, 0, 0, 4));
  return s;
}

MeshStore store_of(const MeshBuffers& soup, uint64_t faces_per_chunk) {
  return MeshStore::build(soup.view(), StoreBuildOptions{.faces_per_chunk = faces_per_chunk, .clean_topology = false});
}

uint64_t fnv(const std::vector<uint32_t>& v) {
  uint64_t h = 1469598103934665603ull;
  for (uint32_t x : v) {
    h ^= x;
    h *= 1099511628211ull;
  }
  return h;
}

// Component of every vertex by a BFS from the smallest unvisited vertex on a face: the former
// implementation, numbered by smallest vertex as the chunk-wise one must be.
std::vector<uint32_t> reference_components(const MeshView& mesh) {
  std::vector<uint32_t> comp(mesh.vertex_count(), kNoComponent);
  uint32_t count = 0;
  for (uint32_t s = 0; s < mesh.vertex_count(); ++s) {
    if (comp[s] != kNoComponent || mesh.faces_of(s).empty()) continue;
    std::vector<uint32_t> queue = {s};
    comp[s] = count;
    for (size_t h = 0; h < queue.size(); ++h)
      for (uint32_t n : mesh.neighbours(queue[h]))
        if (comp[n] == kNoComponent) comp[n] = count, queue.push_back(n);
    ++count;
  }
  return comp;
}


// Everything initial_sampling promises for `budget`: labels in range, −1 exactly on isolated
// vertices and components without clusters, each component holding exactly its clusters, every
// cluster non-empty and in one piece.
void expect_valid_sampling(const MeshView& mesh, const ComponentBudget& budget, std::span<const int32_t> labels) {
  const uint32_t K = budget.total_clusters;
  ASSERT_EQ(labels.size(), mesh.vertex_count());
  std::vector<int64_t> component_of_label(K, -1);
  std::vector<uint32_t> size(K, 0);
  std::vector<std::set<int32_t>> labels_of_component(budget.clusters_per_component.size());
  for (uint32_t v = 0; v < mesh.vertex_count(); ++v) {
    const uint32_t c = budget.component_of_vertex[v];
    if (c == kNoComponent || budget.clusters_per_component[c] == 0) {
      ASSERT_EQ(labels[v], -1) << "vertex " << v;
      continue;
    }
    ASSERT_GE(labels[v], 0) << "vertex " << v;
    ASSERT_LT(labels[v], int32_t(K)) << "vertex " << v;
    const int32_t l = labels[v];
    if (component_of_label[l] < 0) component_of_label[l] = c;
    ASSERT_EQ(component_of_label[l], int64_t(c)) << "label " << l << " spans components";
    ++size[l];
    labels_of_component[c].insert(l);
  }
  for (size_t c = 0; c < labels_of_component.size(); ++c)
    EXPECT_EQ(labels_of_component[c].size(), budget.clusters_per_component[c]) << "component " << c;
  for (uint32_t l = 0; l < K; ++l) EXPECT_GT(size[l], 0u) << "cluster " << l << " is empty";
  const std::vector<uint32_t> pieces = test::pieces_per_cluster(mesh, labels, K);
  for (uint32_t l = 0; l < K; ++l) EXPECT_LE(pieces[l], 1u) << "cluster " << l << " is in " << pieces[l] << " pieces";
  EXPECT_TRUE(clusters_connected(mesh, labels, K));
}

// --- budget -----------------------------------------------------------------------------------

TEST(SamplingBudget, CountsOfTheFormerGlobalImplementationForAnyChunking) {
  // Expected figures computed with the former implementation (global BFS components, serial
  // sums) before the chunk-wise one replaced it: mesh, N, keep small components?, components,
  // total, small kept, dropped, FNV-1a of clusters_per_component, its first 12 entries, note.
  struct Expected {
    const char* mesh;
    uint32_t n;
    bool keep;
    size_t components;
    uint32_t total, kept, dropped;
    uint64_t hash;
    std::vector<uint32_t> first;
    std::string note;
  };
  const std::vector<Expected> table = {
      {"beetle_nonmanifold.obj", 4, true, 2, 4, 0, 1, 0x9a76ab00c554459full, {4, 0}, "1 of 1 small components dropped: keeping them all would take more than a fifth of N"},
      {"beetle_nonmanifold.obj", 4, false, 2, 4, 0, 1, 0x9a76ab00c554459full, {4, 0}, ""},
      {"beetle_nonmanifold.obj", 20, true, 2, 20, 0, 1, 0x9aad0b00c582782full, {20, 0}, "1 of 1 small components dropped: keeping them all would take more than a fifth of N"},
      {"beetle_nonmanifold.obj", 20, false, 2, 20, 0, 1, 0x9aad0b00c582782full, {20, 0}, ""},
      {"beetle_nonmanifold.obj", 100, true, 2, 100, 1, 0, 0x9b9ae900c64c8b33ull, {94, 6}, ""},
      {"beetle_nonmanifold.obj", 100, false, 2, 100, 0, 1, 0x9bbceb00c66974ffull, {100, 0}, ""},
      {"beetle_nonmanifold.obj", 1000, true, 2, 1000, 0, 0, 0x8fc02600bc3a37dfull, {995, 5}, ""},
      {"beetle_nonmanifold.obj", 1000, false, 2, 1000, 0, 0, 0x8fc02600bc3a37dfull, {995, 5}, ""},
      {"beetle_nonmanifold.obj", 10000, true, 2, 1148, 0, 0, 0xa9847900d21e7b0bull, {1142, 6}, "the input has only 1148 vertices on faces"},
      {"beetle_nonmanifold.obj", 10000, false, 2, 1148, 0, 0, 0xa9847900d21e7b0bull, {1142, 6}, "the input has only 1148 vertices on faces"},
      {"bun_zipper_res2.ply", 4, true, 1, 4, 0, 0, 0x44bd2fd473ccfe65ull, {4}, ""},
      {"bun_zipper_res2.ply", 4, false, 1, 4, 0, 0, 0x44bd2fd473ccfe65ull, {4}, ""},
      {"bun_zipper_res2.ply", 20, true, 1, 20, 0, 0, 0x44bd3fd473cd1995ull, {20}, ""},
      {"bun_zipper_res2.ply", 20, false, 1, 20, 0, 0, 0x44bd3fd473cd1995ull, {20}, ""},
      {"bun_zipper_res2.ply", 100, true, 1, 100, 0, 0, 0x44bd8fd473cda185ull, {100}, ""},
      {"bun_zipper_res2.ply", 100, false, 1, 100, 0, 0, 0x44bd8fd473cda185ull, {100}, ""},
      {"bun_zipper_res2.ply", 1000, true, 1, 1000, 0, 0, 0x44ba13d473c7b5d1ull, {1000}, ""},
      {"bun_zipper_res2.ply", 1000, false, 1, 1000, 0, 0, 0x44ba13d473c7b5d1ull, {1000}, ""},
      {"bun_zipper_res2.ply", 10000, true, 1, 8146, 0, 0, 0x44d5f9d473f71da3ull, {8146}, "the input has only 8146 vertices on faces"},
      {"bun_zipper_res2.ply", 10000, false, 1, 8146, 0, 0, 0x44d5f9d473f71da3ull, {8146}, "the input has only 8146 vertices on faces"},
      {"cgal_elephant_with_holes.off", 4, true, 1, 4, 0, 0, 0x44bd2fd473ccfe65ull, {4}, ""},
      {"cgal_elephant_with_holes.off", 4, false, 1, 4, 0, 0, 0x44bd2fd473ccfe65ull, {4}, ""},
      {"cgal_elephant_with_holes.off", 20, true, 1, 20, 0, 0, 0x44bd3fd473cd1995ull, {20}, ""},
      {"cgal_elephant_with_holes.off", 20, false, 1, 20, 0, 0, 0x44bd3fd473cd1995ull, {20}, ""},
      {"cgal_elephant_with_holes.off", 100, true, 1, 100, 0, 0, 0x44bd8fd473cda185ull, {100}, ""},
      {"cgal_elephant_with_holes.off", 100, false, 1, 100, 0, 0, 0x44bd8fd473cda185ull, {100}, ""},
      {"cgal_elephant_with_holes.off", 1000, true, 1, 1000, 0, 0, 0x44ba13d473c7b5d1ull, {1000}, ""},
      {"cgal_elephant_with_holes.off", 1000, false, 1, 1000, 0, 0, 0x44ba13d473c7b5d1ull, {1000}, ""},
      {"cgal_elephant_with_holes.off", 10000, true, 1, 2798, 0, 0, 0x44c315d473d70437ull, {2798}, "the input has only 2798 vertices on faces"},
      {"cgal_elephant_with_holes.off", 10000, false, 1, 2798, 0, 0, 0x44c315d473d70437ull, {2798}, "the input has only 2798 vertices on faces"},
      {"specks", 4, true, 67, 0, 0, 67, 0xd29ed9eb04f19381ull, {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}, "67 of 67 small components dropped: keeping them all would take more than a fifth of N"},
      {"specks", 4, false, 67, 0, 0, 67, 0xd29ed9eb04f19381ull, {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}, "components could not take the whole budget"},
      {"specks", 20, true, 67, 20, 1, 64, 0xf059a76b2ad86eadull, {8, 8, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}, "64 of 65 small components dropped: keeping them all would take more than a fifth of N"},
      {"specks", 20, false, 67, 20, 0, 65, 0x79bde3a5d98b13e9ull, {10, 10, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}, ""},
      {"specks", 100, true, 67, 100, 5, 60, 0xd0073a374bb162a9ull, {38, 42, 0, 0, 0, 0, 0, 0, 0, 0, 4, 0}, "60 of 65 small components dropped: keeping them all would take more than a fifth of N"},
      {"specks", 100, false, 67, 100, 0, 65, 0x0b28c43c4f33d1a5ull, {48, 52, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}, ""},
      {"specks", 1000, true, 67, 1000, 37, 28, 0x6adf05e49e01c821ull, {440, 360, 0, 0, 0, 0, 4, 4, 4, 4, 4, 0}, "28 of 65 small components dropped: keeping them all would take more than a fifth of N"},
      {"specks", 1000, false, 67, 1000, 0, 65, 0x02bdc08c963bbf19ull, {640, 360, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0}, ""},
      {"specks", 10000, true, 67, 6558, 24, 0, 0xcbde8d2e1ba11b43ull, {2562, 360, 9, 6, 4, 162, 42, 162, 42, 162, 42, 15}, "the input has only 7260 vertices on faces"},
      {"specks", 10000, false, 67, 6369, 0, 24, 0xfa7b07dec3ffa6c0ull, {2562, 360, 0, 0, 0, 162, 42, 162, 42, 162, 42, 15}, "the input has only 7260 vertices on faces"}
  };
  for (const char* name : {"beetle_nonmanifold.obj", "bun_zipper_res2.ply", "cgal_elephant_with_holes.off", "specks"}) {
    const MeshBuffers soup = std::string(name) == "specks" ? specks() : read_mesh(test::data_path(name));
    for (uint64_t faces_per_chunk : {uint64_t(1) << 20, uint64_t(300)}) {
      const MeshStore store = store_of(soup, faces_per_chunk);
      const MeshView view = store.view();
      const ItemData items = compute_item_data(view);
      const std::vector<uint32_t> reference = reference_components(view);
      if (faces_per_chunk < soup.face_count()) {
        ASSERT_GT(view.chunks.size(), 4u);
      }
      for (const Expected& e : table) {
        if (e.mesh != std::string(name)) continue;
        SCOPED_TRACE(std::string(name) + " N=" + std::to_string(e.n) + (e.keep ? " keep" : " drop") + ", " +
                     std::to_string(view.chunks.size()) + " chunks");
        const ComponentBudget b =
            plan_component_budget(view, items, e.n, e.keep ? SmallComponents::Keep : SmallComponents::Drop, ram_storage());
        EXPECT_EQ(b.clusters_per_component.size(), e.components);
        EXPECT_EQ(b.total_clusters, e.total);
        EXPECT_EQ(b.small_components_kept, e.kept);
        EXPECT_EQ(b.components_dropped, e.dropped);
        EXPECT_EQ(fnv(b.clusters_per_component), e.hash);
        EXPECT_TRUE(std::equal(e.first.begin(), e.first.end(), b.clusters_per_component.begin()));
        EXPECT_EQ(b.note, e.note);
        EXPECT_TRUE(test::to_vector(b.component_of_vertex) == reference) << "components numbered by smallest vertex";
      }
    }
  }
}

// --- sampling by chunks -----------------------------------------------------------------------

TEST(SamplingChunks, ExactTotalsPerComponentWhenComponentsCrossManyChunks) {
  MeshBuffers soup = make_icosphere(5, 1.0f);          // 10242 vertices
  append(soup, moved(make_torus(80, 30), 1.0f, 4, 0, 0));  // 2400
  append(soup, moved(make_grid(40, 25), 2.0f, 0, 4, 0));   // 1000, open
  append(soup, moved(make_icosphere(2), 0.05f, -3, 0, 0));  // a speck: small component
  soup.positions.insert(soup.positions.end(), {9.0f, 9.0f, 9.0f});  // an isolated vertex
  for (uint64_t faces_per_chunk : {uint64_t(1) << 20, uint64_t(2000), uint64_t(150)}) {
    const MeshStore store = store_of(soup, faces_per_chunk);
    const MeshView view = store.view();
    const ItemData items = compute_item_data(view);
    const std::vector<VertexRange> ranges = sampling_ranges(view);
    for (uint32_t n : {7u, 50u, 333u, 2000u, 9000u}) {
      for (SmallComponents mode : {SmallComponents::Keep, SmallComponents::Drop}) {
        SCOPED_TRACE(std::to_string(ranges.size()) + " ranges, N=" + std::to_string(n) +
                     (mode == SmallComponents::Keep ? " keep" : " drop"));
        const ComponentBudget b = plan_component_budget(view, items, n, mode, ram_storage());
        ASSERT_EQ(b.clusters_per_component.size(), 4u);
        for (uint64_t seed : {1ull, 77ull}) {
          const LargeArray<int32_t> labels = initial_sampling(view, items, b, seed, ram_storage());
          expect_valid_sampling(view, b, labels);
        }
      }
    }
  }
}

TEST(SamplingChunks, PartsLighterThanOneClusterAreAbsorbed) {
  // One open grid of 12×12 vertices cut into chunks of 8 faces: each chunk's part weighs far
  // less than one of the 3 clusters, so most parts get none and are absorbed across frontiers.
  const MeshBuffers soup = make_grid(12, 12);
  const MeshStore store = store_of(soup, 8);
  const MeshView view = store.view();
  const ItemData items = compute_item_data(view);
  const std::vector<VertexRange> ranges = sampling_ranges(view);
  ASSERT_GT(ranges.size(), 12u);
  const ComponentBudget b = plan_component_budget(view, items, 3, SmallComponents::Keep, ram_storage());
  ASSERT_EQ(b.total_clusters, 3u);
  for (uint64_t seed = 1; seed <= 20; ++seed) {
    SCOPED_TRACE("seed " + std::to_string(seed));
    const LargeArray<int32_t> labels = initial_sampling(view, items, b, seed, ram_storage());
    expect_valid_sampling(view, b, labels);  // 3 seeds in 12+ parts: most parts got none
  }
}

TEST(SamplingChunks, ClustersStayConnectedWhenPartsRunOutOfFreeVertices) {
  // Nearly one cluster per vertex, over many chunks: regions run out of free vertices and
  // single vertices are taken from clusters, never cutting one; all clusters one vertex when N = V.
  struct Case {
    std::string name;
    MeshBuffers mesh;
    uint32_t clusters;
  };
  std::vector<Case> cases;
  cases.push_back({"grid-all", make_grid(8, 8), 64});
  cases.push_back({"icosphere3-600", make_icosphere(3), 600});  // 642 vertices
  cases.push_back({"torus-900", make_torus(40, 24), 900});      // 960 vertices
  for (const Case& c : cases)
    for (uint64_t faces_per_chunk : {uint64_t(1) << 20, uint64_t(40)}) {
      const MeshStore store = store_of(c.mesh, faces_per_chunk);
      const MeshView view = store.view();
      const ItemData items = compute_item_data(view);
      const ComponentBudget b = plan_component_budget(view, items, c.clusters, SmallComponents::Keep, ram_storage());
      ASSERT_EQ(b.total_clusters, c.clusters);
      for (uint64_t seed : {3ull, 4ull, 5ull}) {
        SCOPED_TRACE(c.name + " " + std::to_string(view.chunks.size()) + " chunks, seed " + std::to_string(seed));
        const LargeArray<int32_t> labels = initial_sampling(view, items, b, seed, ram_storage());
        expect_valid_sampling(view, b, labels);
      }
    }
}

TEST(SamplingChunks, RejectsABudgetOfAnotherMesh) {
  const MeshStore a = store_of(make_icosphere(2), 1u << 20), other = store_of(make_icosphere(3), 1u << 20);
  const ItemData items = compute_item_data(a.view());
  const ComponentBudget b = plan_component_budget(other.view(), compute_item_data(other.view()), 10,
                                                  SmallComponents::Keep, ram_storage());
  EXPECT_THROW(initial_sampling(a.view(), items, b, 1, ram_storage()), std::invalid_argument);
}

// --- determinism ------------------------------------------------------------------------------

TEST(SamplingDeterminism, SameOutputForEveryThreadCountAndStorage) {
  MeshBuffers soup = make_icosphere(5, 1.0f);
  append(soup, moved(make_torus(60, 20), 0.5f, 3, 0, 0));
  append(soup, moved(make_icosphere(1), 0.01f, -3, 0, 0));
  const MeshStore store = store_of(soup, 700);
  const MeshView view = store.view();
  ASSERT_GT(view.chunks.size(), 20u);
  const ItemData items = compute_item_data(view);
  struct Run {
    std::vector<uint32_t> components, clusters;
    std::vector<int32_t> labels, absorbed;
  };
  auto run = [&](ArrayStorage& storage) {
    Run r;
    const ComponentBudget b = plan_component_budget(view, items, 1500, SmallComponents::Keep, storage);
    r.components = test::to_vector(b.component_of_vertex);
    r.clusters = b.clusters_per_component;
    LargeArray<int32_t> labels = initial_sampling(view, items, b, 2024, storage);
    r.labels = test::to_vector(labels);
    // Free a scattered third of the vertices and whole bands (pieces with no label inside their
    // chunk), then absorb them again.
    for (uint32_t v = 0; v < view.vertex_count(); ++v)
      if ((v * 2654435761u) % 3 == 0 || view.positions[3 * v + 2] > 0.6f) labels[v] = -1;
    absorb_free_vertices(view, labels);
    r.absorbed = test::to_vector(labels);
    return r;
  };
  std::vector<Run> runs;
  tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 8);  // 8 threads on any machine
  for (int threads : {1, 2, 8}) {
    tbb::task_arena arena(threads);
    arena.execute([&] { runs.push_back(run(ram_storage())); });
  }
  WorkSpace files(test::temp_dir("sampling-work").string(), 0);  // every array in a work file
  {
    tbb::task_arena arena(2);
    arena.execute([&] { runs.push_back(run(files)); });
  }
  EXPECT_GT(files.peak_file_bytes(), 0u);
  EXPECT_EQ(files.file_bytes(), 0u) << "work files released";
  for (size_t i = 1; i < runs.size(); ++i) {
    SCOPED_TRACE("run " + std::to_string(i));
    EXPECT_TRUE(runs[i].components == runs[0].components);
    EXPECT_TRUE(runs[i].clusters == runs[0].clusters);
    EXPECT_TRUE(runs[i].labels == runs[0].labels);
    EXPECT_TRUE(runs[i].absorbed == runs[0].absorbed);
  }
  for (int32_t l : runs[0].absorbed) EXPECT_GE(l, 0);
}

// --- absorption -------------------------------------------------------------------------------

TEST(SamplingAbsorb, LabelsTravelAcrossManyChunkFrontiers) {
  // A long strip in chunks of 4 faces; labels only at its two ends: every vertex is reached,
  // across dozens of frontiers, and the two regions stay connected.
  const MeshStore store = store_of(make_grid(200, 3, 50.0f, 0.5f), 4);
  const MeshView view = store.view();
  ASSERT_GT(sampling_ranges(view).size(), 50u);
  std::vector<int32_t> labels(view.vertex_count(), -1);
  uint32_t left = 0, right = 0;
  for (uint32_t v = 0; v < view.vertex_count(); ++v) {
    if (view.positions[3 * v] < view.positions[3 * left]) left = v;
    if (view.positions[3 * v] > view.positions[3 * right]) right = v;
  }
  labels[left] = 0;
  labels[right] = 1;
  absorb_free_vertices(view, labels);
  uint32_t counts[2] = {0, 0};
  for (int32_t l : labels) {
    ASSERT_GE(l, 0);
    ++counts[l];
  }
  EXPECT_GT(counts[0], 100u);
  EXPECT_GT(counts[1], 100u);
  EXPECT_TRUE(clusters_connected(view, labels, 2));
}

TEST(SamplingAbsorb, UnreachableAndIsolatedVerticesStayFree) {
  MeshBuffers soup = make_grid(20, 20);
  append(soup, moved(make_grid(5, 5), 1.0f, 3, 0, 0));   // a second component, nothing labelled
  soup.positions.insert(soup.positions.end(), {7.0f, 7.0f, 7.0f});  // isolated
  const MeshStore store = store_of(soup, 16);
  const MeshView view = store.view();
  const std::vector<uint32_t> comp = reference_components(view);
  std::vector<int32_t> labels(view.vertex_count(), -1);
  for (uint32_t v = 0; v < view.vertex_count(); ++v)
    if (comp[v] == 0 && v % 97 == 0) labels[v] = int32_t(v % 5);
  absorb_free_vertices(view, labels);
  for (uint32_t v = 0; v < view.vertex_count(); ++v) {
    if (comp[v] == 0) EXPECT_GE(labels[v], 0) << v;
    else EXPECT_EQ(labels[v], -1) << v;
  }
}

}  // namespace
}  // namespace streamcvd
