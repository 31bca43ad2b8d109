// PLY reader (G. Turk, "The PLY polygon file format", 1994): ascii, binary_little_endian and
// binary_big_endian, any elements and properties in any order. This file parses the header and
// decides what each property becomes: vertex x/y/z, vertex attributes (any other scalar but the
// normals), the index lists of `face` (polygons) or `tristrips` (strips); everything else is
// skipped without allocating. The bodies are read by ply_binary.cpp and ply_ascii.cpp.
#include <algorithm>
#include <cctype>
#include <cstring>
#include <string>
#include <string_view>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/block_emitter.h"
#include "streamcvd/streaming/io/input_stream.h"
#include "streamcvd/streaming/io/ply_format.h"

namespace streamcvd {

namespace ply {

namespace {

struct ScalarName {
  std::string_view name;
  Scalar type;
};
constexpr ScalarName kScalarNames[] = {
    {"char", Scalar::I8},    {"int8", Scalar::I8},     {"uchar", Scalar::U8},   {"uint8", Scalar::U8},
    {"short", Scalar::I16},  {"int16", Scalar::I16},   {"ushort", Scalar::U16}, {"uint16", Scalar::U16},
    {"int", Scalar::I32},    {"int32", Scalar::I32},   {"uint", Scalar::U32},   {"uint32", Scalar::U32},
    {"float", Scalar::F32},  {"float32", Scalar::F32}, {"double", Scalar::F64}, {"float64", Scalar::F64}};

std::vector<std::string_view> split_words(std::string_view s) {
  std::vector<std::string_view> words;
  size_t i = 0;
  while (i < s.size()) {
    while (i < s.size() && std::isspace(static_cast<unsigned char>(s[i]))) ++i;
    size_t j = i;
    while (j < s.size() && !std::isspace(static_cast<unsigned char>(s[j]))) ++j;
    if (j > i) words.push_back(s.substr(i, j - i));
    i = j;
  }
  return words;
}

bool parse_scalar_type(std::string_view word, Scalar& out) {
  for (const auto& n : kScalarNames)
    if (n.name == word) {
      out = n.type;
      return true;
    }
  return false;
}

bool parse_u64(std::string_view s, uint64_t& out) {
  if (s.empty() || s.size() > 19) return false;
  out = 0;
  for (char c : s) {
    if (c < '0' || c > '9') return false;
    out = out * 10 + uint64_t(c - '0');
  }
  return true;
}

bool is_normal(std::string_view name) { return name == "nx" || name == "ny" || name == "nz"; }

}  // namespace

Header parse_header(InputStream& in, const ReadOptions& options, BlockEmitter& out) {
  // Check the magic before next_line(): a binary file without newlines would be one huge line.
  std::span<const char> head = in.fill(4);
  if (head.size() < 3 || std::memcmp(head.data(), "ply", 3) != 0)
    throw InputError(error_at_line(in.path(), 1, "not a PLY file (it does not start with 'ply')"));
  auto fail = [&](const std::string& problem) -> void {
    throw InputError(error_at_line(in.path(), in.line_number(), problem));
  };
  std::string_view line;
  in.next_line(line);
  if (split_words(line) != std::vector<std::string_view>{"ply"}) fail("not a PLY file (first line is not 'ply')");

  Header h;
  bool have_format = false;
  constexpr uint64_t kMaxHeaderBytes = uint64_t(1) << 20;
  for (;;) {
    if (!in.next_line(line)) fail("header has no end_header line");
    if (in.offset() > kMaxHeaderBytes) fail("header has no end_header line in its first MiB");
    auto w = split_words(line);
    if (w.empty() || w[0] == "comment" || w[0] == "obj_info") continue;
    if (w[0] == "end_header") break;
    if (w[0] == "format") {
      if (w.size() != 3) fail("format line must be 'format <encoding> 1.0'");
      if (w[1] == "ascii") h.encoding = Encoding::Ascii;
      else if (w[1] == "binary_little_endian") h.encoding = Encoding::BinaryLittle;
      else if (w[1] == "binary_big_endian") h.encoding = Encoding::BinaryBig;
      else fail("unknown PLY format '" + std::string(w[1]) + "'");
      if (w[2] != "1.0" && w[2] != "1") fail("unsupported PLY version '" + std::string(w[2]) + "'");
      have_format = true;
    } else if (w[0] == "element") {
      Element e;
      if (w.size() != 3 || !parse_u64(w[2], e.count)) fail("element line must be 'element <name> <count>'");
      e.name = w[1];
      h.elements.push_back(std::move(e));
    } else if (w[0] == "property") {
      if (h.elements.empty()) fail("property before any element");
      Property p;
      if (w.size() == 3) {
        if (!parse_scalar_type(w[1], p.type)) fail("unknown property type '" + std::string(w[1]) + "'");
        p.name = w[2];
      } else if (w.size() == 5 && w[1] == "list") {
        p.is_list = true;
        if (!parse_scalar_type(w[2], p.count_type) || !parse_scalar_type(w[3], p.type))
          fail("unknown list types '" + std::string(w[2]) + " " + std::string(w[3]) + "'");
        if (!is_integer(p.count_type)) fail("list count type must be an integer type");
        p.name = w[4];
      } else {
        fail("property line must be 'property <type> <name>' or 'property list <type> <type> <name>'");
      }
      h.elements.back().props.push_back(std::move(p));
    } else {
      fail("unknown header keyword '" + std::string(w[0]) + "'");
    }
  }
  if (!have_format) fail("header has no format line");

  // Roles: the first `vertex`, `face` and `tristrips` elements; a second one is an error.
  int vertex = -1, face = -1, strips = -1;
  for (size_t i = 0; i < h.elements.size(); ++i) {
    Element& e = h.elements[i];
    for (const Property& p : e.props) {
      e.fixed = e.fixed && !p.is_list;
      e.record_bytes += scalar_size(p.is_list ? p.count_type : p.type);
    }
    int* slot = e.name == "vertex" ? &vertex : e.name == "face" ? &face : e.name == "tristrips" ? &strips : nullptr;
    if (!slot) continue;
    if (*slot >= 0) fail("duplicate element '" + e.name + "'");
    *slot = int(i);
  }
  if (vertex < 0 || h.elements[vertex].count == 0) fail("no vertices (element vertex is missing or empty)");
  Element& ve = h.elements[vertex];
  if (ve.count > 0xFFFFFFFFull) fail("more than 2^32-1 vertices (" + std::to_string(ve.count) + ")");
  ve.role = Role::Vertices;
  h.vertex_count = uint32_t(ve.count);
  MeshHeaderInfo& info = out.header();
  bool has_x = false, has_y = false, has_z = false;
  for (Property& p : ve.props) {
    const bool axis = p.name == "x" || p.name == "y" || p.name == "z";
    if (axis && p.is_list) fail("vertex property " + p.name + " is a list");
    if (axis) {
      (p.name == "x" ? has_x : p.name == "y" ? has_y : has_z) = true;
      p.use = p.name == "x" ? Use::X : p.name == "y" ? Use::Y : Use::Z;
    } else if (!p.is_list && !is_normal(p.name) && attribute_selected(options, p.name)) {
      p.use = Use::Attribute;
      p.slot = uint32_t(info.attributes.size());
      info.attributes.push_back({p.name, p.type});
    }
  }
  if (!has_x || !has_y || !has_z) fail("element vertex lacks an x, y or z property");
  h.last_needed = size_t(vertex);
  if (face < 0 && strips < 0) {
    std::string found;
    for (const Element& e : h.elements)
      found += (found.empty() ? "" : ", ") + e.name + " (" + std::to_string(e.count) + ")";
    fail("no face element: the file has elements " + found + "; faces are read from 'face' or 'tristrips'");
  }

  for (int index : {face, strips}) {
    if (index < 0) continue;
    Element& fe = h.elements[index];
    fe.role = index == face ? Role::Faces : Role::Strips;
    auto list = std::find_if(fe.props.begin(), fe.props.end(),
                             [](const Property& p) { return p.name == "vertex_indices" || p.name == "vertex_index"; });
    if (list == fe.props.end()) fail("element " + fe.name + " has no vertex_indices list");
    if (!list->is_list) fail(fe.name + " property " + list->name + " is not a list");
    if (!is_integer(list->type)) fail(fe.name + " vertex indices must have an integer type");
    list->use = Use::Corners;
    h.last_needed = std::max(h.last_needed, size_t(index));
  }

  info.vertices = ve.count;
  info.faces = strips < 0 ? h.elements[face].count : MeshHeaderInfo::kUnknown;
  info.vertices_before_triangles = (face < 0 || vertex < face) && (strips < 0 || vertex < strips);
  return h;
}

void check_counts_fit(InputStream& in, const Header& h) {
  if (in.compressed() || in.file_size() == 0) return;  // no exact bound on decompressed size
  const bool ascii = h.encoding == Encoding::Ascii;
  double need = 0;  // double: counts × sizes may exceed 2^64
  for (size_t i = 0; i <= h.last_needed; ++i) {
    const Element& e = h.elements[i];
    // ascii: at least one character and one separator per value; faces need 1 + 3 values.
    double bytes = ascii ? 2.0 * double(e.props.size()) : double(e.record_bytes);
    if (e.role == Role::Faces) {
      for (const Property& p : e.props)
        if (p.use == Use::Corners) bytes += ascii ? 6.0 : 3.0 * double(scalar_size(p.type));
    }
    need += bytes * double(e.count);
  }
  if (ascii) need -= 1;  // the last line may lack its newline
  const uint64_t left = in.max_elements(1);
  if (need > double(left))
    throw InputError(error_at_byte(in.path(), in.offset(),
                                   "header counts need at least " + std::to_string(uint64_t(std::min(need, 1e19))) +
                                       " bytes of data but only " + std::to_string(left) + " follow"));
}

std::string index_problem(int64_t v, uint32_t nv) {
  if (v < 0) return "negative vertex index " + std::to_string(v);
  return "uses vertex " + std::to_string(v) + " of " + std::to_string(nv);
}

}  // namespace ply

void stream_ply(InputStream& in, BlockEmitter& out) {
  const ply::Header h = ply::parse_header(in, out.options(), out);
  ply::check_counts_fit(in, h);
  if (h.encoding != ply::Encoding::Ascii) ply::prescan_vertex_bounds(in, h, out);
  out.begin();
  if (h.encoding == ply::Encoding::Ascii) ply::read_ascii_body(in, h, out);
  else ply::read_binary_body(in, h, out);
}

}  // namespace streamcvd
