// Malformed inputs through the CLI (issue 7): every bad input must give exit code 2 with one
// stderr line naming the file, leave nothing in the output folder, and never allocate from a
// header count (checked with an address-space limit). Output and usage errors:
// bad_output_test.cpp.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "streamcvd/streaming/io/output_file.h"
#include "tests/cli_runner.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

namespace fs = std::filesystem;
using test::CliResult;
using test::entries;
using test::expect_one_line_error;
using test::run_cli;

// ---- input builders ------------------------------------------------------------------------

std::string read_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

void write_bytes(const fs::path& path, const std::string& bytes) {
  std::ofstream f(path, std::ios::binary);
  f.write(bytes.data(), std::streamsize(bytes.size()));
}

/// zstd frame of `bytes`, made with the library's own compressing writer.
std::string zstd_of(const fs::path& scratch, const std::string& bytes) {
  const std::string p = (scratch / "frame.zst").string();
  AtomicOutputFile out(p, true, 3);
  out.write(bytes);
  out.commit();
  std::string z = read_bytes(p);
  fs::remove(p);
  return z;
}

template <class T>
std::string le(T v) {
  std::string s(sizeof v, '\0');
  std::memcpy(s.data(), &v, sizeof v);
  return s;
}

std::string ply_header(const std::string& format, uint64_t vertices, uint64_t faces,
                       const std::string& index_type = "int") {
  return "ply\nformat " + format + " 1.0\nelement vertex " + std::to_string(vertices) +
         "\nproperty float x\nproperty float y\nproperty float z\nelement face " + std::to_string(faces) +
         "\nproperty list uchar " + index_type + " vertex_indices\nend_header\n";
}

std::string binary_ply(std::vector<float> xyz, std::vector<std::vector<int32_t>> faces, uint64_t declared_vertices = 0,
                       uint64_t declared_faces = 0) {
  std::string s = ply_header("binary_little_endian", declared_vertices ? declared_vertices : xyz.size() / 3,
                             declared_faces ? declared_faces : faces.size());
  for (float x : xyz) s += le(x);
  for (const auto& f : faces) {
    s += char(uint8_t(f.size()));
    for (int32_t i : f) s += le(i);
  }
  return s;
}

const std::string kAsciiTriangle = "0 0 0\n1 0 0\n0 1 0\n";

/// Header of a PLY with 3 float vertices and the element `element` holding `records` lists.
std::string ply_list_header(const std::string& format, const std::string& element, uint64_t records,
                            const std::string& list = "list int int vertex_indices") {
  return "ply\nformat " + format + " 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
         "element " + element + " " + std::to_string(records) + "\nproperty " + list + "\nend_header\n";
}

/// Binary PLY: the triangle's vertices, then a tristrips element with one list.
std::string binary_strips(const std::vector<int32_t>& list) {
  std::string s = ply_list_header("binary_little_endian", "tristrips", 1);
  for (float x : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) s += le(x);
  s += le(int32_t(list.size()));
  for (int32_t i : list) s += le(i);
  return s;
}

std::string binary_stl(const std::vector<float>& corners, uint32_t declared) {
  std::string s(80, ' ');
  s += le(declared);
  for (size_t t = 0; t + 9 <= corners.size(); t += 9) {
    for (int k = 0; k < 3; ++k) s += le(0.0f);  // normal
    for (int k = 0; k < 9; ++k) s += le(corners[t + k]);
    s += le(uint16_t(0));
  }
  return s;
}

const std::vector<float> kStlTriangle = {0, 0, 0, 1, 0, 0, 0, 1, 0};

std::string garbage(size_t n, uint32_t seed) {
  std::string s(n, '\0');
  for (char& c : s) {
    seed = seed * 1664525u + 1013904223u;
    c = char(seed >> 24);
  }
  return s;
}

// ---- the table of malformed inputs ---------------------------------------------------------

struct BadInput {
  const char* name;
  const char* file;                                     // file name inside the input folder
  std::function<std::string(const fs::path&)> content;  // given a scratch folder (for zstd)
};

std::string obj_with(const std::string& tail) { return "v 0 0 0\nv 1 0 0\nv 0 1 0\n" + tail; }

const std::vector<BadInput>& bad_inputs() {
  static const std::vector<BadInput> cases = {
      // PLY
      {"PlyMagicOnly", "m.ply", [](auto&) { return std::string("ply\n"); }},
      {"PlyTruncatedHeader", "m.ply",
       [](auto&) { return std::string("ply\nformat ascii 1.0\nelement vertex 3\nproperty fl"); }},
      {"PlyNoFormatLine", "m.ply",
       [](auto&) { return "ply\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n" + kAsciiTriangle; }},
      {"PlyAbsurdVertexCountAscii", "m.ply", [](auto&) { return ply_header("ascii", 4000000000ull, 1) + kAsciiTriangle; }},
      {"PlyAbsurdVertexCountBinary", "m.ply",
       [](auto&) { return binary_ply({0, 0, 0, 1, 0, 0, 0, 1, 0}, {{0, 1, 2}}, 4000000000ull); }},
      {"PlyAbsurdFaceCountZstd", "m.ply.zst",
       [](auto& d) { return zstd_of(d, binary_ply({0, 0, 0, 1, 0, 0, 0, 1, 0}, {{0, 1, 2}}, 0, 4000000000ull)); }},
      {"PlyAbsurdCountsZstdAscii", "m.ply.zst",
       [](auto& d) { return zstd_of(d, ply_header("ascii", 3, 3000000000ull) + kAsciiTriangle + "3 0 1 2\n"); }},
      {"PlyMoreVerticesThanData", "m.ply", [](auto&) { return ply_header("ascii", 10, 0) + kAsciiTriangle; }},
      {"PlyMoreFacesThanData", "m.ply", [](auto&) { return ply_header("ascii", 3, 5) + kAsciiTriangle + "3 0 1 2\n"; }},
      {"PlyBinaryTruncatedBody", "m.ply",
       [](auto&) {
         std::string s = binary_ply({0, 0, 0, 1, 0, 0, 0, 1, 0}, {{0, 1, 2}, {0, 2, 1}});
         return s.substr(0, s.size() - 7);
       }},
      {"PlyNegativeIndex", "m.ply", [](auto&) { return ply_header("ascii", 3, 1) + kAsciiTriangle + "3 0 -1 2\n"; }},
      {"PlyIndexOutOfRange", "m.ply", [](auto&) { return binary_ply({0, 0, 0, 1, 0, 0, 0, 1, 0}, {{0, 1, 3}}); }},
      {"PlyHugeUnsignedIndex", "m.ply",
       [](auto&) { return ply_header("ascii", 3, 1, "uint") + kAsciiTriangle + "3 0 1 4294967295\n"; }},
      {"PlyNanCoordinate", "m.ply", [](auto&) { return ply_header("ascii", 3, 1) + "0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n"; }},
      {"PlyInfCoordinateBinary", "m.ply",
       [](auto&) { return binary_ply({0, 0, 0, 1, 0, std::numeric_limits<float>::infinity(), 0, 1, 0}, {{0, 1, 2}}); }},
      {"PlyFaceWithTwoVertices", "m.ply", [](auto&) { return ply_header("ascii", 3, 1) + kAsciiTriangle + "2 0 1\n"; }},
      {"PlyFaceWithZeroVertices", "m.ply", [](auto&) { return binary_ply({0, 0, 0, 1, 0, 0, 0, 1, 0}, {{}}); }},
      {"PlyHugeListCount", "m.ply",
       [](auto&) {
         std::string s = ply_header("binary_little_endian", 3, 1);
         s.replace(s.find("list uchar int"), 14, "list uint int");
         for (float x : {0.f, 0.f, 0.f, 1.f, 0.f, 0.f, 0.f, 1.f, 0.f}) s += le(x);
         return s + le(uint32_t(4000000000u)) + le(int32_t(0)) + le(int32_t(1));
       }},
      {"PlyHeaderCommentOver1MiB", "m.ply",
       [](auto&) { return "ply\nformat ascii 1.0\ncomment " + std::string(size_t(2) << 20, 'c') + "\n"; }},
      {"PlyBinaryGarbage", "m.ply", [](auto&) { return "ply\n" + garbage(5000, 1); }},
      {"PlyOnlyVertices", "m.ply",
       [](auto&) {
         return "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
                "end_header\n" + kAsciiTriangle;
       }},
      {"PlyZeroFaces", "m.ply", [](auto&) { return ply_header("ascii", 3, 0) + kAsciiTriangle; }},
      {"PlyUnknownFaceElement", "m.ply",
       [](auto&) { return ply_list_header("ascii", "polygon", 1, "list uchar int vertex_indices") + kAsciiTriangle + "3 0 1 2\n"; }},
      {"PlyStripIndexOutOfRange", "m.ply",
       [](auto&) { return ply_list_header("ascii", "tristrips", 1) + kAsciiTriangle + "5 0 1 2 -1 3\n"; }},
      {"PlyStripIndexOutOfRangeBinary", "m.ply", [](auto&) { return binary_strips({0, 1, 2, 7}); }},
      {"PlyStripNegativeIndexZstd", "m.ply.zst", [](auto& d) { return zstd_of(d, binary_strips({0, 1, -3})); }},
      {"PlyStripsAllDegenerate", "m.ply", [](auto&) { return binary_strips({0, 0, 1, 1}); }},
      {"PlyStripListTruncatedAscii", "m.ply",
       [](auto&) { return ply_list_header("ascii", "tristrips", 1) + kAsciiTriangle + "7 0 1 2 -1 0\n"; }},
      {"PlyStripListTruncatedBinary", "m.ply",
       [](auto&) {
         const std::string s = binary_strips({0, 1, 2, -1, 0, 2, 1});
         return s.substr(0, s.size() - 6);  // ends inside the list's 6th index
       }},
      {"PlyRangeGridOnly", "m.ply",
       [](auto&) { return ply_list_header("ascii", "range_grid", 4, "list uchar int vertex_indices") + kAsciiTriangle + "1 0\n0\n1 1\n1 2\n"; }},
      {"PlyTruncatedBinaryFaceBlockZstd", "m.ply.zst",
       [](auto& d) {
         // 1000 triangles in the fast path's layout, cut inside the run: only the reader finds it.
         std::vector<std::vector<int32_t>> faces(1000, {0, 1, 2});
         std::string s = binary_ply({0, 0, 0, 1, 0, 0, 0, 1, 0}, faces);
         return zstd_of(d, s.substr(0, s.size() - 13 * 400 - 5));
       }},
      // OBJ
      {"ObjFaceIndexZero", "m.obj", [](auto&) { return obj_with("f 0 1 2\n"); }},
      {"ObjRelativeIndexBeforeFirst", "m.obj", [](auto&) { return obj_with("f -1 -2 -4\n"); }},
      {"ObjIndexPastLastVertex", "m.obj", [](auto&) { return obj_with("f 1 2 4\n"); }},
      {"ObjIndexOverflow", "m.obj", [](auto&) { return obj_with("f 1 2 99999999999999999999999\n"); }},
      {"ObjNanCoordinate", "m.obj", [](auto&) { return std::string("v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n"); }},
      {"ObjInfCoordinate", "m.obj", [](auto&) { return std::string("v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n"); }},
      {"ObjFaceWithTwoCorners", "m.obj", [](auto&) { return obj_with("f 1 2\n"); }},
      {"ObjVertexWithTwoCoordinates", "m.obj", [](auto&) { return std::string("v 0 0\n"); }},
      {"ObjNoVertices", "m.obj", [](auto&) { return std::string("# only a comment\ng group\n"); }},
      {"ObjNoFaces", "m.obj", [](auto&) { return obj_with("# no f records\n"); }},
      {"ObjBinaryGarbage", "m.obj", [](auto&) { return garbage(20000, 2); }},
      {"ObjLineOver256MiBZstd", "m.obj.zst",
       [](auto& d) {
         const std::string p = (d / "long.zst").string();
         AtomicOutputFile out(p, true, 1);
         const std::string block(size_t(1) << 20, 'v');
         for (int i = 0; i < 257; ++i) out.write(block);
         out.commit();
         std::string z = read_bytes(p);
         fs::remove(p);
         return z;
       }},
      // OFF
      {"OffKeywordOnly", "m.off", [](auto&) { return std::string("OFF\n"); }},
      {"OffMissingFaceCount", "m.off", [](auto&) { return std::string("OFF\n3\n"); }},
      {"OffAbsurdVertexCount", "m.off", [](auto&) { return "OFF\n4000000000 1 0\n" + kAsciiTriangle + "3 0 1 2\n"; }},
      {"OffAbsurdFaceCountZstd", "m.off.zst",
       [](auto& d) { return zstd_of(d, "OFF\n3 4000000000 0\n" + kAsciiTriangle + "3 0 1 2\n"); }},
      {"OffMoreVerticesThanData", "m.off", [](auto&) { return "OFF\n5 1 0\n" + kAsciiTriangle; }},
      {"OffMoreFacesThanData", "m.off", [](auto&) { return "OFF\n3 2 0\n" + kAsciiTriangle + "3 0 1 2\n"; }},
      {"OffNegativeIndex", "m.off", [](auto&) { return "OFF\n3 1 0\n" + kAsciiTriangle + "3 0 -1 2\n"; }},
      {"OffIndexOutOfRange", "m.off", [](auto&) { return "OFF\n3 1 0\n" + kAsciiTriangle + "3 0 1 3\n"; }},
      {"OffInfCoordinate", "m.off", [](auto&) { return std::string("OFF\n3 1 0\n0 0 0\ninf 0 0\n0 1 0\n3 0 1 2\n"); }},
      {"OffFaceWithOneVertex", "m.off", [](auto&) { return "OFF\n3 1 0\n" + kAsciiTriangle + "1 0\n"; }},
      {"OffZeroVertices", "m.off", [](auto&) { return std::string("OFF\n0 0 0\n"); }},
      {"OffZeroFaces", "m.off", [](auto&) { return "OFF\n3 0 0\n" + kAsciiTriangle; }},
      {"OffBinaryGarbage", "m.off", [](auto&) { return "OFF\n" + garbage(3000, 3); }},
      // STL
      {"StlBinaryTooShort", "m.stl", [](auto&) { return garbage(50, 4); }},
      {"StlBinaryTruncated", "m.stl",
       [](auto&) {
         std::string s = binary_stl(kStlTriangle, 3);
         return s + s.substr(84, 50);  // 2 of 3 triangles
       }},
      {"StlBinaryAbsurdCount", "m.stl", [](auto&) { return binary_stl(kStlTriangle, 4000000000u); }},
      {"StlBinaryAbsurdCountZstd", "m.stl.zst", [](auto& d) { return zstd_of(d, binary_stl(kStlTriangle, 4000000000u)); }},
      {"StlBinaryZeroTriangles", "m.stl", [](auto&) { return binary_stl({}, 0); }},
      {"StlBinaryNan", "m.stl",
       [](auto&) { return binary_stl({0, 0, 0, 1, std::numeric_limits<float>::quiet_NaN(), 0, 0, 1, 0}, 1); }},
      {"StlAsciiTruncatedFacet", "m.stl",
       [](auto&) { return std::string("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0"); }},
      {"StlAsciiTwoVertexFacet", "m.stl",
       [](auto&) {
         return std::string("solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid t\n");
       }},
      {"StlAsciiNoFacets", "m.stl", [](auto&) { return std::string("solid t\nendsolid t\n"); }},
      // Any format
      {"EmptyPly", "m.ply", [](auto&) { return std::string(); }},
      {"EmptyObj", "m.obj", [](auto&) { return std::string(); }},
      {"UnknownExtensionGarbage", "m.xyz", [](auto&) { return garbage(4096, 5); }},
      {"ZstdMagicOnly", "m.off.zst", [](auto&) { return std::string("\x28\xB5\x2F\xFD", 4); }},
      {"ZstdTruncatedFrame", "m.off.zst",
       [](auto& d) {
         std::string z = zstd_of(d, read_bytes(test::data_path("cgal_hand.off")));
         return z.substr(0, z.size() / 2);
       }},
      {"ZstdCorruptFrame", "m.off.zst",
       [](auto& d) {
         std::string z = zstd_of(d, read_bytes(test::data_path("cgal_hand.off")));
         for (size_t i = z.size() / 3; i < z.size() / 3 + 64; ++i) z[i] = char(~z[i]);
         return z;
       }},
      {"ZstdCorruptBundledFile", "m.off.zst",
       [](auto&) {
         std::string z = read_bytes(test::data_path("fertility.off.zst"));
         z.resize(z.size() - 1);  // loses the frame's last byte (checksum)
         return z;
       }},
      {"ZstdOfGarbage", "m.ply.zst", [](auto& d) { return zstd_of(d, "ply\n" + garbage(100000, 6)); }},
  };
  return cases;
}

// ---- checks --------------------------------------------------------------------------------

void expect_bad_input(const std::string& input, const fs::path& out_dir, const std::string& named,
                      bool limit_memory = true) {
  test::CliLimits limits;
  limits.address_space_mb = limit_memory ? 1024 : 0;
  CliResult info = run_cli({"info", input}, limits);
  if (std::getenv("STREAMCVD_BAD_INPUT_VERBOSE")) std::fputs(info.err.c_str(), stdout);
  EXPECT_FALSE(info.timed_out);
  EXPECT_EQ(info.exit_code, 2) << info.describe();
  expect_one_line_error(info, named);

  const std::string out = (out_dir / "out.ply").string();
  CliResult remesh = run_cli({"remesh", input, "-o", out, "-n", "100", "-q"}, limits);
  EXPECT_FALSE(remesh.timed_out);
  EXPECT_EQ(remesh.exit_code, 2) << remesh.describe();
  expect_one_line_error(remesh, named);

  if (!fs::is_directory(input)) {  // ingest reads mesh files (a store is its output)
    CliResult ingest = run_cli({"ingest", input, (out_dir / "in.store").string()}, limits);
    EXPECT_FALSE(ingest.timed_out);
    EXPECT_EQ(ingest.exit_code, 2) << ingest.describe();
    expect_one_line_error(ingest, named);
  }
  EXPECT_TRUE(entries(out_dir).empty()) << "output folder not empty (an output, a work file or the store's folder)";
}

class BadInputFile : public ::testing::TestWithParam<size_t> {};

TEST_P(BadInputFile, ExitsTwoWithOneLineAndNoOutput) {
  ASSERT_TRUE(test::cli_available()) << "STREAMCVD_CLI not built";
  const BadInput& c = bad_inputs()[GetParam()];
  const fs::path dir = test::temp_dir("bad_input");
  fs::create_directories(dir / "in");
  fs::create_directories(dir / "out");
  const fs::path input = dir / "in" / c.file;
  write_bytes(input, c.content(dir));
  // The 257 MiB line legitimately needs a 256 MiB+ buffer before it can be rejected.
  const bool limit_memory = std::string(c.name).find("Over256MiB") == std::string::npos;
  expect_bad_input(input.string(), dir / "out", input.string(), limit_memory);
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(Cases, BadInputFile, ::testing::Range<size_t>(0, bad_inputs().size()),
                         [](const auto& info) { return std::string(bad_inputs()[info.param].name); });

// ---- inputs that are not files -------------------------------------------------------------

TEST(BadInput, DirectoryAsInput) {
  const fs::path dir = test::temp_dir("bad_dir");
  fs::create_directories(dir / "in.ply");
  fs::create_directories(dir / "out");
  expect_bad_input((dir / "in.ply").string(), dir / "out", (dir / "in.ply").string());
  fs::remove_all(dir);
}

TEST(BadInput, MissingFile) {
  const fs::path dir = test::temp_dir("bad_missing");
  fs::create_directories(dir / "out");
  expect_bad_input((dir / "nope.ply").string(), dir / "out", (dir / "nope.ply").string());
  fs::remove_all(dir);
}

TEST(BadInput, FifoWithoutWriterDoesNotHang) {
  const fs::path dir = test::temp_dir("bad_fifo");
  fs::create_directories(dir / "out");
  const fs::path fifo = dir / "pipe.ply";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0) << std::strerror(errno);
  expect_bad_input(fifo.string(), dir / "out", fifo.string());  // the runner's watchdog catches a hang
  fs::remove_all(dir);
}

TEST(BadInput, CharacterDeviceIsRejected) {
  const fs::path dir = test::temp_dir("bad_dev");
  fs::create_directories(dir / "out");
  expect_bad_input("/dev/zero", dir / "out", "/dev/zero");  // endless data: must not be read
  fs::remove_all(dir);
}

TEST(BadInput, ReadErrorIsReported) {
  // Works as root too: reading a process's own /proc/self/mem at offset 0 fails with EIO.
  const fs::path dir = test::temp_dir("bad_eio");
  fs::create_directories(dir / "out");
  expect_bad_input("/proc/self/mem", dir / "out", "/proc/self/mem");
  fs::remove_all(dir);
}

TEST(BadInput, UnreadableFile) {
  if (::geteuid() == 0) GTEST_SKIP() << "root reads files whatever their mode";
  const fs::path dir = test::temp_dir("bad_perm");
  fs::create_directories(dir / "out");
  const fs::path input = dir / "secret.off";
  fs::copy_file(test::data_path("cgal_hand.off"), input);
  fs::permissions(input, fs::perms::none);
  expect_bad_input(input.string(), dir / "out", input.string());
  fs::permissions(input, fs::perms::owner_all);
  fs::remove_all(dir);
}

TEST(BadInput, CorruptStoreDirectories) {
  const fs::path dir = test::temp_dir("bad_store");
  fs::create_directories(dir / "out");
  const fs::path store = dir / "store";
  CliResult r = run_cli({"ingest", test::data_path("cgal_hand.off"), store.string()});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const std::string good_vv = read_bytes((store / "vv.u32").string());
  const std::string good_tri = read_bytes((store / "triangles.u32").string());
  const std::string good_header = read_bytes((store / "header.bin").string());
  // A truncated array, an index out of range, a header count that disagrees with the files.
  write_bytes(store / "vv.u32", good_vv.substr(0, good_vv.size() - 4));
  expect_bad_input(store.string(), dir / "out", (store / "vv.u32").string());
  write_bytes(store / "vv.u32", good_vv);
  std::string tri = good_tri;
  const uint32_t huge = 0xFFFFFFF0u;
  std::memcpy(tri.data() + 400, &huge, 4);
  write_bytes(store / "triangles.u32", tri);
  expect_bad_input(store.string(), dir / "out", (store / "triangles.u32").string());
  write_bytes(store / "triangles.u32", good_tri);
  std::string header = good_header;
  const uint64_t absurd = 4000000000ull;
  std::memcpy(header.data() + 16, &absurd, 8);  // vertex_count
  write_bytes(store / "header.bin", header);
  expect_bad_input(store.string(), dir / "out", store.string());
  fs::remove_all(dir);
}

TEST(BadInput, StripAndFaceElementErrorsSayWhereAndWhat) {
  const fs::path dir = test::temp_dir("bad_strips");
  struct Case {
    std::string name, bytes;
    std::vector<std::string> parts;  // in the one stderr line, besides the file name
  };
  const std::string binary = binary_strips({0, 1, 2, 7});
  const size_t index_byte = binary.find("end_header\n") + 11 + 36 + 4 + 3 * 4;
  const std::string strip_full = binary_strips({0, 1, 2, -1, 0, 2, 1});
  const std::string strip_cut = strip_full.substr(0, strip_full.size() - 6);  // inside the 6th index
  std::vector<std::vector<int32_t>> faces(1000, {0, 1, 2});
  const std::string block = binary_ply({0, 0, 0, 1, 0, 0, 0, 1, 0}, faces);
  const std::vector<Case> cases = {
      {"ascii.ply", ply_list_header("ascii", "tristrips", 1) + kAsciiTriangle + "5 0 1 2 -1 3\n",
       {"line 13: tristrips 0: item 4: uses vertex 3 of 3"}},
      {"binary.ply", binary, {"byte " + std::to_string(index_byte) + ": tristrips 0: item 3: uses vertex 7 of 3"}},
      {"strip_cut.ply", strip_cut,
       {"byte " + std::to_string(strip_cut.size()) + ": unexpected end of file in tristrips 0 of 1"}},
      {"strip_cut_ascii.ply", ply_list_header("ascii", "tristrips", 1) + kAsciiTriangle + "7 0 1 2 -1 0\n",
       {"line 13: tristrips 0: too few values on the line"}},
      {"range_grid.ply",
       ply_list_header("ascii", "range_grid", 4, "list uchar int vertex_indices") + kAsciiTriangle + "1 0\n0\n1 1\n1 2\n",
       {"line 9: no face element", "vertex (3), range_grid (4)", "'face' or 'tristrips'"}},
      {"points.ply",
       "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n" +
           kAsciiTriangle,
       {"no face element", "elements vertex (3);"}},
      {"polygon.ply", ply_list_header("ascii", "polygon", 1) + kAsciiTriangle + "3 0 1 2\n",
       {"line 9: no face element", "vertex (3), polygon (1)"}},
      {"cut.ply.zst", zstd_of(dir, block.substr(0, block.size() - 13 * 400 - 5)),
       {"byte " + std::to_string(block.size() - 13 * 400 - 5), "unexpected end of file in face 599 of 1000"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    write_bytes(dir / c.name, c.bytes);
    const CliResult r = run_cli({"info", (dir / c.name).string()});
    EXPECT_EQ(r.exit_code, 2) << r.describe();
    expect_one_line_error(r, (dir / c.name).string());
    for (const std::string& part : c.parts) EXPECT_NE(r.err.find(part), std::string::npos) << part << " not in " << r.err;
  }
  fs::remove_all(dir);
}

// ---- inputs that must be accepted ----------------------------------------------------------

void expect_accepted(const fs::path& input, const fs::path& out_dir, uint64_t vertices, uint64_t faces) {
  CliResult info = run_cli({"info", input.string(), "--json"});
  ASSERT_EQ(info.exit_code, 0) << info.describe();
  EXPECT_NE(info.out.find("\"vertices\": " + std::to_string(vertices)), std::string::npos) << info.out;
  EXPECT_NE(info.out.find("\"faces\": " + std::to_string(faces)), std::string::npos) << info.out;
  const fs::path out = out_dir / "out.ply";
  CliResult remesh = run_cli({"remesh", input.string(), "-o", out.string(), "-n", "100", "-q"});
  ASSERT_EQ(remesh.exit_code, 0) << remesh.describe();
  EXPECT_EQ(entries(out_dir), std::vector<std::string>{"out.ply"});
}

TEST(BadInput, MixedLineEndingsAreAccepted) {
  const fs::path dir = test::temp_dir("mixed_eol");
  fs::create_directories(dir / "out");
  const MeshBuffers sphere = make_icosphere(2);
  const char* breaks[] = {"\n", "\r\n", "\r"};
  std::string obj = "# mixed\r\n", off = "OFF\r" + std::to_string(sphere.vertex_count()) + " " +
                                          std::to_string(sphere.face_count()) + " 0\r\n";
  std::string ply = "ply\r\nformat ascii 1.0\nelement vertex " + std::to_string(sphere.vertex_count()) +
                    "\r\nproperty float x\rproperty float y\nproperty float z\r\nelement face " +
                    std::to_string(sphere.face_count()) + "\nproperty list uchar int vertex_indices\r\nend_header\r\n";
  for (uint32_t v = 0; v < sphere.vertex_count(); ++v) {
    std::string xyz = std::to_string(sphere.positions[3 * v]) + " " + std::to_string(sphere.positions[3 * v + 1]) +
                      " " + std::to_string(sphere.positions[3 * v + 2]);
    obj += "v " + xyz + breaks[v % 3];
    off += xyz + breaks[(v + 1) % 3];
    ply += xyz + breaks[(v + 2) % 3];
  }
  for (uint64_t f = 0; f < sphere.face_count(); ++f) {
    const uint32_t* t = &sphere.triangles[3 * f];
    obj += "f " + std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) + " " + std::to_string(t[2] + 1) + breaks[f % 3];
    const std::string ids = std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]);
    off += "3 " + ids + breaks[(f + 1) % 3];
    ply += "3 " + ids + breaks[(f + 2) % 3];
  }
  for (const auto& [name, text] : {std::pair{"m.obj", obj}, std::pair{"m.off", off}, std::pair{"m.ply", ply}}) {
    SCOPED_TRACE(name);
    write_bytes(dir / name, text);
    expect_accepted(dir / name, dir / "out", sphere.vertex_count(), sphere.face_count());
    fs::remove(dir / "out" / "out.ply");
  }
  fs::remove_all(dir);
}

TEST(BadInput, StripListsWithoutTrailingRestartAreAccepted) {
  // A tristrips element with one list per triangle of a sphere: no -1 anywhere, each list's end
  // ends its strip.
  const fs::path dir = test::temp_dir("strips_ok");
  fs::create_directories(dir / "out");
  const MeshBuffers sphere = make_icosphere(2);
  std::string ply = "ply\nformat ascii 1.0\nelement vertex " + std::to_string(sphere.vertex_count()) +
                    "\nproperty float x\nproperty float y\nproperty float z\nelement tristrips " +
                    std::to_string(sphere.face_count()) + "\nproperty list int int vertex_indices\nend_header\n";
  for (uint32_t v = 0; v < sphere.vertex_count(); ++v)
    ply += std::to_string(sphere.positions[3 * v]) + " " + std::to_string(sphere.positions[3 * v + 1]) + " " +
           std::to_string(sphere.positions[3 * v + 2]) + "\n";
  for (uint64_t f = 0; f < sphere.face_count(); ++f)
    ply += "3 " + std::to_string(sphere.triangles[3 * f]) + " " + std::to_string(sphere.triangles[3 * f + 1]) + " " +
           std::to_string(sphere.triangles[3 * f + 2]) + "\n";
  write_bytes(dir / "strips.ply", ply);
  expect_accepted(dir / "strips.ply", dir / "out", sphere.vertex_count(), sphere.face_count());
  fs::remove_all(dir);
}

TEST(BadInput, LongCommentLinesAreAccepted) {
  const fs::path dir = test::temp_dir("long_line");
  fs::create_directories(dir / "out");
  const std::string hand = read_bytes(test::data_path("cgal_hand.off"));
  // A 3 MiB comment line in the middle of an OBJ and at the start of an OFF.
  const std::string comment = "# " + std::string(size_t(3) << 20, 'x') + "\n";
  write_bytes(dir / "m.off", comment + hand);
  expect_accepted(dir / "m.off", dir / "out", 1197, 2390);
  fs::remove(dir / "out" / "out.ply");
  write_bytes(dir / "m.obj", obj_with(comment + "f 1 2 3\n"));
  CliResult info = run_cli({"info", (dir / "m.obj").string()});
  EXPECT_EQ(info.exit_code, 0) << info.describe();
  fs::remove_all(dir);
}

}  // namespace
}  // namespace streamcvd
