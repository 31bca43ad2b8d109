// Vertex attributes in the writers (streaming/io/mesh_io.h: PLY properties with their names and
// types, integers rounded and clamped; OBJ "v x y z r g b"; none in OFF and STL) and through the
// streamed subdivision (midpoints get their edge's mean).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/store/store.h"
#include "streamcvd/streaming/store/subdivision_stream.h"
#include "tests/cli_runner.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

namespace fs = std::filesystem;

MeshBuffers triangle() {
  MeshBuffers m;
  m.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  m.triangles = {0, 1, 2};
  return m;
}

const std::vector<VertexAttribute> kEveryType = {
    {"a_char", ScalarType::I8},   {"a_uchar", ScalarType::U8},  {"a_short", ScalarType::I16},
    {"a_ushort", ScalarType::U16}, {"a_int", ScalarType::I32},   {"a_uint", ScalarType::U32},
    {"a_float", ScalarType::F32},  {"a_double", ScalarType::F64}};

TEST(AttributeWriter, PlyKeepsNamesAndTypesRoundingAndClampingIntegers) {
  const fs::path dir = test::temp_dir("attribute_writer");
  const float nan = std::numeric_limits<float>::quiet_NaN();
  // Per vertex, one value per type: out of range low, out of range high, halves and NaN.
  const std::vector<float> values = {
      -200.4f, 300.2f, 12.5f,  -1.0f,   3.7f,  -5.0f, 0.1f,  0.1f,   // vertex 0
      127.6f,  254.5f, -12.5f, 70000.f, -3.7f, 5e9f,  -2.5f, 1e30f,  // vertex 1
      nan,     nan,    nan,    nan,     nan,   nan,   7.0f,  -0.0f};  // vertex 2
  const std::vector<float> expected = {
      -128, 255, 13,  0,     4,  0,           0.1f,  0.1f,
      127,  255, -13, 65535, -4, 4294967295.f, -2.5f, 1e30f,
      0,    0,   0,   0,     0,  0,           7.0f,  -0.0f};
  const MeshBuffers m = triangle();
  for (bool ascii : {false, true}) {
    SCOPED_TRACE(ascii ? "ascii" : "binary");
    const std::string path = (dir / (ascii ? "a.ply" : "b.ply")).string();
    WriteOptions o;
    o.ascii = ascii;
    o.attributes = {kEveryType, values};
    write_mesh(path, m.view(), o);
    const std::string bytes = test::slurp(path);
    EXPECT_NE(bytes.find("property float z\nproperty char a_char\nproperty uchar a_uchar\nproperty short a_short\n"
                         "property ushort a_ushort\nproperty int a_int\nproperty uint a_uint\nproperty float a_float\n"
                         "property double a_double\nelement face 1\n"),
              std::string::npos)
        << bytes.substr(0, 400);
    const MeshWithAttributes back = read_mesh_with_attributes(path);
    EXPECT_EQ(back.mesh.positions, m.positions);
    EXPECT_EQ(back.mesh.triangles, m.triangles);
    ASSERT_EQ(back.attributes.size(), kEveryType.size());
    for (size_t k = 0; k < kEveryType.size(); ++k) {
      EXPECT_EQ(back.attributes[k].name, kEveryType[k].name);
      EXPECT_EQ(back.attributes[k].type, kEveryType[k].type);
    }
    ASSERT_EQ(back.values.size(), expected.size());
    for (size_t i = 0; i < expected.size(); ++i) EXPECT_EQ(back.values[i], expected[i]) << "value " << i;
  }
  std::error_code ec;
  fs::remove_all(dir, ec);
}

TEST(AttributeWriter, ObjGetsColoursInUnitRangeOthersAreDropped) {
  const fs::path dir = test::temp_dir("attribute_writer_obj");
  const MeshBuffers m = triangle();
  const std::vector<VertexAttribute> names = {
      {"confidence", ScalarType::F32}, {"blue", ScalarType::U8}, {"green", ScalarType::U8}, {"red", ScalarType::U8}};
  const std::vector<float> values = {0.5f, 0, 0, 255, 0.5f, 51, 102, 300, 0.5f, 255, 127.5f, 0};
  WriteOptions o;
  o.attributes = {names, values};
  const std::string path = (dir / "c.obj").string();
  write_mesh(path, m.view(), o);
  std::istringstream text(test::slurp(path));
  std::vector<std::string> lines;
  for (std::string line; std::getline(text, line);)
    if (line.rfind("v ", 0) == 0) lines.push_back(line);
  // red green blue in that order, uchar / 255 (300 clamps to 1).
  EXPECT_EQ(lines, (std::vector<std::string>{"v 0 0 0 1 0 0", "v 1 0 0 1 0.4 0.2", "v 0 1 0 0 0.5 1"}));
  EXPECT_EQ(attributes_written(MeshFormat::Obj, names), (std::vector<size_t>{3, 2, 1}));
  EXPECT_EQ(attributes_written(MeshFormat::Ply, names), (std::vector<size_t>{0, 1, 2, 3}));
  EXPECT_TRUE(attributes_written(MeshFormat::Off, names).empty());
  EXPECT_TRUE(attributes_written(MeshFormat::Stl, names).empty());
  // Without all three channels an OBJ vertex is plain "v x y z"; OFF and STL are the files
  // written without attributes.
  const std::vector<VertexAttribute> two(names.begin(), names.begin() + 3);
  const std::vector<float> two_values = {0.5f, 0, 0, 0.5f, 1, 1, 0.5f, 2, 2};
  for (const char* name : {"p.obj", "p.off", "p.stl"}) {
    const std::string plain = (dir / (std::string("plain_") + name)).string(), with = (dir / name).string();
    write_mesh(plain, m.view());
    WriteOptions w;
    w.attributes = {two, two_values};
    write_mesh(with, m.view(), w);
    EXPECT_EQ(test::slurp(with), test::slurp(plain)) << name;
  }
  // Rows that do not match the vertex count are a caller bug: refused, no file.
  WriteOptions bad;
  bad.attributes = {names, std::span<const float>(values).first(8)};
  EXPECT_THROW(write_mesh((dir / "bad.ply").string(), m.view(), bad), std::invalid_argument);
  EXPECT_FALSE(fs::exists(dir / "bad.ply"));
  std::error_code ec;
  fs::remove_all(dir, ec);
}

// Collects a streamed mesh with its attribute rows.
struct Collect final : MeshSink {
  MeshHeaderInfo header;
  std::vector<float> xyz, rows;
  std::vector<uint32_t> corners;
  void begin(const MeshHeaderInfo& h) override { header = h; }
  void vertices(std::span<const float> p, std::span<const float> a) override {
    xyz.insert(xyz.end(), p.begin(), p.end());
    rows.insert(rows.end(), a.begin(), a.end());
  }
  void triangles(std::span<const uint32_t> c) override { corners.insert(corners.end(), c.begin(), c.end()); }
  void end(const ReadStats&) override {}
};

TEST(AttributeWriter, SubdivisionMidpointsTakeTheirEdgesMean) {
  const MeshBuffers sphere = make_icosphere(2);
  const MeshStore store = MeshStore::build(sphere.view());
  const MeshView view = store.view();
  // Two attributes linear in the position: their mean at a midpoint is their value there.
  const std::vector<VertexAttribute> names = {{"red", ScalarType::U8}, {"confidence", ScalarType::F32}};
  std::vector<float> rows;
  auto f = [](const float* p) { return std::array<double, 2>{100 + 50.0 * p[0], p[1] - 2.0 * p[2]}; };
  for (uint32_t v = 0; v < view.vertex_count(); ++v)
    for (double x : f(&view.positions[3 * size_t(v)])) rows.push_back(float(x));
  Collect out;
  stream_subdivision(view, out, ram_storage(), {names, rows}, 7);  // small blocks: rows split across blocks
  ASSERT_EQ(out.header.attributes.size(), 2u);
  EXPECT_EQ(out.header.attributes[0].name, "red");
  EXPECT_EQ(out.header.attributes[0].type, ScalarType::U8);
  const size_t V = out.xyz.size() / 3;
  ASSERT_EQ(out.rows.size(), 2 * V);
  ASSERT_GT(V, size_t(view.vertex_count()));
  for (size_t v = 0; v < V; ++v) {
    const std::array<double, 2> want = f(&out.xyz[3 * v]);
    for (int k = 0; k < 2; ++k) EXPECT_NEAR(out.rows[2 * v + k], want[k], 1e-4) << "vertex " << v;
  }
  for (size_t i = 0; i < rows.size(); ++i) EXPECT_EQ(out.rows[i], rows[i]);  // input vertices unchanged
  // Without attributes the stream has none.
  Collect plain;
  stream_subdivision(view, plain);
  EXPECT_TRUE(plain.header.attributes.empty());
  EXPECT_TRUE(plain.rows.empty());
  EXPECT_EQ(plain.xyz, out.xyz);
}

}  // namespace
}  // namespace streamcvd
