// PLY reader: every encoding, scalar type and layout the format allows, compressed copies, and
// malformed files that must fail with the file name and the line or byte of the problem.
#include <gtest/gtest.h>
#include <zstd.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "tests/ply_builder.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

using test::build_ply;
using test::Elem;
using test::Enc;
using test::enc_name;
using test::kAllEncodings;
using test::Prop;

// Vertex element: x, y, z from `pos`, every other property filled with small made-up values.
Elem vertex_element(const std::vector<double>& pos, const std::vector<Prop>& props) {
  Elem e{"vertex", props, {}};
  for (size_t i = 0; i < pos.size() / 3; ++i) {
    std::vector<std::vector<double>> rec;
    for (const Prop& p : props) {
      if (p.name == "x" || p.name == "y" || p.name == "z") rec.push_back({pos[3 * i + (p.name[0] - 'x')]});
      else if (!p.count_type.empty()) rec.push_back({double(i % 3), 1.0});
      else rec.push_back({double((i * 7) % 100)});
    }
    e.records.push_back(rec);
  }
  return e;
}

Elem face_element(const std::vector<std::vector<uint32_t>>& polys, const std::vector<Prop>& props) {
  Elem e{"face", props, {}};
  for (size_t i = 0; i < polys.size(); ++i) {
    std::vector<std::vector<double>> rec;
    for (const Prop& p : props) {
      if (p.name == "vertex_indices" || p.name == "vertex_index") rec.push_back(std::vector<double>(polys[i].begin(), polys[i].end()));
      else if (!p.count_type.empty()) rec.push_back({0.5, 0.25, double(i)});
      else rec.push_back({double(i % 5)});
    }
    e.records.push_back(rec);
  }
  return e;
}

// The reference mesh: a triangle, a quad, a pentagon and a triangle over 6 vertices.
const std::vector<double> kPos = {0.1,  -2.5, 3.14159265358979, 1e-3, 12345.678, -0.0, 1.0 / 3, 2.0 / 3, -7,
                                  100, 200.5, 300.25,           -1.5, 0,         2,    4,       5e-20,   6e20};
const std::vector<std::vector<uint32_t>> kPolys = {{0, 1, 2}, {0, 2, 3, 4}, {1, 2, 3, 4, 5}, {5, 4, 3}};
const std::vector<uint32_t> kTriangles = {0, 1, 2, 0, 2, 3, 0, 3, 4, 1, 2, 3, 1, 3, 4, 1, 4, 5, 5, 4, 3};

std::string write_file(const std::filesystem::path& dir, const std::string& name, const std::string& bytes) {
  std::string path = (dir / name).string();
  std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
  return path;
}

std::string zstd_compress(const std::string& bytes, int level = 3) {
  std::string out(ZSTD_compressBound(bytes.size()), '\0');
  size_t n = ZSTD_compress(out.data(), out.size(), bytes.data(), bytes.size(), level);
  EXPECT_FALSE(ZSTD_isError(n));
  out.resize(n);
  return out;
}

// Expected float32 positions for `pos` (double → float rounding, as the reader does).
std::vector<float> as_floats(const std::vector<double>& pos) { return std::vector<float>(pos.begin(), pos.end()); }

// Bit-exact comparison: -0.0 must stay -0.0.
void expect_positions(const MeshBuffers& m, const std::vector<float>& want) {
  ASSERT_EQ(m.positions.size(), want.size());
  for (size_t i = 0; i < want.size(); ++i)
    EXPECT_EQ(std::bit_cast<uint32_t>(m.positions[i]), std::bit_cast<uint32_t>(want[i]))
        << "coordinate " << i << ": " << m.positions[i] << " vs " << want[i];
}

void expect_reference(const MeshBuffers& m, const std::vector<float>& pos) {
  EXPECT_EQ(m.vertex_count(), 6u);
  EXPECT_EQ(m.face_count(), 7u);
  EXPECT_EQ(m.polygons_split, 2u);
  EXPECT_EQ(m.triangles, kTriangles);
  expect_positions(m, pos);
}

// Reads `path` expecting InputError whose one-line message names the file and every `parts`.
void expect_error(const std::string& path, const std::vector<std::string>& parts) {
  try {
    read_mesh(path);
    ADD_FAILURE() << "no error for " << path;
  } catch (const InputError& e) {
    std::string m = e.what();
    EXPECT_NE(m.find(path), std::string::npos) << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
    for (const std::string& p : parts) EXPECT_NE(m.find(p), std::string::npos) << "'" << p << "' not in: " << m;
  }
}

TEST(PlyReader, FloatVerticesWithExtraPropertiesInEveryEncoding) {
  auto dir = test::temp_dir("ply_float");
  std::vector<Prop> vprops = {{"float", "x", ""},     {"float", "y", ""},    {"float", "z", ""},
                              {"float", "nx", ""},    {"float", "ny", ""},   {"float", "nz", ""},
                              {"uchar", "red", ""},   {"uchar", "green", ""}, {"uchar", "blue", ""},
                              {"float", "confidence", ""}};
  for (Enc enc : kAllEncodings) {
    SCOPED_TRACE(enc_name(enc));
    std::string bytes = build_ply(enc, {vertex_element(kPos, vprops), face_element(kPolys, {{"int", "vertex_indices", "uchar"}})},
                                  "comment made by ply_reader_test\nobj_info nothing\n");
    std::string path = write_file(dir, std::string(enc_name(enc)) + ".ply", bytes);
    expect_reference(read_mesh(path), as_floats(kPos));
    // Read from standard-input-like content too: no extension, the format sniffed.
    expect_reference(read_mesh(write_file(dir, std::string(enc_name(enc)) + ".mesh", bytes)), as_floats(kPos));
  }
}

TEST(PlyReader, PlainXyzAndUintIndices) {
  // "float x y z" only: the 12-byte-record bulk copy; uint indices: the fast face path.
  auto dir = test::temp_dir("ply_plain");
  for (Enc enc : kAllEncodings) {
    SCOPED_TRACE(enc_name(enc));
    std::string bytes = build_ply(enc, {vertex_element(kPos, {{"float32", "x", ""}, {"float32", "y", ""}, {"float32", "z", ""}}),
                                        face_element(kPolys, {{"uint", "vertex_indices", "uint8"}})});
    expect_reference(read_mesh(write_file(dir, "m.ply", bytes)), as_floats(kPos));
  }
}

TEST(PlyReader, DoubleCoordinatesOddOrderExtraElements) {
  auto dir = test::temp_dir("ply_double");
  // z before x, a list property inside the vertex element, an "edge" element between vertex and
  // face, a "material" element with a list before the vertices, face list named vertex_index with
  // a flags scalar before it and a texcoord list after it.
  Elem material{"material", {{"uchar", "ambient_red", ""}, {"float", "coeffs", "int"}}, {{{10}, {1.5, 2.5}}, {{20}, {}}}};
  Elem edge{"edge", {{"int", "vertex1", ""}, {"int32", "vertex2", ""}}, {{{0}, {1}}, {{1}, {2}}, {{2}, {0}}}};
  std::vector<Prop> vprops = {{"double", "z", ""}, {"ushort", "flags", ""}, {"float64", "x", ""},
                              {"uchar", "uv", "uchar"}, {"double", "y", ""}};
  std::vector<Prop> fprops = {{"uchar", "flags", ""}, {"uint", "vertex_index", "ushort"}, {"float", "texcoord", "uchar"}};
  for (Enc enc : kAllEncodings) {
    SCOPED_TRACE(enc_name(enc));
    std::string bytes = build_ply(enc, {material, vertex_element(kPos, vprops), edge, face_element(kPolys, fprops)});
    expect_reference(read_mesh(write_file(dir, "m.ply", bytes)), as_floats(kPos));
  }
}

TEST(PlyReader, EveryCountAndIndexType) {
  auto dir = test::temp_dir("ply_index");
  const std::vector<std::pair<std::string, std::string>> combos = {
      {"uchar", "int"},    {"uchar", "uint"},  {"ushort", "ushort"}, {"int", "int"},    {"uint", "uint"},
      {"char", "short"},   {"uint8", "int32"}, {"int16", "uint16"},  {"uint32", "uchar"}, {"int8", "uint8"}};
  for (Enc enc : kAllEncodings)
    for (const auto& [count, index] : combos) {
      SCOPED_TRACE(std::string(enc_name(enc)) + " " + count + " " + index);
      std::string bytes = build_ply(enc, {vertex_element(kPos, {{"float", "x", ""}, {"float", "y", ""}, {"float", "z", ""}}),
                                          face_element(kPolys, {{index, "vertex_indices", count}})});
      expect_reference(read_mesh(write_file(dir, "m.ply", bytes)), as_floats(kPos));
    }
}

TEST(PlyReader, IntegerCoordinateTypes) {
  auto dir = test::temp_dir("ply_intcoord");
  const std::vector<double> pos = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 100, 101, 127};
  const std::vector<double> neg = {0, -1, 2, -3, 4, -5, 6, -7, 8, -9, 10, -11, 12, -13, 14, -100, 101, -128};
  for (std::string t : {"char", "uchar", "short", "ushort", "int", "uint", "int8", "uint8", "int16", "uint16", "int32",
                        "uint32", "float32", "float64"}) {
    const bool is_signed = t == "char" || t == "short" || t == "int" || t[0] == 'i' || t[0] == 'f';
    const auto& p = is_signed ? neg : pos;
    for (Enc enc : kAllEncodings) {
      SCOPED_TRACE(t + " " + enc_name(enc));
      std::string bytes = build_ply(enc, {vertex_element(p, {{t, "x", ""}, {t, "y", ""}, {t, "z", ""}}),
                                          face_element(kPolys, {{"int", "vertex_indices", "uchar"}})});
      expect_reference(read_mesh(write_file(dir, "m.ply", bytes)), as_floats(p));
    }
  }
}

TEST(PlyReader, AsciiWhitespaceLineEndingsAndCompressedCopies) {
  auto dir = test::temp_dir("ply_ws");
  std::string text = build_ply(Enc::Ascii, {vertex_element(kPos, {{"float", "x", ""}, {"float", "y", ""}, {"float", "z", ""}}),
                                            face_element(kPolys, {{"int", "vertex_indices", "uchar"}})});
  std::string crlf, cr, messy;
  for (char c : text) crlf += c == '\n' ? std::string("\r\n") : std::string(1, c);
  for (char c : text) cr += c == '\n' ? '\r' : c;
  // Tabs, doubled blanks, trailing blanks, blank lines in the body, no final newline.
  size_t body = text.find("end_header\n") + 11;
  messy = text.substr(0, body) + "\n  \t\n";
  for (size_t i = body; i < text.size(); ++i) messy += text[i] == ' ' ? std::string(" \t ") : text[i] == '\n' ? std::string(" \n\n") : std::string(1, text[i]);
  while (messy.back() == '\n' || messy.back() == ' ') messy.pop_back();
  for (const auto& [name, bytes] : std::vector<std::pair<std::string, std::string>>{{"crlf", crlf}, {"cr", cr}, {"messy", messy}}) {
    SCOPED_TRACE(name);
    expect_reference(read_mesh(write_file(dir, name + ".ply", bytes)), as_floats(kPos));
    expect_reference(read_mesh(write_file(dir, name + ".ply.zst", zstd_compress(bytes))), as_floats(kPos));
  }
}

TEST(PlyReader, LargeMeshAcrossBufferBoundaries) {
  // A ~3 MB ascii file crosses the reader's 1 MiB blocks many times, in the middle of lines.
  auto dir = test::temp_dir("ply_large");
  MeshBuffers sphere = make_icosphere(6);
  std::vector<double> pos(sphere.positions.begin(), sphere.positions.end());
  std::vector<std::vector<uint32_t>> tris;
  for (size_t f = 0; f < sphere.face_count(); ++f)
    tris.push_back({sphere.triangles[3 * f], sphere.triangles[3 * f + 1], sphere.triangles[3 * f + 2]});
  for (Enc enc : kAllEncodings) {
    SCOPED_TRACE(enc_name(enc));
    std::string bytes = build_ply(enc, {vertex_element(pos, {{"float", "x", ""}, {"float", "y", ""}, {"float", "z", ""}, {"float", "quality", ""}}),
                                        face_element(tris, {{"int", "vertex_indices", "uchar"}})});
    if (enc == Enc::Ascii) {
      ASSERT_GT(bytes.size(), size_t(2) << 20);
      std::string cr = bytes;  // lone-'\r' line ends, so that blocks are cut at '\r'
      std::replace(cr.begin(), cr.end(), '\n', '\r');
      MeshBuffers m = read_mesh(write_file(dir, "cr.ply", cr));
      EXPECT_EQ(m.triangles, sphere.triangles);
      expect_positions(m, sphere.positions);
    }
    for (std::string name : {"m.ply", "m.ply.zst"}) {
      SCOPED_TRACE(name);
      MeshBuffers m = read_mesh(write_file(dir, name, name.ends_with(".zst") ? zstd_compress(bytes, 1) : bytes));
      EXPECT_EQ(m.triangles, sphere.triangles);
      EXPECT_EQ(m.polygons_split, 0u);
      expect_positions(m, sphere.positions);
    }
  }
}

TEST(PlyReader, FacesBeforeVertices) {
  auto dir = test::temp_dir("ply_faces_first");
  for (Enc enc : kAllEncodings) {
    SCOPED_TRACE(enc_name(enc));
    std::string bytes = build_ply(enc, {face_element(kPolys, {{"int", "vertex_indices", "uchar"}}),
                                        vertex_element(kPos, {{"float", "x", ""}, {"float", "y", ""}, {"float", "z", ""}})});
    expect_reference(read_mesh(write_file(dir, "m.ply", bytes)), as_floats(kPos));
  }
}

TEST(PlyReader, PointCloudWithoutFacesIsRejected) {
  // No element to read faces from, or an empty one: every command needs triangles, so the read
  // fails at once, naming what the file has.
  auto dir = test::temp_dir("ply_points");
  const Elem points = vertex_element(kPos, {{"float", "x", ""}, {"float", "y", ""}, {"float", "z", ""}});
  for (Enc enc : kAllEncodings) {
    SCOPED_TRACE(enc_name(enc));
    expect_error(write_file(dir, "p.ply", build_ply(enc, {points})), {"line 7", "no face element", "vertex (6)"});
    expect_error(write_file(dir, "e.ply", build_ply(enc, {points, face_element({}, {{"int", "vertex_indices", "uchar"}})})),
                 {"no faces", "6 vertices"});
  }
}

TEST(PlyReader, BundledBunny) {
  MeshBuffers m = read_mesh(test::data_path("bun_zipper_res2.ply"));
  EXPECT_EQ(m.vertex_count(), 8171u);
  EXPECT_EQ(m.face_count(), 16301u);
  EXPECT_EQ(m.polygons_split, 0u);
  // First vertex line of the file: "-0.036872 0.127727 0.00440925 0.850855 0.5".
  EXPECT_EQ(m.positions[0], -0.036872f);
  EXPECT_EQ(m.positions[1], 0.127727f);
  EXPECT_EQ(m.positions[2], 0.00440925f);
}

// ---- malformed input ---------------------------------------------------------------------

const std::string kAsciiHead =  // 9 lines: the body starts on line 10
    "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
    "element face 1\nproperty list uchar int vertex_indices\nend_header\n";

TEST(PlyReader, HeaderErrors) {
  auto dir = test::temp_dir("ply_bad_header");
  auto check = [&](const std::string& name, const std::string& bytes, const std::vector<std::string>& parts) {
    SCOPED_TRACE(name);
    expect_error(write_file(dir, name + ".ply", bytes), parts);
  };
  check("magic", "plx\nformat ascii 1.0\n", {"line 1", "not a PLY file"});
  check("magic_word", "plyfile\nformat ascii 1.0\n", {"line 1", "not a PLY file"});
  check("format", "ply\nformat binary_middle_endian 1.0\nelement vertex 1\nproperty float x\nend_header\n", {"line 2", "unknown PLY format"});
  check("version", "ply\nformat ascii 2.0\nend_header\n", {"line 2", "version"});
  check("no_format", "ply\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n", {"line 6", "format"});
  check("no_end", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", {"line 4", "end_header"});
  check("keyword", "ply\nformat ascii 1.0\nelemnt vertex 1\nend_header\n", {"line 3", "unknown header keyword 'elemnt'"});
  check("early_property", "ply\nformat ascii 1.0\nproperty float x\nend_header\n", {"line 3", "property before any element"});
  check("type", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n", {"line 4", "unknown property type"});
  check("count", "ply\nformat ascii 1.0\nelement vertex -5\nend_header\n", {"line 3", "element"});
  check("float_count", "ply\nformat ascii 1.0\nelement face 1\nproperty list float int vertex_indices\nend_header\n", {"line 4", "count type"});
  check("no_vertices", "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n", {"no vertices"});
  check("no_vertex_element", "ply\nformat ascii 1.0\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n", {"no vertices"});
  check("no_z", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n0 0\n", {"x, y or z"});
  check("list_x", "ply\nformat ascii 1.0\nelement vertex 1\nproperty list uchar float x\nproperty float y\nproperty float z\nend_header\n", {"list"});
  check("no_indices", kAsciiHead.substr(0, kAsciiHead.find("property list")) + "property list uchar int corners\nend_header\n", {"vertex_indices"});
  check("float_indices", kAsciiHead.substr(0, kAsciiHead.find("property list")) + "property list uchar float vertex_indices\nend_header\n", {"integer"});
}

TEST(PlyReader, AsciiBodyErrorsNameTheLine) {
  auto dir = test::temp_dir("ply_bad_ascii");
  auto check = [&](const std::string& name, const std::string& body, const std::vector<std::string>& parts) {
    SCOPED_TRACE(name);
    expect_error(write_file(dir, name + ".ply", kAsciiHead + body), parts);
  };
  check("nan", "0 0 0\n1 0 nan\n0 1 0\n3 0 1 2\n", {"line 11", "vertex 1", "non-finite"});
  check("inf", "0 0 0\n1 0 0\n0 -inf 0\n3 0 1 2\n", {"line 12", "vertex 2", "non-finite"});
  check("overflow", "0 0 0\n1 0 0\n0 1e999 0\n3 0 1 2\n", {"line 12", "vertex 2"});
  check("word", "0 0 0\n1 abc 0\n0 1 0\n3 0 1 2\n", {"line 11", "non-numeric", "'abc'"});
  check("two_dots", "0 0 0\n1 1.2.3 0\n0 1 0\n3 0 1 2\n", {"line 11", "non-numeric", "'1.2.3'"});
  check("too_few", "0.0 0.0 0.0\n1 0\n0 1 0\n3 0 1 2\n", {"line 11", "too few values"});
  check("too_many", "0 0 0\n1 0 0 7\n0 1 0\n3 0 1 2\n", {"line 11", "more values"});
  check("two_corners", "0.0 0.0 0.0\n1 0 0\n0 1 0\n2 0 1\n", {"line 13", "face 0", "at least 3"});
  check("out_of_range", "0 0 0\n1 0 0\n0 1 0\n3 0 1 3\n", {"line 13", "face 0", "vertex 3 of 3"});
  check("negative", "0 0 0\n1 0 0\n0 1 0\n3 0 -1 2\n", {"line 13", "negative vertex index -1"});
  check("float_index", "0 0 0\n1 0 0\n0 1 0\n3 0 1.5 2\n", {"line 13", "not an integer"});
  check("short_face", "0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n", {"line 13", "too few values"});
  // Long enough numbers that the byte-count check passes: the reader itself finds the gap.
  check("truncated", "0.000000000 0.000000000 0.000000000\n1.000000000 0.000000000 0.000000000\n", {"line 12", "unexpected end of file", "vertex 2 of 3"});
}

TEST(PlyReader, BinaryBodyErrorsNameTheByte) {
  auto dir = test::temp_dir("ply_bad_binary");
  const std::vector<double> pos = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  const Elem v = vertex_element(pos, {{"float", "x", ""}, {"float", "y", ""}, {"float", "z", ""}});
  for (Enc enc : {Enc::Le, Enc::Be}) {
    SCOPED_TRACE(enc_name(enc));
    auto ply = [&](const Elem& vert, const std::vector<std::vector<uint32_t>>& polys) {
      return build_ply(enc, {vert, face_element(polys, {{"int", "vertex_indices", "uchar"}})});
    };
    const std::string good = ply(v, {{0, 1, 2}});
    const size_t head = good.find("end_header\n") + 11;
    auto at = [&](size_t byte) { return "byte " + std::to_string(byte); };

    Elem nan_vertex = v;
    nan_vertex.records[1][2][0] = std::numeric_limits<double>::quiet_NaN();
    expect_error(write_file(dir, "nan.ply", ply(nan_vertex, {{0, 1, 2}})), {at(head + 12), "vertex 1", "non-finite"});
    Elem inf_vertex = v;
    inf_vertex.records[2][0][0] = -std::numeric_limits<double>::infinity();
    expect_error(write_file(dir, "inf.ply", ply(inf_vertex, {{0, 1, 2}})), {at(head + 24), "vertex 2", "non-finite"});
    expect_error(write_file(dir, "range.ply", ply(v, {{0, 1, 2}, {2, 1, 3}})), {at(head + 36 + 13), "face 1", "vertex 3 of 3"});
    expect_error(write_file(dir, "neg.ply", ply(v, {{0, 1, 2}, {2, 1, uint32_t(-1)}})), {at(head + 36 + 13), "negative vertex index -1"});
    // Trailing bytes after the last element are ignored; here they keep the byte-count check quiet.
    expect_error(write_file(dir, "two.ply", ply(v, {{0, 1, 2}, {2, 1}}) + "padding"), {at(head + 36 + 13), "face 1", "at least 3"});
    // Shorter than the header's counts allow: caught before reading the body.
    expect_error(write_file(dir, "short.ply", ply(v, {{0, 1, 2}, {2, 1}})), {at(head), "header counts need at least 62 bytes of data but only 58 follow"});
    // Quad then a triangle cut after two indices: the byte-count check passes, the body ends early.
    std::string cut = ply(v, {{0, 1, 2, 0}, {0, 1, 2}});
    cut.resize(cut.size() - 4);
    expect_error(write_file(dir, "cut.ply", cut), {at(cut.size()), "unexpected end of file", "face 1 of 2"});
    // A generic-path face (extra property) cut inside its index list.
    std::string cut2 = build_ply(enc, {v, face_element({{0, 1, 2}}, {{"int", "vertex_indices", "uint"}, {"uchar", "flags", ""}})});
    cut2.resize(cut2.size() - 2);
    expect_error(write_file(dir, "cut2.ply.zst", zstd_compress(cut2)), {at(cut2.size()), "unexpected end of file", "face 0 of 1"});
  }
}

TEST(PlyReader, HugeCountsFailFastWithoutAllocating) {
  auto dir = test::temp_dir("ply_huge");
  const std::string head = "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\nproperty float x\n"
                           "property float y\nproperty float z\nelement face 1\nproperty list uchar int vertex_indices\n"
                           "end_header\n";
  std::string small = head + std::string(24, '\0');
  ASSERT_LT(small.size(), 250u);
  expect_error(write_file(dir, "huge.ply", small), {"byte " + std::to_string(head.size()), "header counts need"});
  // Compressed: no exact size bound before reading, so the reader must stop at the real end.
  expect_error(write_file(dir, "huge.ply.zst", zstd_compress(small)), {"unexpected end of file", "vertex 2 of 4000000000"});
  std::string ascii = "ply\nformat ascii 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n"
                      "property float z\nelement face 4000000000\nproperty list uint uint vertex_indices\nend_header\n0 0 0\n";
  expect_error(write_file(dir, "huge_ascii.ply", ascii), {"header counts need"});
  expect_error(write_file(dir, "huge_ascii.ply.zst", zstd_compress(ascii)), {"line 11", "unexpected end of file"});
  // A face claiming 4 billion corners in a tiny compressed file.
  std::string corners = "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                        "property float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n" +
                        std::string(36, '\0') + std::string("\xff\xff\xff\xff", 4) + std::string(12, '\0');
  expect_error(write_file(dir, "corners.ply.zst", zstd_compress(corners)), {"unexpected end of file", "face 0 of 1"});
}

}  // namespace
}  // namespace streamcvd
