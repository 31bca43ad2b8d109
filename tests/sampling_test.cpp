// Tests of the chunk-wise component budget (core/sampling.cpp): the budget of the former global
// implementation for any chunking.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "core/clustering.h"
#include "core/item_data.h"
#include "core/shapes.h"
#include "streaming/store.h"
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
  return MeshStore::build(soup.view(), StoreBuildOptions{.faces_per_chunk = faces_per_chunk});
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

}  // namespace
}  // namespace streamcvd
