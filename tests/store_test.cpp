#include "streamcvd/streaming/store/store.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <numeric>
#include <random>
#include <set>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/store/hilbert.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

namespace fs = std::filesystem;

// The same mesh with its vertices listed in a random order (faces follow).
MeshBuffers shuffled(const MeshBuffers& m, uint32_t seed) {
  std::vector<uint32_t> perm(m.vertex_count());
  std::iota(perm.begin(), perm.end(), 0u);
  std::shuffle(perm.begin(), perm.end(), std::mt19937(seed));
  MeshBuffers out;
  out.positions.resize(m.positions.size());
  for (uint32_t v = 0; v < perm.size(); ++v)
    for (int k = 0; k < 3; ++k) out.positions[3 * perm[v] + k] = m.positions[3 * v + k];
  for (uint32_t i : m.triangles) out.triangles.push_back(perm[i]);
  return out;
}

// Reference flags from an edge map (independent of streaming/store/adjacency.cpp); fan checks excluded.
std::vector<uint8_t> reference_edge_flags(const MeshView& m) {
  std::map<std::pair<uint32_t, uint32_t>, int> edges;
  for (uint64_t f = 0; f < m.face_count(); ++f) {
    std::set<std::pair<uint32_t, uint32_t>> face_edges;
    for (int k = 0; k < 3; ++k) {
      uint32_t a = m.triangles[3 * f + k], b = m.triangles[3 * f + (k + 1) % 3];
      if (a != b) face_edges.insert(std::minmax(a, b));
    }
    for (auto& e : face_edges) ++edges[e];
  }
  std::vector<uint8_t> flags(m.vertex_count(), kVertexIsolated);
  for (uint32_t i : m.triangles) flags[i] = 0;
  for (auto& [e, n] : edges) {
    uint8_t bit = n == 1 ? kVertexBoundary : n > 2 ? kVertexNonManifold : 0;
    flags[e.first] |= bit;
    flags[e.second] |= bit;
  }
  return flags;
}

// Every structural invariant of a store built from `soup`.
void expect_valid_store(const MeshStore& store, const TriangleSoupView& soup) {
  const MeshView m = store.view();
  const uint32_t nv = m.vertex_count();
  const uint64_t nf = m.face_count();
  ASSERT_EQ(nv, soup.vertex_count());
  ASSERT_EQ(nf, soup.face_count());
  ASSERT_EQ(store.header().vertex_count, nv);
  ASSERT_EQ(store.header().face_count, nf);
  // original ids: a permutation mapping positions and faces back to the input exactly.
  auto orig = store.original_vertex_ids();
  ASSERT_EQ(orig.size(), nv);
  std::vector<uint8_t> seen(nv, 0);
  for (uint32_t v = 0; v < nv; ++v) {
    ASSERT_LT(orig[v], nv);
    ASSERT_FALSE(seen[orig[v]]);
    seen[orig[v]] = 1;
    ASSERT_EQ(std::memcmp(&m.positions[3 * v], &soup.positions[3 * size_t(orig[v])], 12), 0);
  }
  std::vector<std::array<uint32_t, 3>> back, in;
  for (uint64_t f = 0; f < nf; ++f) {
    back.push_back({orig[m.triangles[3 * f]], orig[m.triangles[3 * f + 1]], orig[m.triangles[3 * f + 2]]});
    in.push_back({soup.triangles[3 * f], soup.triangles[3 * f + 1], soup.triangles[3 * f + 2]});
  }
  std::sort(back.begin(), back.end());
  std::sort(in.begin(), in.end());
  ASSERT_EQ(back, in) << "faces (with orientation) differ from the input";
  // faces sorted by owner = smallest vertex.
  uint32_t prev_owner = 0;
  for (uint64_t f = 0; f < nf; ++f) {
    uint32_t owner = std::min({m.triangles[3 * f], m.triangles[3 * f + 1], m.triangles[3 * f + 2]});
    ASSERT_GE(owner, prev_owner) << "face " << f;
    prev_owner = owner;
  }
  // vertex→face: ascending, consistent with triangles, one entry per corner.
  ASSERT_EQ(m.vertex_face_offsets.size(), nv + 1u);
  ASSERT_EQ(m.vertex_face.size(), 3 * nf);
  std::vector<uint32_t> corners_seen(nf, 0);
  for (uint32_t v = 0; v < nv; ++v) {
    auto fs_ = m.faces_of(v);
    ASSERT_TRUE(std::is_sorted(fs_.begin(), fs_.end()));
    for (uint32_t f : fs_) {
      const uint32_t* t = &m.triangles[3 * size_t(f)];
      ASSERT_TRUE(t[0] == v || t[1] == v || t[2] == v) << "vertex " << v << " face " << f;
      ++corners_seen[f];
    }
  }
  for (uint64_t f = 0; f < nf; ++f) ASSERT_EQ(corners_seen[f], 3u);
  // vertex→vertex: sorted, unique, symmetric, exactly the vertices sharing a face.
  ASSERT_EQ(m.vertex_vertex_offsets.size(), nv + 1u);
  for (uint32_t v = 0; v < nv; ++v) {
    auto nb = m.neighbours(v);
    ASSERT_TRUE(std::adjacent_find(nb.begin(), nb.end(), std::greater_equal<uint32_t>()) == nb.end()) << v;
    std::set<uint32_t> expect;
    for (uint32_t f : m.faces_of(v))
      for (int k = 0; k < 3; ++k)
        if (m.triangles[3 * size_t(f) + k] != v) expect.insert(m.triangles[3 * size_t(f) + k]);
    ASSERT_EQ(std::vector<uint32_t>(nb.begin(), nb.end()), std::vector<uint32_t>(expect.begin(), expect.end())) << v;
    for (uint32_t u : nb) {
      auto back_nb = m.neighbours(u);
      ASSERT_TRUE(std::binary_search(back_nb.begin(), back_nb.end(), v)) << v << "-" << u;
    }
  }
  // flags: boundary/isolated exactly; non-manifold at least on non-manifold edges.
  auto ref = reference_edge_flags(m);
  for (uint32_t v = 0; v < nv; ++v) {
    ASSERT_EQ(m.vertex_flags[v] & (kVertexBoundary | kVertexIsolated), ref[v] & (kVertexBoundary | kVertexIsolated))
        << v;
    if (ref[v] & kVertexNonManifold) {
      ASSERT_TRUE(m.vertex_flags[v] & kVertexNonManifold) << v;
    }
  }
  // chunks: contiguous cover, face ranges = owned faces, bbox holds the vertices.
  ASSERT_EQ(m.chunks.size(), store.header().chunk_count);
  ASSERT_FALSE(m.chunks.empty());
  uint32_t v_next = 0;
  uint64_t f_next = 0;
  for (const Chunk& c : m.chunks) {
    ASSERT_EQ(c.vertex_begin, v_next);
    ASSERT_LT(c.vertex_begin, c.vertex_end);
    ASSERT_EQ(c.face_begin, f_next);
    for (uint64_t f = c.face_begin; f < c.face_end; ++f) {
      uint32_t owner = std::min({m.triangles[3 * f], m.triangles[3 * f + 1], m.triangles[3 * f + 2]});
      ASSERT_TRUE(owner >= c.vertex_begin && owner < c.vertex_end);
    }
    for (uint32_t v = c.vertex_begin; v < c.vertex_end; ++v)
      for (int k = 0; k < 3; ++k) {
        ASSERT_GE(m.positions[3 * v + k], c.bbox_min[k]);
        ASSERT_LE(m.positions[3 * v + k], c.bbox_max[k]);
      }
    v_next = c.vertex_end;
    f_next = c.face_end;
  }
  ASSERT_EQ(v_next, nv);
  ASSERT_EQ(f_next, nf);
}

// Brute-force halo counts of chunk c: faces not owned by c touching a vertex within `rings`-1
// edges of it (BFS from all chunk vertices at once).
uint64_t brute_halo(const MeshView& m, const Chunk& c, int rings) {
  std::vector<int> dist(m.vertex_count(), -1);
  std::vector<uint32_t> frontier;
  for (uint32_t v = c.vertex_begin; v < c.vertex_end; ++v) dist[v] = 0, frontier.push_back(v);
  for (int d = 1; d < rings; ++d) {
    std::vector<uint32_t> next;
    for (uint32_t v : frontier)
      for (uint32_t u : m.neighbours(v))
        if (dist[u] < 0) dist[u] = d, next.push_back(u);
    frontier = std::move(next);
  }
  uint64_t count = 0;
  for (uint64_t f = 0; f < m.face_count(); ++f) {
    if (f >= c.face_begin && f < c.face_end) continue;
    bool near = false;
    for (int k = 0; k < 3; ++k) near |= dist[m.triangles[3 * f + k]] >= 0;
    count += near;
  }
  return count;
}

TEST(Store, ProceduralMeshesAreValid) {
  for (const MeshBuffers& mesh :
       {make_icosphere(3), make_torus(40, 30), make_grid(30, 20), shuffled(make_torus(25, 16), 5)}) {
    MeshStore store = MeshStore::build(mesh.view());
    expect_valid_store(store, mesh.view());
    EXPECT_EQ(store.view().chunks.size(), 1u);
  }
}

TEST(Store, BundledMeshesAreValid) {
  for (const char* name : {"bun_zipper_res2.ply", "beetle_nonmanifold.obj", "cgal_elephant_with_holes.off",
                           "cgal_hand.off", "fertility.off.zst"}) {
    SCOPED_TRACE(name);
    MeshBuffers mesh = read_mesh(test::data_path(name));
    MeshStore store = MeshStore::build(mesh.view(), {.faces_per_chunk = 500, .clean_topology = false});
    expect_valid_store(store, mesh.view());
  }
}

TEST(Store, FlagsOfClosedMeshesAndGrid) {
  for (const MeshBuffers& mesh : {make_icosphere(3), make_torus(20, 10)}) {
    MeshStore store = MeshStore::build(mesh.view());
    for (uint8_t f : store.view().vertex_flags) ASSERT_EQ(f, 0);
  }
  const int nx = 17, ny = 9;
  MeshBuffers grid = make_grid(nx, ny);
  MeshStore store = MeshStore::build(grid.view());
  const MeshView m = store.view();
  auto orig = store.original_vertex_ids();
  int border = 0;
  for (uint32_t v = 0; v < m.vertex_count(); ++v) {
    const int i = int(orig[v]) % nx, j = int(orig[v]) / nx;
    const bool on_border = i == 0 || j == 0 || i == nx - 1 || j == ny - 1;
    border += on_border;
    EXPECT_EQ(m.vertex_flags[v], on_border ? kVertexBoundary : 0) << i << "," << j;
  }
  EXPECT_EQ(border, 2 * (nx + ny) - 4);
}

TEST(Store, FlagsOfNonManifoldConfigurations) {
  // Bowtie (0: shared tip), fin on edge {5,6} (three faces), vertex 10 unreferenced.
  MeshBuffers m;
  m.positions = {0, 0, 0, 1, 1, 0, -1,   1, 0, 1,    -1, 0, -1,   -1, 0,  // bowtie
                 5, 0, 0, 6, 0, 0, 5.5f, 1, 0, 5.5f, -1, 0, 5.5f, 0,  1,  // fin
                 9, 9, 9};
  m.triangles = {0, 1, 2, 0, 3, 4, 5, 6, 7, 6, 5, 8, 5, 6, 9};
  MeshStore store = MeshStore::build(m.view(), {.clean_topology = false});  // the flags of the input as read
  expect_valid_store(store, m.view());
  const MeshView view = store.view();
  auto orig = store.original_vertex_ids();
  for (uint32_t v = 0; v < view.vertex_count(); ++v) {
    const uint32_t o = orig[v];
    const uint8_t expect = o == 10                      ? kVertexIsolated
                           : o == 0 || o == 5 || o == 6 ? kVertexBoundary | kVertexNonManifold
                                                        : kVertexBoundary;
    EXPECT_EQ(view.vertex_flags[v], expect) << "input vertex " << o;
  }
}

// Brute-force neighbour chunks of chunk c: chunks owning a face that touches c's vertices, and
// chunks whose vertices touch a face c owns.
std::vector<uint32_t> brute_neighbours(const MeshView& m, uint32_t c) {
  auto chunk_of_vertex = [&](uint32_t v) {
    for (uint32_t i = 0; i < m.chunks.size(); ++i)
      if (v >= m.chunks[i].vertex_begin && v < m.chunks[i].vertex_end) return i;
    return UINT32_MAX;
  };
  auto chunk_of_face = [&](uint64_t f) {
    for (uint32_t i = 0; i < m.chunks.size(); ++i)
      if (f >= m.chunks[i].face_begin && f < m.chunks[i].face_end) return i;
    return UINT32_MAX;
  };
  std::set<uint32_t> out;
  for (uint64_t f = 0; f < m.face_count(); ++f) {
    const uint32_t owner = chunk_of_face(f);
    for (int k = 0; k < 3; ++k) {
      const uint32_t d = chunk_of_vertex(m.triangles[3 * f + k]);
      if (owner == c && d != c) out.insert(d);
      if (d == c && owner != c) out.insert(owner);
    }
  }
  return {out.begin(), out.end()};
}

TEST(Store, ChunksHoldAboutFacesPerChunkAndCorrectHalos) {
  MeshBuffers torus = shuffled(make_torus(100, 50), 1);  // 10,000 faces
  // Small vertex ranges too, so that chunks span ranges and ranges cut chunks.
  for (uint32_t range : {1u << 22, 4096u}) {
    MeshStore store = MeshStore::build(torus.view(), {.faces_per_chunk = 100, .max_range_vertices = range});
    expect_valid_store(store, torus.view());
    const MeshView m = store.view();
    ASSERT_EQ(m.chunks.size(), 100u);
    uint64_t halo = 0;
    for (uint32_t i = 0; i < m.chunks.size(); ++i) {
      const Chunk& c = m.chunks[i];
      const uint64_t faces = c.face_end - c.face_begin;
      EXPECT_GE(faces, 75u);
      EXPECT_LE(faces, 125u);
      ASSERT_EQ(c.halo_faces, brute_halo(m, c, 1));
      const auto neighbours = m.chunk_neighbours.subspan(c.neighbour_begin, c.neighbour_count);
      ASSERT_EQ(std::vector<uint32_t>(neighbours.begin(), neighbours.end()), brute_neighbours(m, i)) << "chunk " << i;
      EXPECT_GT(c.neighbour_count, 0u);
      halo += c.halo_faces;
    }
    // Hilbert chunks are compact: even at 100 faces a chunk's 1-ring halo stays a fraction of it.
    EXPECT_LT(halo, torus.face_count());
  }
}

TEST(Store, HilbertOrderIsLocal) {
  MeshBuffers sphere = shuffled(make_icosphere(6), 42);  // 40,962 vertices in random order
  auto mean_spread = [](const MeshView& m) {
    double sum = 0;
    for (uint32_t v = 0; v < m.vertex_count(); ++v)
      for (uint32_t u : m.neighbours(v)) sum += std::abs(double(u) - double(v));
    return sum / double(m.vertex_vertex.size());
  };
  MeshStore random_order = MeshStore::build(sphere.view(), {.hilbert_order = false});
  MeshStore hilbert = MeshStore::build(sphere.view());
  for (uint32_t v = 0; v < random_order.view().vertex_count(); ++v) ASSERT_EQ(random_order.original_vertex_ids()[v], v);
  const double random_spread = mean_spread(random_order.view()), hilbert_spread = mean_spread(hilbert.view());
  EXPECT_GT(random_spread, sphere.vertex_count() / 4.0);  // ~V/3 for a random order
  EXPECT_LT(hilbert_spread, 0.05 * random_spread);
}

// The vertex order is exactly (Hilbert key, input id), also with many vertices in one cell
// (duplicates: ties broken by id) and crowded buckets, on enough vertices for parallel sorts.
TEST(Store, HilbertOrderIsSortedByKeyThenInputId) {
  MeshBuffers mesh = shuffled(make_icosphere(7), 5);  // 163,842 vertices
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> near(0.5f, 0.5001f);
  for (int i = 0; i < 100; ++i) mesh.positions.insert(mesh.positions.end(), {0.25f, -0.5f, 0.125f});
  for (int i = 0; i < 300; ++i) mesh.positions.insert(mesh.positions.end(), {near(rng), near(rng), 0.5f});
  MeshStore store = MeshStore::build(mesh.view());
  const StoreHeader& h = store.header();
  const HilbertGrid grid = make_hilbert_grid(h.bbox_min, h.bbox_max);
  std::vector<std::pair<uint64_t, uint32_t>> expected(mesh.vertex_count());
  for (uint32_t v = 0; v < mesh.vertex_count(); ++v) expected[v] = {hilbert_key(grid, &mesh.positions[3 * v]), v};
  std::sort(expected.begin(), expected.end());
  const auto ids = store.original_vertex_ids();
  ASSERT_EQ(ids.size(), expected.size());
  for (size_t i = 0; i < ids.size(); ++i) ASSERT_EQ(ids[i], expected[i].second) << i;
}

TEST(Store, WriteOpenRoundTripIsByteIdentical) {
  MeshBuffers mesh = shuffled(make_torus(60, 40), 3);
  mesh.positions.insert(mesh.positions.end(), {7, 7, 7});  // an isolated vertex too
  MeshStore built = MeshStore::build(mesh.view(), {.faces_per_chunk = 700});
  const fs::path dir = test::temp_dir("store_roundtrip") / "store";
  built.write(dir.string());
  EXPECT_TRUE(is_store_directory(dir.string()));
  uint64_t on_disk = 0;
  for (const auto& e : fs::directory_iterator(dir)) on_disk += e.file_size();
  EXPECT_EQ(on_disk, built.size_bytes());
  MeshStore opened = MeshStore::open(dir.string());
  test::expect_same_arrays(built, opened);
  EXPECT_EQ(opened.size_bytes(), built.size_bytes());
  expect_valid_store(opened, mesh.view());
  MeshStore loaded = load_mesh_or_store(dir.string());
  test::expect_same_arrays(built, loaded);
  // Moving keeps the mapping alive.
  MeshStore moved = std::move(opened);
  test::expect_same_arrays(built, moved);
  // Writing another mesh over it replaces the store completely.
  MeshBuffers small = make_icosphere(1);
  MeshStore other = MeshStore::build(small.view());
  other.write(dir.string());
  test::expect_same_arrays(other, MeshStore::open(dir.string()));
  fs::remove_all(dir.parent_path());
}

// One builder: a store ingested from a file to disk, under a memory limit that forces key
// buckets, vertex ranges and spilled blocks, has the bytes of the store built in RAM.
TEST(Store, IngestToDiskEqualsBuildInRamAtAnyMemoryLimit) {
  MeshBuffers mesh = shuffled(make_icosphere(8), 4);  // 655,362 vertices, 1,310,720 faces
  const StoreBuildOptions options{.faces_per_chunk = 20000};
  MeshStore built = MeshStore::build(mesh.view(), options);
  const fs::path root = test::temp_dir("store_ingest");
  const fs::path ply = root / "mesh.ply";
  write_mesh(ply.string(), mesh.view());
  for (uint64_t limit : {uint64_t(0), uint64_t(48) << 20}) {
    SCOPED_TRACE(limit);
    const fs::path dir = root / ("store" + std::to_string(limit));
    StoreBuildOptions o = options;
    o.memory_limit = limit;
    StoreBuildReport report;
    MeshStore ingested = MeshStore::ingest(ply.string(), dir.string(), o, {}, &report);
    test::expect_same_arrays(built, ingested);
    if (limit > 0) {  // the limit did force the external-memory paths
      EXPECT_GT(report.key_buckets, 1u);
      EXPECT_GT(report.vertex_ranges, 1u);
      EXPECT_GT(report.spilled_bytes, 0u);
    }
    uint64_t on_disk = 0, temporaries = 0;
    for (const auto& e : fs::directory_iterator(dir)) {
      on_disk += e.file_size();
      temporaries += e.path().filename().string().find(".tmp.") != std::string::npos;
    }
    EXPECT_EQ(on_disk, built.size_bytes() + 0);  // attributes.txt is empty
    EXPECT_EQ(temporaries, 0u);
  }
  // A temporary store of a file: in RAM without a limit, in anonymous mapped work files under
  // one (its ~70 MB do not fit half of 48 MiB); the same bytes, and nothing left in the folder.
  const fs::path work = root / "work";
  fs::create_directories(work);
  for (uint64_t limit : {uint64_t(0), uint64_t(48) << 20}) {
    StoreBuildOptions o = options;
    o.memory_limit = limit;
    o.work_directory = work.string();
    test::expect_same_arrays(built, MeshStore::build_from_file(ply.string(), o));
    EXPECT_TRUE(fs::is_empty(work));
  }
  // An unwritable destination fails with OutputError and leaves no store.
  const fs::path file = root / "plain_file";
  std::ofstream(file) << "x";
  EXPECT_THROW(MeshStore::ingest(ply.string(), (file / "store").string()), OutputError);
  // A limit below the minimum is refused up front, naming the minimum.
  try {
    MeshStore::ingest(ply.string(), (root / "tiny").string(), {.memory_limit = uint64_t(8) << 20});
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("at least"), std::string::npos) << e.what();
  }
  fs::remove_all(root);
}

TEST(Store, LoadMeshOrStoreReadsFiles) {
  const std::string path = test::data_path("cgal_hand.off");
  EXPECT_FALSE(is_store_directory(path));
  EXPECT_FALSE(is_store_directory(test::data_path("")));
  EXPECT_FALSE(is_store_directory("/nonexistent/dir"));
  MeshStore store = load_mesh_or_store(path);
  MeshBuffers mesh = read_mesh(path);
  test::expect_same_arrays(store, MeshStore::build(mesh.view()));
}

TEST(Store, DeterministicAcrossRunsAndThreadCounts) {
  // 163,842 vertices and 327,680 faces: big enough for the multi-range counting sorts.
  MeshBuffers mesh = shuffled(make_icosphere(7), 9);
  MeshStore a = MeshStore::build(mesh.view(), {.faces_per_chunk = 1000});
  MeshStore b = MeshStore::build(mesh.view(), {.faces_per_chunk = 1000});
  test::expect_same_arrays(a, b);
  {
    tbb::global_control one(tbb::global_control::max_allowed_parallelism, 1);
    MeshStore serial = MeshStore::build(mesh.view(), {.faces_per_chunk = 1000});
    test::expect_same_arrays(a, serial);
  }
  {
    tbb::global_control many(tbb::global_control::max_allowed_parallelism, 8);
    MeshStore parallel = MeshStore::build(mesh.view(), {.faces_per_chunk = 1000});
    test::expect_same_arrays(a, parallel);
  }
}

TEST(Store, EmptyFacesAndBadSoups) {
  MeshBuffers points;
  points.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  MeshStore store = MeshStore::build(points.view());
  ASSERT_EQ(store.view().chunks.size(), 1u);
  for (uint8_t f : store.view().vertex_flags) EXPECT_EQ(f, kVertexIsolated);
  const fs::path dir = test::temp_dir("store_points");
  store.write(dir.string());
  test::expect_same_arrays(store, MeshStore::open(dir.string()));
  fs::remove_all(dir);

  MeshBuffers bad = make_icosphere(1);
  bad.triangles[7] = bad.vertex_count();
  EXPECT_THROW(MeshStore::build(bad.view()), InputError);
  MeshBuffers ok = make_icosphere(1);
  EXPECT_THROW(MeshStore::build(ok.view(), {.faces_per_chunk = 0}), InputError);
}

// Writes a store, lets `damage` edit one file, expects open() to throw naming that file.
void expect_corrupt(const std::string& file, const std::function<void(const fs::path&)>& damage,
                    const std::string& expected_message_part) {
  SCOPED_TRACE(file);
  MeshBuffers mesh = make_torus(30, 20);
  MeshStore store = MeshStore::build(mesh.view(), {.faces_per_chunk = 300});
  const fs::path dir = test::temp_dir("store_corrupt");
  store.write(dir.string());
  damage(dir / file);
  try {
    MeshStore opened = MeshStore::open(dir.string());
    opened.validate_all();  // the arrays are checked chunk by chunk, on first use
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find((dir / file).string()), std::string::npos) << what;
    EXPECT_NE(what.find(expected_message_part), std::string::npos) << what;
  }
  fs::remove_all(dir);
}

void patch(const fs::path& path, uint64_t offset, const void* bytes, size_t n) {
  std::fstream f(path, std::ios::in | std::ios::out | std::ios::binary);
  f.seekp(std::streamoff(offset));
  f.write(static_cast<const char*>(bytes), std::streamsize(n));
}

TEST(Store, CorruptStoresThrowInputError) {
  expect_corrupt(
      "triangles.u32", [](const fs::path& p) { fs::resize_file(p, fs::file_size(p) - 4); }, "size");
  expect_corrupt(
      "header.bin", [](const fs::path& p) { patch(p, 0, "XXXX", 4); }, "magic");
  expect_corrupt(
      "header.bin",
      [](const fs::path& p) {
        uint32_t v = 99;
        patch(p, 8, &v, 4);
      },
      "version");
  expect_corrupt(
      "header.bin", [](const fs::path& p) { fs::resize_file(p, 50); }, "size");
  expect_corrupt(
      "triangles.u32",
      [](const fs::path& p) {
        uint32_t v = 600;
        patch(p, 40, &v, 4);
      },
      "vertex 600 of 600");
  expect_corrupt(
      "vv.u32",
      [](const fs::path& p) {
        uint32_t v = 1u << 31;
        patch(p, 4, &v, 4);
      },
      "entry 1");
  expect_corrupt(
      "vf.u32",
      [](const fs::path& p) {
        uint32_t v = 1200;
        patch(p, 8, &v, 4);
      },
      "face 1200 of 1200");
  expect_corrupt(
      "vf_offsets.u64",
      [](const fs::path& p) {
        uint64_t v = 1u << 20;
        patch(p, 80, &v, 8);
      },
      "decrease");
  expect_corrupt(
      "vv_offsets.u64",
      [](const fs::path& p) {
        uint64_t v = 3;
        patch(p, 0, &v, 8);
      },
      "offset 0");
  expect_corrupt(
      "chunks.bin",
      [](const fs::path& p) {
        uint32_t v = 5;
        patch(p, 64, &v, 4);
      },
      "chunk 1");
  expect_corrupt(
      "original_ids.u32",
      [](const fs::path& p) {
        uint32_t v = 12345;
        patch(p, 12, &v, 4);
      },
      "entry 3");
  expect_corrupt(
      "flags.u8", [](const fs::path& p) { fs::remove(p); }, "cannot open");
  expect_corrupt(
      "header.bin", [](const fs::path& p) { fs::remove(p); }, "cannot open");
}

}  // namespace
}  // namespace streamcvd
