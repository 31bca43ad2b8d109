// Generic read entry points: format from the extension, content sniffing when the extension
// says nothing, and the validation every read ends with.
#include <gtest/gtest.h>
#include <zstd.h>

#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

std::string write_file(const std::filesystem::path& dir, const std::string& name, const std::string& bytes) {
  std::string path = (dir / name).string();
  std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
  return path;
}

std::string zstd_compress(const std::string& bytes) {
  std::string out(ZSTD_compressBound(bytes.size()), '\0');
  size_t n = ZSTD_compress(out.data(), out.size(), bytes.data(), bytes.size(), 3);
  EXPECT_FALSE(ZSTD_isError(n));
  out.resize(n);
  return out;
}

std::string error_of(const auto& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(MeshReader, FormatFromPath) {
  EXPECT_EQ(format_from_path("a.ply"), MeshFormat::Ply);
  EXPECT_EQ(format_from_path("/x/y/B.PLY"), MeshFormat::Ply);
  EXPECT_EQ(format_from_path("mesh.obj.zst"), MeshFormat::Obj);
  EXPECT_EQ(format_from_path("mesh.Off"), MeshFormat::Off);
  EXPECT_EQ(format_from_path("MESH.STL.ZST"), MeshFormat::Stl);
  EXPECT_EQ(format_from_path("dir.ply/mesh.stl"), MeshFormat::Stl);
  for (std::string bad : {"mesh.txt", "mesh.zst", "mesh", "mesh.ply.gz", "ply", ".zst"}) {
    std::string m = error_of([&] { format_from_path(bad); });
    EXPECT_EQ(m.rfind(bad + ": ", 0), 0u) << m;
    EXPECT_NE(m.find("extension"), std::string::npos) << m;
  }
  EXPECT_TRUE(has_zst_extension("a.ply.zst"));
  EXPECT_TRUE(has_zst_extension("A.OBJ.ZsT"));
  EXPECT_FALSE(has_zst_extension("a.ply"));
  EXPECT_FALSE(has_zst_extension("zst"));
  EXPECT_FALSE(has_zst_extension("a.zst.ply"));
}

TEST(MeshReader, SniffsTheFormatWhenTheExtensionSaysNothing) {
  auto dir = test::temp_dir("sniff");
  const std::string ply =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  const std::string off = "# a comment\n\nOFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  const std::string coff = "COFF 3 1 0\n0 0 0 255 0 0 255\n1 0 0 255 0 0 255\n0 1 0 255 0 0 255\n3 0 1 2\n";
  const std::string obj = "# made by hand\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const std::string stl_ascii =
      "solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid t\n";
  std::string stl_binary(84, '\0');
  stl_binary.replace(0, 5, "solid");  // a lying header: the exact size check must win
  uint32_t one = 1;
  std::memcpy(&stl_binary[80], &one, 4);
  const float tri[12] = {0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0};
  stl_binary.append(reinterpret_cast<const char*>(tri), 48);
  stl_binary.append(2, '\0');
  for (const auto& [name, bytes] : std::vector<std::pair<std::string, std::string>>{
           {"ply", ply}, {"off", off}, {"coff", coff}, {"obj", obj}, {"stl_ascii", stl_ascii}, {"stl_binary", stl_binary}}) {
    SCOPED_TRACE(name);
    for (const std::string& file : {name + ".mesh", name + ".zst"}) {
      MeshBuffers m = read_mesh(write_file(dir, file, file.ends_with(".zst") ? zstd_compress(bytes) : bytes));
      EXPECT_EQ(m.vertex_count(), 3u);
      ASSERT_EQ(m.face_count(), 1u);
      EXPECT_EQ(m.triangles, (std::vector<uint32_t>{0, 1, 2}));
      EXPECT_EQ(m.positions[3], 1.0f);
      EXPECT_EQ(m.positions[7], 1.0f);
    }
  }
}

TEST(MeshReader, ExtensionWinsOverContent) {
  // An OFF file named .ply is read as PLY and rejected as such, naming the file and line 1.
  auto dir = test::temp_dir("ext_wins");
  std::string path = write_file(dir, "liar.ply", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  std::string m = error_of([&] { read_mesh(path); });
  EXPECT_EQ(m.rfind(path + ": line 1: ", 0), 0u) << m;
}

TEST(MeshReader, MissingEmptyAndDirectoryInputs) {
  auto dir = test::temp_dir("missing");
  std::string missing = (dir / "nope.ply").string();
  EXPECT_EQ(error_of([&] { read_mesh(missing); }).rfind(missing + ": ", 0), 0u);
  std::string empty = write_file(dir, "empty.obj", "");
  EXPECT_NE(error_of([&] { read_mesh(empty); }).find(empty), std::string::npos);
  std::string folder = (dir / "folder.ply").string();
  std::filesystem::create_directory(folder);
  EXPECT_NE(error_of([&] { read_mesh(folder); }).find(folder), std::string::npos);
}

TEST(MeshReader, ValidateSoupNamesTheCulprit) {
  MeshBuffers m;
  m.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  m.triangles = {0, 1, 2, 2, 1, 0};
  EXPECT_NO_THROW(validate_soup("ok.ply", m));

  MeshBuffers empty;
  EXPECT_EQ(error_of([&] { validate_soup("e.ply", empty); }), "e.ply: no vertices");

  MeshBuffers nan = m;
  nan.positions[4] = std::numeric_limits<float>::quiet_NaN();
  std::string msg = error_of([&] { validate_soup("n.ply", nan); });
  EXPECT_EQ(msg.rfind("n.ply: vertex 1 ", 0), 0u) << msg;
  EXPECT_NE(msg.find("non-finite"), std::string::npos) << msg;

  MeshBuffers inf = m;
  inf.positions[8] = -std::numeric_limits<float>::infinity();
  msg = error_of([&] { validate_soup("i.ply", inf); });
  EXPECT_EQ(msg.rfind("i.ply: vertex 2 ", 0), 0u) << msg;

  MeshBuffers range = m;
  range.triangles[4] = 3;
  EXPECT_EQ(error_of([&] { validate_soup("r.ply", range); }), "r.ply: face 1 uses vertex 3 of 3");

  MeshBuffers ragged = m;
  ragged.positions.pop_back();
  EXPECT_NE(error_of([&] { validate_soup("g.ply", ragged); }).find("multiple of 3"), std::string::npos);
  ragged = m;
  ragged.triangles.pop_back();
  EXPECT_NE(error_of([&] { validate_soup("g.ply", ragged); }).find("multiple of 3"), std::string::npos);
}

}  // namespace
}  // namespace streamcvd
