// components_touching_others: a sheet cut off at a vertex (its own copy of the vertex, same
// position) is found, a separate piece elsewhere is not.
#include "streamcvd/core/mesh/coincident_components.h"

#include <gtest/gtest.h>

#include <numeric>

#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/core/mesh/chunked_components.h"
#include "streamcvd/streaming/store/store.h"

namespace streamcvd {
namespace {

// Components of a store view by a union-find over its faces.
std::vector<uint32_t> components_of(const MeshView& m, uint32_t& count) {
  std::vector<uint32_t> parent(m.vertex_count());
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (uint64_t f = 0; f < m.face_count(); ++f)
    for (int k = 1; k < 3; ++k) parent[find(m.triangles[3 * f + k])] = find(m.triangles[3 * f]);
  std::vector<uint32_t> id(m.vertex_count(), kNoComponent), out(m.vertex_count());
  count = 0;
  for (uint32_t v = 0; v < m.vertex_count(); ++v) {
    uint32_t& c = id[find(v)];
    if (c == kNoComponent) c = count++;
    out[v] = c;
  }
  return out;
}

TEST(CoincidentComponents, ACutSheetTouchesTheSurfaceAFarPieceDoesNot) {
  MeshBuffers m = make_torus(40, 20);
  const uint32_t base = m.vertex_count();
  const float* p = &m.positions[3 * 7];  // a fin: a triangle on its own copy of torus vertex 7
  m.positions.insert(m.positions.end(), {p[0], p[1], p[2], p[0] + 0.1f, p[1], p[2] + 0.3f, p[0], p[1] + 0.1f, p[2] + 0.3f});
  m.positions.insert(m.positions.end(), {5, 5, 5, 6, 5, 5, 5, 6, 5});  // a piece far away
  m.triangles.insert(m.triangles.end(), {base, base + 1, base + 2, base + 3, base + 4, base + 5});
  StoreBuildOptions options;
  options.clean_topology = false;
  const MeshStore store = MeshStore::build(m.view(), options);
  uint32_t count = 0;
  const std::vector<uint32_t> component = components_of(store.view(), count);
  ASSERT_EQ(count, 3u);
  const std::vector<uint8_t> touches = components_touching_others(store.view(), component, count);
  ASSERT_EQ(touches.size(), 3u);
  EXPECT_EQ(std::count(touches.begin(), touches.end(), uint8_t(1)), 2);  // the torus and the fin
  // The far piece: the component of the vertex at (5, 5, 5).
  for (uint32_t v = 0; v < store.view().vertex_count(); ++v)
    if (store.view().positions[3 * v] == 5 && store.view().positions[3 * v + 1] == 5 && store.view().positions[3 * v + 2] == 5) {
      EXPECT_EQ(touches[component[v]], 0);
    }
}

TEST(CoincidentComponents, NoTouchingWithoutCoincidentVertices) {
  const MeshBuffers m = make_torus(30, 16);
  const MeshStore store = MeshStore::build(m.view());
  uint32_t count = 0;
  const std::vector<uint32_t> component = components_of(store.view(), count);
  const std::vector<uint8_t> touches = components_touching_others(store.view(), component, count);
  EXPECT_EQ(std::count(touches.begin(), touches.end(), uint8_t(1)), 0);
}

}  // namespace
}  // namespace streamcvd
