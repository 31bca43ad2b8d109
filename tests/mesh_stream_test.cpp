// read_mesh_stream and its collectors: the MeshSink contract (block sizes, callback order,
// header) in every format and block size, STL corners sent by value and merged by read_mesh as
// before, OBJ vertex colours, standard input (in process and through the CLI), progress, and
// memory bounded by the block whatever the file size.
#include <gtest/gtest.h>
#include <malloc.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <cstring>
#include <fstream>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/shapes.h"
#include "fuzz/fuzz_common.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/io/mesh_reader.h"
#include "tests/cli_runner.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

namespace fs = std::filesystem;
using fuzz::RecordingSink;

std::string read_bytes(const fs::path& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

void write_bytes(const fs::path& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
}

std::string error_of(const auto& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

RecordingSink stream(const std::string& path, uint32_t block, ReadOptions options = {}) {
  options.block = block;
  RecordingSink sink(block);
  read_mesh_stream(path, sink, options);
  EXPECT_EQ(sink.violation, "") << path << " block " << block;
  EXPECT_EQ(sink.ends, 1);
  return sink;
}

// ---- blocks -----------------------------------------------------------------------------

TEST(MeshStream, BlocksNeverExceedTheBlockSizeInAnyFormat) {
  const fs::path dir = test::temp_dir("stream_blocks");
  const MeshBuffers hand = read_mesh(test::data_path("cgal_hand.off"));  // 1197 V, 2390 F
  WriteOptions ascii;
  ascii.ascii = true;
  const std::vector<std::pair<std::string, WriteOptions>> files = {
      {"m.ply", {}}, {"a.ply", ascii}, {"m.obj", {}}, {"m.off", {}}, {"m.stl", {}}, {"z.ply.zst", {}}};
  for (const auto& [name, options] : files) {
    const std::string path = (dir / name).string();
    write_mesh(path, hand.view(), options);
    const MeshBuffers whole = read_mesh(path);
    for (uint32_t block : {1u, 7u, 1000u, 1u << 16}) {
      SCOPED_TRACE(name + " block " + std::to_string(block));
      const RecordingSink s = stream(path, block);
      // Full blocks except where an element ends (PLY/OFF: 2 ends) or vertices go out first.
      for (size_t n : s.vertex_blocks) EXPECT_LE(n, block);
      for (size_t n : s.triangle_blocks) EXPECT_LE(n, block);
      if (!s.header.corners_by_value) {
        EXPECT_EQ(s.xyz, whole.positions);
        EXPECT_EQ(s.corners, whole.triangles);
        EXPECT_EQ(s.vertex_blocks.size(), (whole.vertex_count() + block - 1) / block);
        EXPECT_EQ(s.triangle_blocks.size(), (whole.face_count() + block - 1) / block);
      } else {
        EXPECT_EQ(s.stats.vertices, 3 * whole.face_count());
      }
      EXPECT_EQ(s.stats.triangles, whole.face_count());
      EXPECT_EQ(s.stats.polygons_split, 0u);
      EXPECT_EQ(s.header.vertices_before_triangles, name.find(".ply") != std::string::npos || name == "m.off");
    }
  }
  fs::remove_all(dir);
}

TEST(MeshStream, HeaderAnnouncesCountsFormatAndInput) {
  const fs::path dir = test::temp_dir("stream_header");
  const MeshBuffers hand = read_mesh(test::data_path("cgal_hand.off"));
  for (const std::string name : {"m.ply", "m.off", "m.obj", "m.stl", "m.ply.zst"}) {
    SCOPED_TRACE(name);
    const std::string path = (dir / name).string();
    write_mesh(path, hand.view());
    const RecordingSink s = stream(path, 4096);
    const bool counted = name != "m.obj" && name != "m.stl";
    EXPECT_EQ(s.header.vertices, counted ? hand.vertex_count() : MeshHeaderInfo::kUnknown);
    EXPECT_EQ(s.header.faces, name == "m.obj" ? MeshHeaderInfo::kUnknown : hand.face_count());
    EXPECT_EQ(s.header.input_bytes, fs::file_size(path));
    EXPECT_EQ(s.header.compressed, name.ends_with(".zst"));
    EXPECT_EQ(s.header.corners_by_value, name == "m.stl");
    EXPECT_TRUE(s.header.attributes.empty());
    EXPECT_EQ(s.header.format, format_from_path(path));
    EXPECT_GT(s.stats.bytes, 0u);
  }
  fs::remove_all(dir);
}

TEST(MeshStream, ProgressIsReportedBetweenBlocksUpToTheFileSize) {
  const fs::path dir = test::temp_dir("stream_progress");
  const std::string path = (dir / "t.ply").string();
  write_mesh(path, make_torus(100, 100).view());
  ReadOptions options;
  std::vector<uint64_t> seen;
  options.progress = [&](uint64_t bytes, uint64_t total) {
    EXPECT_EQ(total, fs::file_size(path));
    EXPECT_LE(bytes, total);
    seen.push_back(bytes);
  };
  stream(path, 1000, options);
  EXPECT_EQ(seen.size(), 10u + 20u);  // 10,000 vertices and 20,000 triangles in blocks of 1000
  EXPECT_TRUE(std::is_sorted(seen.begin(), seen.end()));
  fs::remove_all(dir);
}

TEST(MeshStream, ZeroBlockIsRefused) {
  RecordingSink sink(1);
  ReadOptions options;
  options.block = 0;
  EXPECT_NE(error_of([&] { read_mesh_stream(test::data_path("cgal_hand.off"), sink, options); }).find("block"),
            std::string::npos);
}

TEST(MeshStream, MemoryIsBoundedByTheBlockNotTheFile) {
  // A 38 MB binary PLY streamed into a sink that keeps nothing: the heap in use never grows by
  // more than the input buffer (4 MiB) and the blocks, whatever the file size.
  const fs::path dir = test::temp_dir("stream_memory");
  const std::string path = (dir / "big.ply").string();
  write_mesh(path, make_torus(1000, 1000).view());
  ASSERT_GT(fs::file_size(path), size_t(30) << 20);
  struct HeapWatch final : MeshSink {
    size_t base = 0, peak = 0;
    static size_t in_use() {
      const struct mallinfo2 m = mallinfo2();
      return m.uordblks + m.hblkhd;
    }
    void note() { peak = std::max(peak, in_use()); }
    void begin(const MeshHeaderInfo&) override { note(); }
    void vertices(std::span<const float>, std::span<const float>) override { note(); }
    void triangles(std::span<const uint32_t>) override { note(); }
    void end(const ReadStats&) override { note(); }
  } watch;
  watch.base = HeapWatch::in_use();
  read_mesh_stream(path, watch);
  EXPECT_LT(watch.peak - std::min(watch.peak, watch.base), size_t(12) << 20);
  fs::remove_all(dir);
}

// ---- STL: corners by value, merged by read_mesh -------------------------------------------

/// What read_mesh has always given for an STL of `mesh`: vertices in order of first appearance
/// in the triangle list (the bundled meshes have no two vertices at the same place).
MeshBuffers first_appearance_order(const MeshBuffers& mesh) {
  MeshBuffers out;
  std::vector<uint32_t> id(mesh.vertex_count(), ~0u);
  for (uint32_t v : mesh.triangles) {
    if (id[v] == ~0u) {
      id[v] = out.vertex_count();
      out.positions.insert(out.positions.end(), &mesh.positions[3 * size_t(v)], &mesh.positions[3 * size_t(v) + 3]);
    }
    out.triangles.push_back(id[v]);
  }
  return out;
}

std::string ascii_stl(const MeshBuffers& m) {
  std::string s = "solid hand\n";
  auto num = [&](float x) {
    char buf[32];
    s.append(buf, std::to_chars(buf, buf + 32, x).ptr);  // shortest round trip: exact floats
  };
  for (size_t f = 0; f < m.face_count(); ++f) {
    s += "facet normal 0 0 1\nouter loop\n";
    for (int k = 0; k < 3; ++k) {
      s += "vertex ";
      for (int c = 0; c < 3; ++c) num(m.positions[3 * size_t(m.triangles[3 * f + k]) + c]), s += ' ';
      s += '\n';
    }
    s += "endloop\nendfacet\n";
  }
  return s + "endsolid hand\n";
}

TEST(MeshStream, StlCornersComeByValueAndReadMeshMergesThemAsBefore) {
  const fs::path dir = test::temp_dir("stream_stl");
  const MeshBuffers hand = read_mesh(test::data_path("cgal_hand.off"));
  const MeshBuffers expected = first_appearance_order(hand);
  write_mesh((dir / "b.stl").string(), hand.view());
  write_bytes(dir / "a.stl", ascii_stl(hand));
  for (const std::string name : {"b.stl", "a.stl"}) {
    SCOPED_TRACE(name);
    const std::string path = (dir / name).string();
    const RecordingSink s = stream(path, 100);
    ASSERT_TRUE(s.header.corners_by_value);
    ASSERT_EQ(s.xyz.size(), 9 * hand.face_count());
    for (size_t i = 0; i < s.corners.size(); ++i) ASSERT_EQ(s.corners[i], i);
    for (size_t i = 0; i < hand.triangles.size(); ++i)
      for (int c = 0; c < 3; ++c) ASSERT_EQ(s.xyz[3 * i + c], hand.positions[3 * size_t(hand.triangles[i]) + c]);
    const MeshBuffers m = read_mesh(path);
    EXPECT_EQ(m.positions, expected.positions);
    EXPECT_EQ(m.triangles, expected.triangles);
  }
  fs::remove_all(dir);
}

TEST(MeshStream, StlNegativeZeroIsFoldedAndPolygonFacetsFanByValue) {
  const fs::path dir = test::temp_dir("stream_stl_zero");
  const std::string stl =
      "solid q\nfacet normal 0 0 1\nouter loop\nvertex -0 0 0\nvertex 1 0 0\nvertex 1 1 -0.0\nvertex 0 1 0\n"
      "endloop\nendfacet\nendsolid q\n";
  write_bytes(dir / "q.stl", stl);
  const RecordingSink s = stream((dir / "q.stl").string(), 2);
  ASSERT_EQ(s.xyz.size(), 18u);  // two fan triangles, three corners each
  for (float x : s.xyz) EXPECT_FALSE(std::signbit(x));
  EXPECT_EQ(s.stats.polygons_split, 1u);
  const MeshBuffers m = read_mesh((dir / "q.stl").string());
  EXPECT_EQ(m.vertex_count(), 4u);
  EXPECT_EQ(m.triangles, (std::vector<uint32_t>{0, 1, 2, 0, 2, 3}));
  EXPECT_EQ(m.polygons_split, 1u);
  fs::remove_all(dir);
}

// ---- OBJ colours ------------------------------------------------------------------------

TEST(MeshStream, ObjVertexColoursAreAttributes) {
  const fs::path dir = test::temp_dir("stream_obj");
  const std::string path = (dir / "c.obj").string();
  write_bytes(path, "v 0 0 0 1 0.5 0.25\nv 1 0 0 0 0 1\nv 0 1 0\nf 1 2 3\n");
  const MeshWithAttributes all = read_mesh_with_attributes(path);
  ASSERT_EQ(all.attributes.size(), 3u);
  EXPECT_EQ(all.attributes[0].name, "red");
  EXPECT_EQ(all.attributes[2].name, "blue");
  EXPECT_EQ(all.attributes[1].type, ScalarType::F32);
  // The third vertex has no colour: black.
  EXPECT_EQ(all.values, (std::vector<float>{1, 0.5f, 0.25f, 0, 0, 1, 0, 0, 0}));
  ReadOptions green;
  green.attributes = ReadOptions::Attributes::Named;
  green.attribute_names = {"green", "confidence"};
  const MeshWithAttributes g = read_mesh_with_attributes(path, green);
  ASSERT_EQ(g.attributes.size(), 1u);
  EXPECT_EQ(g.values, (std::vector<float>{0.5f, 0, 0}));
  ReadOptions none;
  none.attributes = ReadOptions::Attributes::None;
  EXPECT_TRUE(read_mesh_with_attributes(path, none).values.empty());
  EXPECT_EQ(read_mesh(path).positions, all.mesh.positions);
  fs::remove_all(dir);
}

TEST(MeshStream, ObjForwardReferencesAreCheckedBeforeEnd) {
  const fs::path dir = test::temp_dir("stream_obj_fwd");
  const std::string path = (dir / "f.obj").string();
  write_bytes(path, "f 1 2 3\nf 1 2 4\nv 0 0 0\nv 1 0 0\nv 0 1 0\n");
  RecordingSink sink(1);
  ReadOptions options;
  options.block = 1;
  const std::string m = error_of([&] { read_mesh_stream(path, sink, options); });
  EXPECT_EQ(m, path + ": line 2: face index 4 is out of range (the file defines 3 vertices)");
  EXPECT_EQ(sink.ends, 0);
  fs::remove_all(dir);
}

// ---- standard input ---------------------------------------------------------------------

/// Runs `body` with standard input reading `bytes` from a pipe (fed by a thread), then restores
/// standard input.
template <class Body>
void with_stdin(const std::string& bytes, Body body) {
  int fds[2];
  ASSERT_EQ(::pipe(fds), 0);
  const int saved = ::dup(STDIN_FILENO);
  ::dup2(fds[0], STDIN_FILENO);
  ::close(fds[0]);
  std::thread writer([&] {
    for (size_t done = 0; done < bytes.size();) {
      const ssize_t n = ::write(fds[1], bytes.data() + done, bytes.size() - done);
      if (n <= 0) break;  // the reader stopped early (an error): nothing more to feed
      done += size_t(n);
    }
    ::close(fds[1]);
  });
  body();
  ::dup2(saved, STDIN_FILENO);  // closes the pipe's read end: a blocked writer gets EPIPE
  ::close(saved);
  writer.join();
}

TEST(MeshStream, DashReadsStandardInputWithTheFormatSniffed) {
  struct IgnoreSigpipe {  // the writer thread may outlive an early error
    void (*old)(int) = ::signal(SIGPIPE, SIG_IGN);
    ~IgnoreSigpipe() { ::signal(SIGPIPE, old); }
  } ignore_sigpipe;
  const fs::path dir = test::temp_dir("stream_stdin");
  const MeshBuffers hand = read_mesh(test::data_path("cgal_hand.off"));
  for (const std::string name : {"m.ply", "m.off", "m.obj", "m.stl", "m.ply.zst"}) {
    SCOPED_TRACE(name);
    write_mesh((dir / name).string(), hand.view());
    const MeshBuffers from_file = read_mesh((dir / name).string());
    with_stdin(read_bytes(dir / name), [&] {
      const MeshBuffers m = read_mesh("-");
      EXPECT_EQ(m.positions, from_file.positions);
      EXPECT_EQ(m.triangles, from_file.triangles);
    });
  }
  // Errors name standard input "stdin", with the position.
  std::string bytes = read_bytes(dir / "m.ply");
  bytes.resize(bytes.size() - 100);
  with_stdin(bytes, [&] {
    const std::string m = error_of([] { read_mesh("-"); });
    EXPECT_EQ(m.rfind("stdin: byte ", 0), 0u) << m;
    EXPECT_NE(m.find("unexpected end of file"), std::string::npos) << m;
  });
  with_stdin("", [&] { EXPECT_EQ(error_of([] { read_mesh("-"); }).rfind("stdin: ", 0), 0u); });
  fs::remove_all(dir);
}

TEST(MeshStream, CliInfoReadsAPipe) {
  ASSERT_TRUE(test::cli_available()) << "STREAMCVD_CLI not built";
  const fs::path dir = test::temp_dir("stream_cli_stdin");
  write_mesh((dir / "m.ply").string(), read_mesh(test::data_path("cgal_hand.off")).view());
  // sh -c "cat m.ply | streamcvd info - --json": the command line of the documentation.
  const std::string out = (dir / "out.json").string();
  const std::string command = "cat '" + (dir / "m.ply").string() + "' | '" + STREAMCVD_CLI + "' info - --json > '" + out + "'";
  const int status = std::system(command.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0);
  const std::string json = read_bytes(out);
  EXPECT_NE(json.find("\"vertices\": 1197"), std::string::npos) << json;
  EXPECT_NE(json.find("\"faces\": 2390"), std::string::npos) << json;
  fs::remove_all(dir);
}

}  // namespace
}  // namespace streamcvd
