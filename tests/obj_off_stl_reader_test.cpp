// Tests of the OBJ, OFF and STL readers: every syntax variant with exact expectations, the same
// files zstd-compressed, malformed inputs, and the shared meshes against MANIFEST.tsv.
#include <gtest/gtest.h>
#include <zstd.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

void write_bytes(const std::filesystem::path& path, const std::string& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(bytes.data(), std::streamsize(bytes.size()));
  ASSERT_TRUE(out.good()) << path;
}

std::string zstd_compress(const std::string& bytes) {
  std::string out(ZSTD_compressBound(bytes.size()), '\0');
  size_t n = ZSTD_compress(out.data(), out.size(), bytes.data(), bytes.size(), 3);
  EXPECT_FALSE(ZSTD_isError(n));
  out.resize(n);
  return out;
}

/// Scratch folder shared by this file's tests, removed when the test binary exits.
const std::filesystem::path& scratch() {
  struct Dir {
    std::filesystem::path path = test::temp_dir("objoffstl");
    ~Dir() {
      std::error_code ignored;
      std::filesystem::remove_all(path, ignored);
    }
  };
  static const Dir dir;
  return dir.path;
}

/// Through the public entry point: every name here has the extension of the format it holds.
MeshBuffers read_file(const std::string& path) { return read_mesh(path); }

/// Writes `bytes` to `name` and a zstd copy to `name`.zst, reads both and checks they agree.
MeshBuffers read_bytes(const std::string& name, const std::string& bytes) {
  std::string path = (scratch() / name).string();
  write_bytes(path, bytes);
  write_bytes(path + ".zst", zstd_compress(bytes));
  MeshBuffers plain = read_file(path);
  MeshBuffers packed = read_file(path + ".zst");
  EXPECT_EQ(plain.positions, packed.positions) << name;
  EXPECT_EQ(plain.triangles, packed.triangles) << name;
  EXPECT_EQ(plain.polygons_split, packed.polygons_split) << name;
  return plain;
}

/// Expects both the plain and the zstd copy to throw InputError naming the file and containing
/// `fragment` (the plain copy's message only; zstd offsets may differ).
void expect_error(const std::string& name, const std::string& bytes, const std::string& fragment) {
  std::string path = (scratch() / name).string();
  write_bytes(path, bytes);
  write_bytes(path + ".zst", zstd_compress(bytes));
  for (const std::string& p : {path, path + ".zst"}) {
    try {
      read_file(p);
      ADD_FAILURE() << p << ": no InputError";
    } catch (const InputError& e) {
      std::string what = e.what();
      EXPECT_NE(what.find(p + ": "), std::string::npos) << what;
      EXPECT_EQ(what.find('\n'), std::string::npos) << what;
      if (p == path) {
        EXPECT_NE(what.find(fragment), std::string::npos) << what;
      }
    }
  }
}

std::vector<float> floats(std::initializer_list<float> v) { return v; }
std::vector<uint32_t> indices(std::initializer_list<uint32_t> v) { return v; }

// ---------------------------------------------------------------------------------------- OBJ

TEST(ObjReader, CornerFormsAndIgnoredRecords) {
  const std::string obj =
      "# comment\nmtllib a.mtl\no thing\ng group\ns 1\nusemtl red\n"
      "v 0 0 0\nv 1.5 0 0 1.0\nv 0 -2.25 0 0.5 0.5 0.5\nv +0 0 1e3 # trailing comment\n"
      "vt 0 0\nvt 1 0\nvt 0 1\nvt 1 1\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\nvp 0.5\n"
      "f 1 2 3\nf 1/1 2/2 4/4\nf 1/1/1 3/3/3 4/4/4\nf\t2//2  3//3 4//4  \nl 1 2\np 3\n";
  MeshBuffers m = read_bytes("forms.obj", obj);
  EXPECT_EQ(m.positions, floats({0, 0, 0, 1.5f, 0, 0, 0, -2.25f, 0, 0, 0, 1000}));
  EXPECT_EQ(m.triangles, indices({0, 1, 2, 0, 1, 3, 0, 2, 3, 1, 2, 3}));
  EXPECT_EQ(m.polygons_split, 0u);
}

TEST(ObjReader, NumberSyntaxAndVertexExtras) {
  const std::string obj = "v .5 1. -.25E+1\nv\t1e-2 +3 -0 1 0.2 0.3 0.4\nv 0 1 0\nf +1 2 3\n";
  MeshBuffers m = read_bytes("numbers.obj", obj);
  EXPECT_EQ(m.positions, floats({0.5f, 1, -2.5f, 1e-2f, 3, -0.0f, 0, 1, 0}));
  EXPECT_EQ(m.triangles, indices({0, 1, 2}));
}

TEST(ObjReader, NegativeIndicesCountBackFromLastDefinedVertex) {
  const std::string obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 0 0 1\nf -1/-1/-1 -2//-2 -4\n";
  MeshBuffers m = read_bytes("negative.obj", obj);
  EXPECT_EQ(m.vertex_count(), 4u);
  EXPECT_EQ(m.triangles, indices({0, 1, 2, 3, 2, 0}));
}

TEST(ObjReader, PolygonsAreFanTriangulated) {
  const std::string obj =
      "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv -1 0.5 0\nf 1 2 3 4\nf 1 4 5\nf 5 4 3 2 1\n";
  MeshBuffers m = read_bytes("poly.obj", obj);
  EXPECT_EQ(m.triangles, indices({0, 1, 2, 0, 2, 3, 0, 3, 4, 4, 3, 2, 4, 2, 1, 4, 1, 0}));
  EXPECT_EQ(m.polygons_split, 2u);
}

TEST(ObjReader, ContinuationCrlfAndForwardReferences) {
  // A face may name a vertex defined later (positive indices are checked against the total).
  const std::string obj = "f 1 2 \\\r\n 3\r\nv 0 0 0\r\nv 1 \\\r\n0 0\r\nv 0 1 0";
  MeshBuffers m = read_bytes("continued.obj", obj);
  EXPECT_EQ(m.positions, floats({0, 0, 0, 1, 0, 0, 0, 1, 0}));
  EXPECT_EQ(m.triangles, indices({0, 1, 2}));
}

TEST(ObjReader, MalformedInputsThrowNamingFileAndLine) {
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  expect_error("zero.obj", tri + "f 0 1 2\n", "line 4: face index 0");
  expect_error("range.obj", tri + "f 1 2 4\nf 1 2 3\n", "line 4: face index 4 is out of range");
  expect_error("relative.obj", tri + "f -1 -2 -4\n", "line 4: relative face index -4");
  expect_error("two.obj", tri + "f 1 2\n", "line 4: face with 2 corners");
  expect_error("badnum.obj", "v 0 0 0\nv 1 x 0\n", "line 2: bad number 'x'");
  expect_error("nan.obj", "v 0 nan 0\n", "line 1: coordinate is not finite");
  expect_error("inf.obj", "v 0 0 -inf\n", "coordinate is not finite");
  expect_error("overflow.obj", "v 0 0 1e39\n", "coordinate is not finite");
  expect_error("short.obj", "v 0 0\n", "vertex needs 3 coordinates");
  expect_error("badidx.obj", tri + "f 1 a 3\n", "bad face index 'a'");
  expect_error("badidx2.obj", tri + "f 1 2x 3\n", "bad face index '2x'");
  expect_error("hugeidx.obj", tri + "f 1 2 99999999999999999999\n", "out of range");
  expect_error("empty.obj", "# nothing\ng x\n", "no vertices");
}

// ---------------------------------------------------------------------------------------- OFF

TEST(OffReader, CountsOnKeywordLineAndCommentsAnywhere) {
  const std::string off =
      "# leading comment\n\nOFF 4 2 0 # counts here\n# between\n0 0 0\n1 0 0 # end of line\n\n0 1 0\n0 0 1\n"
      "3 0 1 2\n# face comment\n3 0 2 3\n";
  MeshBuffers m = read_bytes("keyline.off", off);
  EXPECT_EQ(m.positions, floats({0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1}));
  EXPECT_EQ(m.triangles, indices({0, 1, 2, 0, 2, 3}));
}

TEST(OffReader, CountsOnNextLineWithoutEdgeCount) {
  const std::string off = "OFF\n# comment\n3 1\n0.5 -0.25 2e-3\n+1 0 0\n0 1 0\n3 2 1 0\n";
  MeshBuffers m = read_bytes("nextline.off", off);
  EXPECT_EQ(m.positions, floats({0.5f, -0.25f, 2e-3f, 1, 0, 0, 0, 1, 0}));
  EXPECT_EQ(m.triangles, indices({2, 1, 0}));
}

TEST(OffReader, ColourNormalAndTextureVariantsSkipExtraValues) {
  const std::string faces = "4 0 1 2 3 255 0 0\n3 0 1 2 0.1 0.2 0.3 1\n";
  const std::string verts[] = {
      "COFF\n4 2 0\n0 0 0 255 0 0 255\n1 0 0 0 255 0 255\n1 1 0 0 0 255 255\n0 1 0 9 9 9 9\n",
      "COFF\n4 2 0\n0 0 0 1 0 0\n1 0 0 0 1 0\n1 1 0 0 0 1\n0 1 0 1 1 1\n",
      "NOFF\n4 2 0\n0 0 0 0 0 1\n1 0 0 0 0 1\n1 1 0 0 0 1\n0 1 0 0 0 1\n",
      "CNOFF\n4 2 0\n0 0 0 0 0 1 1 0 0 1\n1 0 0 0 0 1 1 0 0 1\n1 1 0 0 0 1 1 0 0 1\n0 1 0 0 0 1 1 0 0 1\n",
      "STOFF\n4 2 0\n0 0 0 0 0\n1 0 0 1 0\n1 1 0 1 1\n0 1 0 0 1\n",
      "4OFF\n4 2 0\n0 0 0 2\n2 0 0 2\n3 3 0 3\n0 0.5 0 0.5\n",
      "nOFF 3\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n",
      "4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n",  // keyword is optional
      "OFF\n4 2 0\n0\n0 0\n1 0\n0\n1 1 0\n0 1\n0\n",  // values spilling over lines
  };
  int i = 0;
  for (const std::string& v : verts) {
    SCOPED_TRACE(v);
    MeshBuffers m = read_bytes("variant" + std::to_string(i++) + ".off", v + faces);
    EXPECT_EQ(m.positions, floats({0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 0}));
    EXPECT_EQ(m.triangles, indices({0, 1, 2, 0, 2, 3, 0, 1, 2}));
    EXPECT_EQ(m.polygons_split, 1u);
  }
}

TEST(OffReader, MalformedInputsThrowNamingFileAndLine) {
  const std::string tri = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n";
  expect_error("binary.off", "OFF BINARY\n3 1 0\n", "binary OFF is not supported");
  expect_error("keyword.off", "OFFX\n3 1 0\n", "unknown OFF keyword");
  expect_error("notoff.off", "ply\nformat ascii 1.0\n", "not an OFF file");
  expect_error("fewverts.off", "OFF\n5 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "vertices");
  expect_error("fewfaces.off", "OFF\n3 2 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n", "file ends after 1 of 2 faces");
  expect_error("range.off", tri + "3 0 1 3\n", "line 6: vertex index 3 is out of range");
  expect_error("negative.off", tri + "3 0 -1 2\n", "bad vertex index '-1'");
  expect_error("two.off", tri + "2 0 1\n", "face with 2 corners");
  expect_error("nan.off", "OFF\n3 1 0\n0 0 0\n1 NaN 0\n0 1 0\n3 0 1 2\n", "line 4: coordinate is not finite");
  expect_error("badnum.off", "OFF\n3 1 0\n0 0 0\n1 0,5 0\n0 1 0\n3 0 1 2\n", "bad number '0,5'");
  expect_error("badcount.off", "OFF\nthree 1 0\n", "bad vertex count");
  expect_error("huge.off", "OFF\n4000000000 1 0\n0 0 0\n", "file ends after 1 of 4000000000 vertices");
  expect_error("toohuge.off", "OFF\n99999999999 1 0\n0 0 0\n", "more than 4294967295 vertices");
  expect_error("novertex.off", "OFF\n0 0 0\n", "0 vertices");
  expect_error("comments.off", "# only\n\n# comments\n", "no OFF header");
  expect_error("dim.off", "nOFF 4\n3 1 0\n", "only 3-dimensional");
}

// ---------------------------------------------------------------------------------------- STL

std::string binary_stl(const std::string& header, const std::vector<float>& corners, uint32_t declared,
                       const std::string& trailer = "") {
  std::string out = header.substr(0, 80);
  out.resize(80, ' ');
  char count[4];
  std::memcpy(count, &declared, 4);
  out.append(count, 4);
  for (size_t t = 0; t + 9 <= corners.size(); t += 9) {
    float rec[12] = {0, 0, 1};
    std::memcpy(rec + 3, corners.data() + t, 9 * sizeof(float));
    out.append(reinterpret_cast<const char*>(rec), sizeof rec);
    out.append(2, '\0');
  }
  return out + trailer;
}

// Two triangles sharing an edge, and a third repeating a corner with -0.0.
const std::vector<float> kCorners = {0, 0, 0, 1, 0, 0, 0, 1, 0,    //
                                     1, 0, 0, 1, 1, 0, 0, 1, 0,    //
                                     -0.0f, 0, -0.0f, 0, 1, 0, 0.5f, 0.5f, 2};

TEST(StlReader, AsciiMergesIdenticalCoordinatesInOrderOfFirstAppearance) {
  const std::string stl =
      "solid test\n"
      "  facet normal 0 0 1\n    outer loop\n      vertex 0 0 0\n      vertex 1 0 0\n      vertex 0 1 0\n"
      "    endloop\n  endfacet\n"
      "facet normal nan nan nan\nouter loop\nvertex 1.0 0 0\nvertex 1 1 0\nvertex 0.0 1e0 0\nendloop\nendfacet\n"
      "facet normal 0 0 1\nouter loop\nvertex -0.0 0 -0\nvertex 0 1 0\nvertex 0.5 0.5 2\nendloop\nendfacet\n"
      "endsolid test\n";
  MeshBuffers m = read_bytes("ascii.stl", stl);
  EXPECT_EQ(m.positions, floats({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0.5f, 0.5f, 2}));
  EXPECT_EQ(m.triangles, indices({0, 1, 2, 1, 3, 2, 0, 2, 4}));
  EXPECT_FALSE(std::signbit(m.positions[0]));
}

TEST(StlReader, AsciiToleratesWhitespaceCaseAndSeveralSolids) {
  const std::string stl =
      "solid\r\nfacet normal 0 0 1 outer loop vertex 0 0 0 vertex 1 0 0 vertex 0 1 0 endloop endfacet\r\n"
      "endsolid\r\n\r\nSOLID second part\n\tFACET NORMAL 0 0 1\n\t\tOUTER LOOP\n"
      "VERTEX 1 0 0\nVERTEX\t1 1 0\n VERTEX 0 1 0 \n ENDLOOP\n ENDFACET\nENDSOLID second part";
  MeshBuffers m = read_bytes("loose.stl", stl);
  EXPECT_EQ(m.positions, floats({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0}));
  EXPECT_EQ(m.triangles, indices({0, 1, 2, 1, 3, 2}));
}

TEST(StlReader, BinaryEvenWhenTheHeaderStartsWithSolid) {
  for (const std::string header : {"binary writer", "solid written by a binary writer\nfacet"}) {
    SCOPED_TRACE(header);
    MeshBuffers m = read_bytes("binary.stl", binary_stl(header, kCorners, 3));
    EXPECT_EQ(m.positions, floats({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0.5f, 0.5f, 2}));
    EXPECT_EQ(m.triangles, indices({0, 1, 2, 1, 3, 2, 0, 2, 4}));
  }
  // Bytes after the declared triangles are ignored.
  MeshBuffers m = read_bytes("trailing.stl", binary_stl("solid x", kCorners, 2, "garbage!"));
  EXPECT_EQ(m.triangles, indices({0, 1, 2, 1, 3, 2}));
}

TEST(StlReader, BinaryGridMergesEveryShared) {
  // An n×n grid: 2n² triangles, (n+1)² distinct corners; enough to grow the hash table.
  const int n = 300;
  std::vector<float> corners;
  auto push = [&](int i, int j) { corners.insert(corners.end(), {float(i) * 0.1f, float(j) * 0.1f, float(i * j % 7)}); };
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      push(i, j), push(i + 1, j), push(i + 1, j + 1);
      push(i, j), push(i + 1, j + 1), push(i, j + 1);
    }
  MeshBuffers m = read_bytes("grid.stl", binary_stl("grid", corners, 2 * n * n));
  ASSERT_EQ(m.vertex_count(), uint32_t((n + 1) * (n + 1)));
  ASSERT_EQ(m.face_count(), uint64_t(2 * n * n));
  for (size_t k = 0; k < m.triangles.size(); ++k)
    for (int c = 0; c < 3; ++c) ASSERT_EQ(m.positions[3 * m.triangles[k] + c], corners[3 * k + c]) << k;
}

TEST(StlReader, MalformedInputsThrowNamingFileAndOffset) {
  const std::string facet = "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n";
  std::string truncated = binary_stl("x", kCorners, 3);
  truncated.resize(truncated.size() - 10);
  expect_error("truncated.stl", truncated, "byte 80: truncated binary STL: header declares 3 triangles");
  expect_error("truncsolid.stl", binary_stl("solid x", kCorners, 4), "truncated binary STL");
  expect_error("short.stl", std::string(40, 'x'), "file too short for a binary STL");
  expect_error("zero.stl", binary_stl("x", {}, 0), "declares 0 triangles");
  std::vector<float> bad = kCorners;
  bad[4] = std::nanf("");
  expect_error("nanbin.stl", binary_stl("x", bad, 3), "byte 112: coordinate is not finite in triangle 0");
  expect_error("twovert.stl",
               "solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid\n",
               "line 7: facet with 2 vertices");
  expect_error("endsinside.stl", "solid a\n" + facet + "facet normal 0 0 1\nouter loop\nvertex 0 0 0\n",
               "file ends inside a facet");
  expect_error("nanascii.stl", "solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 inf 0\n",
               "line 4: coordinate is not finite");
  expect_error("badnum.stl", "solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 1..0 0\n", "line 4: bad number");
  expect_error("token.stl", "solid a\n" + facet + "fact normal 0 0 1\n", "line 9: unexpected 'fact'");
  expect_error("outside.stl", "solid a\nvertex 0 0 0\n", "unexpected 'vertex'");
  expect_error("empty.stl", "solid a\nendsolid a\n", "no facets");
}

// ------------------------------------------------------------------------------ shared meshes

TEST(StlReader, GmshAneurysmHasManifestCounts) {
  auto path = test::shared_data_path("gmsh_aneurysm.stl");
  if (!path) GTEST_SKIP() << "shared data absent";
  MeshBuffers m = read_file(*path);
  EXPECT_EQ(m.vertex_count(), 10204u);
  EXPECT_EQ(m.face_count(), 20294u);
}

TEST(ObjOffReader, SharedMeshesMatchManifest) {
  auto manifest = test::shared_data_path("MANIFEST.tsv");
  if (!manifest) GTEST_SKIP() << "shared data absent";
  std::ifstream in(*manifest);
  std::string line;
  std::getline(in, line);  // header: name file format vertices faces ...
  int checked = 0;
  while (std::getline(in, line)) {
    std::vector<std::string> cols;
    std::stringstream ss(line);
    for (std::string c; std::getline(ss, c, '\t');) cols.push_back(c);
    if (cols.size() < 5 || (cols[2] != "OBJ" && cols[2] != "OFF")) continue;
    auto path = test::shared_data_path(cols[1]);
    if (!path) continue;
    SCOPED_TRACE(*path);
    MeshBuffers m = read_file(*path);
    EXPECT_EQ(m.vertex_count(), std::stoull(cols[3]));
    EXPECT_EQ(m.face_count(), std::stoull(cols[4]));
    ++checked;
  }
  EXPECT_GT(checked, 0);
}

TEST(ObjOffReader, BundledZstdCopiesMatchManifest) {
  for (auto [name, v, f] : {std::tuple{"cgal_fandisk.off.zst", 6475u, 12946u}, {"fertility.off.zst", 4494u, 9000u}}) {
    MeshBuffers m = read_file(test::data_path(name));
    EXPECT_EQ(m.vertex_count(), v) << name;
    EXPECT_EQ(m.face_count(), f) << name;
  }
}

}  // namespace
}  // namespace streamcvd
