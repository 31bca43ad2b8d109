// A double layer that is not an exact duplicate (issue 16): two unit cubes sharing their wall,
// each cube's copy of the wall with interior vertices of its own, jittered apart by 2 % of a
// grid step (as ../shared/tools/genbig leaves a subdivided face and its reverse). Along the
// wall's rim each edge has four faces: the two cubes' side faces, which continue each other, and
// the wall's two copies, whose order about the edge is noise. The cleaning must pair the copies
// with each other everywhere (streaming/store/store_clean.cpp, pair_edge): the box stays closed
// and the wall becomes a flat closed piece, which the remesh drops as a double layer
// (core/clustering/component_budget.cpp). Pairing by the noisy order opened holes along the rim.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <map>
#include <tuple>
#include <nlohmann/json.hpp>

#include "streamcvd/core/measure/store_stats.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/store/store.h"
#include "streamcvd/streaming/store/store_build.h"
#include "tests/cli_runner.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

namespace fs = std::filesystem;

// Deterministic value in [-1, 1] from integers.
float jitter(uint32_t a, uint32_t b, uint32_t c) {
  uint32_t h = a * 73856093u ^ b * 19349663u ^ c * 83492791u;
  h ^= h >> 13, h *= 0x5bd1e995u, h ^= h >> 15;
  return float(h & 0xffff) / 32767.5f - 1.0f;
}

// Cubes [0,1]³ and [1,2]×[0,1]², each face a k × k grid of two triangles per quad, oriented
// outward; grid points shared, except the interior points of the wall x = 1, which each cube
// has jittered copies of.
MeshBuffers cubes_sharing_a_jittered_wall(int k) {
  MeshBuffers m;
  std::map<std::tuple<int, int, int, int>, uint32_t> id;  // grid point (and cube, on the wall) → vertex
  auto vertex = [&](int cube, int x, int y, int z) {
    const bool wall = x == k && y > 0 && y < k && z > 0 && z < k;
    const auto key = std::make_tuple(wall ? cube : -1, x, y, z);
    const auto [it, added] = id.try_emplace(key, m.vertex_count());
    if (added) {
      const float amp = wall ? 0.02f / float(k) : 0.0f;
      m.positions.insert(m.positions.end(), {float(x) / float(k) + amp * jitter(cube, y, z),
                                             float(y) / float(k) + amp * jitter(y, z, cube + 7),
                                             float(z) / float(k) + amp * jitter(z, cube + 3, y)});
    }
    return it->second;
  };
  for (int cube = 0; cube < 2; ++cube)
    for (int axis = 0; axis < 3; ++axis)
      for (int side = 0; side < 2; ++side)
        for (int i = 0; i < k; ++i)
          for (int j = 0; j < k; ++j) {
            uint32_t q[4];
            const int corner[4][2] = {{i, j}, {i + 1, j}, {i + 1, j + 1}, {i, j + 1}};
            for (int c = 0; c < 4; ++c) {
              int p[3];
              p[axis] = side * k;
              p[(axis + 1) % 3] = corner[c][0];
              p[(axis + 2) % 3] = corner[c][1];
              q[c] = vertex(cube, p[0] + cube * k, p[1], p[2]);
            }
            // (axis+1, axis+2) is a right-handed pair about axis: counter-clockwise seen from
            // +axis, outward on side 1.
            if (side == 1) m.triangles.insert(m.triangles.end(), {q[0], q[1], q[2], q[0], q[2], q[3]});
            else m.triangles.insert(m.triangles.end(), {q[0], q[2], q[1], q[0], q[3], q[2]});
          }
  return m;
}

TEST(DoubleLayer, JitteredWallCopiesPairWithEachOtherAndTheBoxStaysClosed) {
  const int k = 6;
  const MeshBuffers m = cubes_sharing_a_jittered_wall(k);
  StoreBuildReport r;
  const MeshStore store =
      MeshStore::build_from_stream([&](MeshSink& sink) { stream_soup(m.view(), sink); }, {}, &r);
  ASSERT_TRUE(r.topology_checked);
  // The wall's rim, and the diagonals of two corner triangles whose corners are all on the rim:
  // the same in both copies (a face and its reverse, as genbig's corner sub-faces are), dropped
  // whole by the double-layer rule, which leaves their four rim edges to the side faces alone.
  EXPECT_EQ(r.input_topology.nonmanifold_edges, uint64_t(4 * k + 2));
  EXPECT_EQ(r.input_topology.boundary_loops, 0u);
  EXPECT_EQ(r.cleaning.double_layer_faces_dropped, 4u);
  EXPECT_EQ(r.cleaning.nonmanifold_edges_cut, uint64_t(4 * k - 4));
  EXPECT_EQ(r.cleaning.unpaired_edge_faces, 0u);
  const TopologyStats s = compute_topology_stats(store.view());
  EXPECT_EQ(s.nonmanifold_edges, 0u);
  EXPECT_EQ(s.boundary_loops, 0u);
  EXPECT_TRUE(s.closed_manifold);
  EXPECT_EQ(s.components, 2u);           // the 2 × 1 × 1 box and the wall's two copies
  EXPECT_EQ(s.euler_characteristic, 4);  // two spheres
  EXPECT_EQ(s.faces, m.face_count() - 4);

  if (!test::cli_available()) GTEST_SKIP() << "no CLI";
  const fs::path dir = test::temp_dir("double_layer");
  const std::string in = (dir / "cubes.ply").string();
  write_mesh(in, m.view());
  for (const char* n : {"60", "200"}) {
    SCOPED_TRACE(std::string("N=") + n);
    const std::string out = (dir / "out.ply").string(), report = (dir / "r.json").string();
    const test::CliResult run = test::run_cli({"remesh", in, "-o", out, "-n", n, "--report", report, "-q"});
    ASSERT_EQ(run.exit_code, 0) << run.describe();
    const nlohmann::json j = nlohmann::json::parse(test::slurp(report));
    EXPECT_TRUE(j["checks"]["all_ok"].get<bool>()) << j["checks"].dump();
    // The wall's copies take a sixth of the area, above the resolution: dropped as a double
    // layer, not as a small piece.
    EXPECT_EQ(j["components"]["cut_sheets_dropped"].get<uint32_t>(), 1u) << j["components"].dump();
    EXPECT_EQ(j["output"]["components"].get<uint32_t>(), 1u);
    EXPECT_EQ(j["output"]["boundary_loops"].get<uint32_t>(), 0u);
    EXPECT_EQ(j["output"]["vertices"].get<uint32_t>(), uint32_t(std::stoi(n)));
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace streamcvd
