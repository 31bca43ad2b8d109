// PLY triangle strips (`element tristrips`) and vertex attributes: a hand-written strip fixture
// with exact triangles, strips of a real mesh (greedy stripifier) read back as the same oriented
// faces, in every encoding and across the ascii reader's windows, strip errors with their
// position, and attribute values as stored.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <fstream>
#include <string>
#include <unordered_map>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/shapes.h"
#include "fuzz/fuzz_common.h"
#include "streamcvd/streaming/io/mesh_reader.h"
#include "tests/ply_builder.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

namespace fs = std::filesystem;
using test::build_ply;
using test::Elem;
using test::Enc;
using test::enc_name;
using test::kAllEncodings;
using test::Prop;
using Triangle = std::array<uint32_t, 3>;

std::string write_file(const fs::path& dir, const std::string& name, const std::string& bytes) {
  const std::string path = (dir / name).string();
  std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
  return path;
}

std::string error_of(const auto& fn) {
  try {
    fn();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

Elem xyz_vertices(const std::vector<float>& pos) {
  Elem e{"vertex", {{"float", "x", ""}, {"float", "y", ""}, {"float", "z", ""}}, {}};
  for (size_t i = 0; i + 2 < pos.size(); i += 3) e.records.push_back({{pos[i]}, {pos[i + 1]}, {pos[i + 2]}});
  return e;
}

/// `tristrips` element: one record per list.
Elem strips_element(const std::vector<std::vector<int64_t>>& lists, const std::string& index = "int",
                    const std::string& count = "int") {
  Elem e{"tristrips", {{index, "vertex_indices", count}}, {}};
  for (const auto& l : lists) e.records.push_back({std::vector<double>(l.begin(), l.end())});
  return e;
}

/// Streams `path` in small blocks through the contract checks; returns the sink.
fuzz::RecordingSink stream(const std::string& path, uint32_t block = 5) {
  fuzz::RecordingSink sink(block);
  ReadOptions options;
  options.block = block;
  read_mesh_stream(path, sink, options);
  EXPECT_EQ(sink.violation, "");
  return sink;
}

std::vector<Triangle> triangles_of(const std::vector<uint32_t>& ids) {
  std::vector<Triangle> t;
  for (size_t i = 0; i + 2 < ids.size(); i += 3) t.push_back({ids[i], ids[i + 1], ids[i + 2]});
  return t;
}

// ---- the hand-written fixture -----------------------------------------------------------

const std::vector<float> kEight = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0, 0, 2, 0, 1, 2, 0, 0, 3, 0, 1, 3, 0};
// Record 0: two strips separated by -1. Record 1: strips 0 2 4 and 6 1 3 joined by repeating
// 4 and 6 (4 degenerate triangles), no -1 at the end. Record 2: restarts and a lone index.
const std::vector<std::vector<int64_t>> kStrips = {{0, 1, 2, 3, -1, 4, 5, 6, 7}, {0, 2, 4, 4, 6, 6, 1, 3}, {-1, -1, 5}};
// Even triangles (s[i], s[i+1], s[i+2]), odd ones (s[i+1], s[i], s[i+2]); record 1's last
// kept triangle is i = 5 (odd) of its list.
const std::vector<Triangle> kStripTriangles = {{0, 1, 2}, {2, 1, 3}, {4, 5, 6}, {6, 5, 7}, {0, 2, 4}, {1, 6, 3}};

TEST(PlyStrips, HandWrittenStripsGiveTheExactTriangles) {
  const fs::path dir = test::temp_dir("ply_strips");
  // (index, count) types: every integer type on both sides. A -1 in an unsigned list is stored
  // as its all-ones value (255, 65535, 2^32-1), which restarts the strip as -1 does.
  const std::vector<std::pair<std::string, std::string>> types = {
      {"int", "int"},   {"int", "uchar"},    {"uint", "uint"},   {"uchar", "uchar"},
      {"char", "short"}, {"ushort", "ushort"}, {"short", "uint"}, {"uint", "char"}};
  for (Enc enc : kAllEncodings)
    for (const auto& [index, count] : types) {
      SCOPED_TRACE(std::string(enc_name(enc)) + " " + count + " " + index);
      const std::string path = write_file(dir, "s.ply", build_ply(enc, {xyz_vertices(kEight), strips_element(kStrips, index, count)}));
      for (uint32_t block : {1u, 4u, 1000u}) {
        const fuzz::RecordingSink s = stream(path, block);
        EXPECT_EQ(triangles_of(s.corners), kStripTriangles);
        EXPECT_EQ(s.stats.strip_triangles_dropped, 4u);
        EXPECT_EQ(s.header.faces, MeshHeaderInfo::kUnknown);  // strips hold any number of triangles
      }
      const MeshBuffers m = read_mesh(path);
      EXPECT_EQ(triangles_of(m.triangles), kStripTriangles);
      EXPECT_EQ(m.positions, kEight);
    }
  fs::remove_all(dir);
}

TEST(PlyStrips, ErrorsNameTheLineOrByteOfTheIndex) {
  const fs::path dir = test::temp_dir("ply_strips_bad");
  const std::vector<std::vector<int64_t>> out_of_range = {{0, 1, 2, 8, 3}};
  const std::string ascii = write_file(dir, "a.ply", build_ply(Enc::Ascii, {xyz_vertices(kEight), strips_element(out_of_range)}));
  // Header: 9 lines, then 8 vertex lines: the strip is line 18.
  EXPECT_EQ(error_of([&] { read_mesh(ascii); }), ascii + ": line 18: tristrips 0: item 3: uses vertex 8 of 8");
  for (Enc enc : {Enc::Le, Enc::Be}) {
    const std::string bytes = build_ply(enc, {xyz_vertices(kEight), strips_element(out_of_range)});
    const std::string path = write_file(dir, "b.ply", bytes);
    // The index's own byte: header, 8 vertices of 12 bytes, the int count, 3 indices before it.
    const size_t at = bytes.find("end_header\n") + 11 + 8 * 12 + 4 + 3 * 4;
    EXPECT_EQ(error_of([&] { read_mesh(path); }), path + ": byte " + std::to_string(at) + ": tristrips 0: item 3: uses vertex 8 of 8");
  }
  const std::string negative = write_file(dir, "n.ply", build_ply(Enc::Le, {xyz_vertices(kEight), strips_element({{0, 1, -2}})}));
  EXPECT_NE(error_of([&] { read_mesh(negative); }).find("negative vertex index -2"), std::string::npos);
  const std::string unnamed = write_file(
      dir, "u.ply", build_ply(Enc::Ascii, {xyz_vertices(kEight), {"tristrips", {{"int", "corners", "int"}}, {}}}));
  EXPECT_NE(error_of([&] { read_mesh(unnamed); }).find("element tristrips has no vertex_indices list"), std::string::npos);
  // All strip triangles degenerate: no faces at all.
  const std::string flat = write_file(dir, "f.ply", build_ply(Enc::Ascii, {xyz_vertices(kEight), strips_element({{0, 0, 1, 1}})}));
  EXPECT_EQ(error_of([&] { read_mesh(flat); }), flat + ": no faces (8 vertices and no triangle; 2 degenerate strip triangles dropped)");
  fs::remove_all(dir);
}

TEST(PlyStrips, AllOnesIndexIsAVertexWhenTheMeshHasThatMany) {
  // 256 vertices: uchar 255 is vertex 255, not a restart, so no file with valid indices changes
  // meaning. With 8 vertices the same byte (or "255" in ascii) restarts the strip.
  const fs::path dir = test::temp_dir("ply_strips_ones");
  std::vector<float> fan(3 * 256);
  for (int v = 0; v < 256; ++v) fan[3 * v] = float(v % 16), fan[3 * v + 1] = float(v / 16);
  for (Enc enc : kAllEncodings) {
    SCOPED_TRACE(enc_name(enc));
    const std::string many = write_file(dir, "m.ply", build_ply(enc, {xyz_vertices(fan), strips_element({{0, 1, 255, 16}}, "uchar", "uchar")}));
    EXPECT_EQ(triangles_of(read_mesh(many).triangles), (std::vector<Triangle>{{0, 1, 255}, {255, 1, 16}}));
    const std::string few = write_file(dir, "f.ply", build_ply(enc, {xyz_vertices(kEight), strips_element({{0, 1, 2, 255, 3, 4, 5}}, "uchar", "uchar")}));
    EXPECT_EQ(triangles_of(read_mesh(few).triangles), (std::vector<Triangle>{{0, 1, 2}, {3, 4, 5}}));
  }
  fs::remove_all(dir);
}

TEST(PlyStrips, UnknownFaceElementIsAnErrorNamingTheElements) {
  const fs::path dir = test::temp_dir("ply_polygon");
  Elem polygons{"polygon", {{"int", "vertex_indices", "uchar"}}, {{{0, 1, 2}}}};
  const std::string path = write_file(dir, "p.ply", build_ply(Enc::Le, {xyz_vertices(kEight), polygons}));
  EXPECT_EQ(error_of([&] { read_mesh(path); }),
            path + ": line 9: no face element: the file has elements vertex (8), polygon (1); faces are read from "
                   "'face' or 'tristrips'");
  fs::remove_all(dir);
}

// ---- strips of a real mesh --------------------------------------------------------------

/// Greedy stripifier: from each unused face, extend the strip across the edge that the next
/// triangle of the alternating rule needs, while the face behind it is unused.
std::vector<std::vector<int64_t>> stripify(const MeshBuffers& m) {
  auto key = [](uint32_t a, uint32_t b) { return (uint64_t(a) << 32) | b; };
  std::unordered_map<uint64_t, uint32_t> face_of_edge;  // directed edge a→b of a face's cycle
  for (uint32_t f = 0; f < m.face_count(); ++f)
    for (int k = 0; k < 3; ++k) face_of_edge[key(m.triangles[3 * f + k], m.triangles[3 * f + (k + 1) % 3])] = f;
  std::vector<bool> used(m.face_count());
  std::vector<std::vector<int64_t>> strips;
  for (uint32_t f = 0; f < m.face_count(); ++f) {
    if (used[f]) continue;
    used[f] = true;
    std::vector<int64_t> s = {m.triangles[3 * f], m.triangles[3 * f + 1], m.triangles[3 * f + 2]};
    for (;;) {
      const size_t n = s.size();
      // Triangle i = n-2 comes next: (s[i], s[i+1], w) if i is even, (s[i+1], s[i], w) if odd.
      const uint32_t x = uint32_t((n - 2) % 2 == 0 ? s[n - 2] : s[n - 1]), y = uint32_t((n - 2) % 2 == 0 ? s[n - 1] : s[n - 2]);
      auto it = face_of_edge.find(key(x, y));
      if (it == face_of_edge.end() || used[it->second]) break;
      const uint32_t* t = &m.triangles[3 * size_t(it->second)];
      const int k = t[0] == x ? 0 : t[1] == x ? 1 : 2;  // x→y is t[k]→t[k+1]: the third follows
      used[it->second] = true;
      s.push_back(t[(k + 2) % 3]);
    }
    strips.push_back(std::move(s));
  }
  return strips;
}

/// Oriented triangles as a sorted list, each rotated to start at its smallest id.
std::vector<Triangle> oriented_set(const std::vector<Triangle>& in) {
  std::vector<Triangle> out;
  for (Triangle t : in) {
    while (t[0] != std::min({t[0], t[1], t[2]})) t = {t[1], t[2], t[0]};
    out.push_back(t);
  }
  std::sort(out.begin(), out.end());
  return out;
}

/// Joins strips into one list by repeating the last index of one and the first of the next
/// (once more when needed to keep the next strip's first triangle even); returns the list and
/// how many degenerate triangles the joins make.
std::pair<std::vector<int64_t>, uint64_t> join_with_degenerates(const std::vector<std::vector<int64_t>>& strips) {
  std::vector<int64_t> list;
  for (const auto& s : strips) {
    if (!list.empty()) {
      const int64_t last = list.back();
      list.push_back(last);
      if (list.size() % 2 == 0) list.push_back(last);  // s[0] then lands at an even position
      list.push_back(s[0]);
    }
    list.insert(list.end(), s.begin(), s.end());
  }
  uint64_t degenerate = 0;
  for (size_t i = 0; i + 2 < list.size(); ++i)
    degenerate += list[i] == list[i + 1] || list[i + 1] == list[i + 2] || list[i] == list[i + 2];
  return {list, degenerate};
}

TEST(PlyStrips, StripsOfARealMeshGiveItsOrientedFaces) {
  const fs::path dir = test::temp_dir("ply_strips_real");
  for (const std::string name : {"cgal_hand.off", "icosphere7"}) {
    SCOPED_TRACE(name);
    const MeshBuffers mesh = name == "icosphere7" ? make_icosphere(7) : read_mesh(test::data_path(name));
    const std::vector<std::vector<int64_t>> strips = stripify(mesh);
    ASSERT_GT(double(mesh.face_count()) / double(strips.size()), 2.0) << "strips too short to test anything";
    const std::vector<Triangle> want = oriented_set(triangles_of(mesh.triangles));
    const std::vector<float> pos(mesh.positions.begin(), mesh.positions.end());
    // (1) One list, strips separated by -1 (ascii: one line of megabytes for the icosphere).
    std::vector<int64_t> one;
    for (const auto& s : strips) {
      if (!one.empty()) one.push_back(-1);
      one.insert(one.end(), s.begin(), s.end());
    }
    // (2) A record per 50 strips, no -1 at all. (3) One list with degenerate joins.
    std::vector<std::vector<int64_t>> records;
    for (size_t i = 0; i < strips.size(); i += 50) {
      records.emplace_back();
      for (size_t j = i; j < std::min(strips.size(), i + 50); ++j) {
        if (j > i) records.back().push_back(-1);
        records.back().insert(records.back().end(), strips[j].begin(), strips[j].end());
      }
    }
    const auto [joined, degenerate] = join_with_degenerates(strips);
    ASSERT_GT(degenerate, 0u);
    const std::vector<std::pair<std::vector<std::vector<int64_t>>, uint64_t>> layouts = {
        {{one}, 0}, {records, 0}, {{joined}, degenerate}};
    for (Enc enc : kAllEncodings)
      for (size_t l = 0; l < layouts.size(); ++l) {
        SCOPED_TRACE(std::string(enc_name(enc)) + " layout " + std::to_string(l));
        const std::string bytes = build_ply(enc, {xyz_vertices(pos), strips_element(layouts[l].first)});
        if (enc == Enc::Ascii && l != 1 && name == "icosphere7") {
          ASSERT_GT(bytes.size(), size_t(2) << 20);  // one line over several 1 MiB windows
        }
        const fuzz::RecordingSink s = stream(write_file(dir, "s.ply", bytes), 1u << 12);
        EXPECT_EQ(oriented_set(triangles_of(s.corners)), want);
        EXPECT_EQ(s.stats.strip_triangles_dropped, layouts[l].second);
      }
  }
  fs::remove_all(dir);
}

TEST(PlyStrips, AsciiLineLongerThanTheInputBufferIsReadInPieces) {
  // The ascii reader's windows hold whole lines, up to the 4 MiB input buffer: a longer line
  // (a strip list, or a skipped element's list) is read in pieces cut at blanks.
  const fs::path dir = test::temp_dir("ply_long_line");
  constexpr int kRepeats = 700000;  // "0 1 2 3 -1 " × 700,000: a 7.7 MB line
  std::vector<int64_t> list;
  for (int r = 0; r < kRepeats; ++r) list.insert(list.end(), {0, 1, 2, 3, -1});
  std::vector<double> blob(1500000, 1234567.0);  // a 12 MB line in an element that is skipped
  const Elem skipped{"blob", {{"int", "data", "int"}}, {{blob}}};
  const std::string path = write_file(
      dir, "long.ply", build_ply(Enc::Ascii, {xyz_vertices({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0}), skipped, strips_element({list})}));
  ASSERT_GT(std::filesystem::file_size(path), size_t(16) << 20);
  const MeshBuffers m = read_mesh(path);
  ASSERT_EQ(m.face_count(), 2u * kRepeats);
  for (size_t t = 0; t < m.face_count(); ++t) {
    const uint32_t* f = &m.triangles[3 * t];
    const Triangle want = t % 2 == 0 ? Triangle{0, 1, 2} : Triangle{2, 1, 3};
    ASSERT_TRUE(f[0] == want[0] && f[1] == want[1] && f[2] == want[2]) << "triangle " << t;
  }
  // An error deep inside the long line still names its line (11 header lines, 4 vertices, blob).
  list[5 * 600000 + 2] = 4;
  const std::string bad = write_file(dir, "bad.ply", build_ply(Enc::Ascii, {xyz_vertices({0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0}), skipped, strips_element({list})}));
  EXPECT_EQ(error_of([&] { read_mesh(bad); }), bad + ": line 17: tristrips 0: item 3000002: uses vertex 4 of 4");
  fs::remove_all(dir);
}

// ---- vertex attributes ------------------------------------------------------------------

TEST(PlyAttributes, ColoursAndScalarsArriveAsStoredNormalsAndListsDoNot) {
  const fs::path dir = test::temp_dir("ply_attributes");
  const std::vector<Prop> props = {{"float", "x", ""},       {"float", "nx", ""},   {"float", "y", ""},
                                   {"float", "z", ""},       {"float", "ny", ""},   {"float", "nz", ""},
                                   {"uchar", "red", ""},     {"uchar", "green", ""}, {"uchar", "blue", ""},
                                   {"uchar", "alpha", ""},   {"float", "confidence", ""},
                                   {"double", "intensity", ""}, {"ushort", "quality", ""}};
  const std::vector<std::string> names = {"red", "green", "blue", "alpha", "confidence", "intensity", "quality"};
  const std::vector<ScalarType> types = {ScalarType::U8,  ScalarType::U8,  ScalarType::U8, ScalarType::U8,
                                         ScalarType::F32, ScalarType::F64, ScalarType::U16};
  std::vector<float> values;
  Elem vertices{"vertex", props, {}};
  for (int v = 0; v < 4; ++v) {
    const float row[7] = {float(200 + v), float(10 * v), 255, 0, 0.25f * float(v) + 0.125f, -1.5f * float(v), float(60000 + v)};
    values.insert(values.end(), row, row + 7);
    vertices.records.push_back({{float(v)}, {0}, {float(v % 2)}, {0.5f}, {0}, {1}, {row[0]}, {row[1]}, {row[2]}, {row[3]},
                                {row[4]}, {row[5]}, {row[6]}});
  }
  Elem faces{"face", {{"int", "vertex_indices", "uchar"}}, {{{0, 1, 2}}, {{1, 3, 2}}}};
  Elem with_list = vertices;  // a list property: the binary reader's per-record path
  with_list.props.insert(with_list.props.begin() + 3, {"float", "uv", "uchar"});
  for (auto& r : with_list.records) r.insert(r.begin() + 3, std::vector<double>{0.5, 0.75});
  for (Enc enc : kAllEncodings)
    for (const Elem& v : {vertices, with_list}) {
      SCOPED_TRACE(std::string(enc_name(enc)) + (v.props.size() > props.size() ? " with a list" : ""));
      const std::string path = write_file(dir, "a.ply", build_ply(enc, {v, faces}));
      const MeshWithAttributes all = read_mesh_with_attributes(path);
      ASSERT_EQ(all.attributes.size(), names.size());
      for (size_t k = 0; k < names.size(); ++k) {
        EXPECT_EQ(all.attributes[k].name, names[k]);
        EXPECT_EQ(all.attributes[k].type, types[k]);
      }
      EXPECT_EQ(all.values, values);
      EXPECT_EQ(all.mesh.positions, read_mesh(path).positions);
      EXPECT_EQ(stream(path, 3).attributes, values);  // blocks of 3 vertices: rows stay aligned

      ReadOptions named;
      named.attributes = ReadOptions::Attributes::Named;
      named.attribute_names = {"confidence", "red", "nx", "missing"};  // file order; normals never
      const MeshWithAttributes some = read_mesh_with_attributes(path, named);
      ASSERT_EQ(some.attributes.size(), 2u);
      EXPECT_EQ(some.attributes[0].name, "red");
      EXPECT_EQ(some.attributes[1].name, "confidence");
      for (int i = 0; i < 4; ++i) {
        EXPECT_EQ(some.values[2 * i], values[7 * i]);
        EXPECT_EQ(some.values[2 * i + 1], values[7 * i + 4]);
      }
      ReadOptions none;
      none.attributes = ReadOptions::Attributes::None;
      const MeshWithAttributes bare = read_mesh_with_attributes(path, none);
      EXPECT_TRUE(bare.attributes.empty());
      EXPECT_TRUE(bare.values.empty());
    }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace streamcvd
