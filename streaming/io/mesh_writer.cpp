// Mesh writers: PLY (binary little-endian or ascii), OBJ, OFF, binary STL, each optionally
// zstd-compressed. Everything goes through AtomicOutputFile, so a failed write leaves nothing.
//
// Speed: binary vertex blocks are written straight from the caller's array; per-element
// records (ascii lines, binary PLY faces, STL facets) are formatted in blocks of ~4 MiB,
// in parallel with a TBB pipeline whose last stage writes the blocks in order. Ascii floats use
// std::to_chars (shortest representation that reads back to the same float32, bit-exact).
//
// Vertex attributes: PLY properties after x y z (binary records formatted in blocks then, not
// written straight from the positions), OBJ "v x y z r g b" colours (streaming/io/mesh_io.h).
//
// Empty meshes: V = 0 is refused with OutputError (read_mesh rejects such a file, so it could
// never be read back); F = 0 with V > 0 (a point set) is written for PLY, OBJ and OFF, but not
// for STL, which stores only triangles and would come back empty.
#include <oneapi/tbb/parallel_pipeline.h>
#include <oneapi/tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/io/output_file.h"

namespace streamcvd {

namespace {

static_assert(std::numeric_limits<float>::is_iec559, "float32 must be IEEE-754 binary32");

constexpr size_t kBlockBytes = size_t(4) << 20;  // formatted bytes per pipeline block
constexpr size_t kVertexLineMax = 64;             // "-1.17549435e-38 " ×3 + newline < 64
constexpr size_t kFaceLineMax = 48;               // "f 4294967295 ×3\n" < 48

inline char* put_float(char* p, float v) { return std::to_chars(p, p + 24, v).ptr; }
inline char* put_uint(char* p, uint64_t v) { return std::to_chars(p, p + 20, v).ptr; }
inline char* put_str(char* p, std::string_view s) {
  std::memcpy(p, s.data(), s.size());
  return p + s.size();
}
template <class T>
inline char* put_le(char* p, T v) {
  if constexpr (std::endian::native == std::endian::big) {
    auto bytes = std::bit_cast<std::array<char, sizeof(T)>>(v);
    std::reverse(bytes.begin(), bytes.end());
    std::memcpy(p, bytes.data(), sizeof(T));
  } else {
    std::memcpy(p, &v, sizeof(T));
  }
  return p + sizeof(T);
}

/// Streams `count` records, `format(dst, i)` writing record i (≤ max_bytes) at dst and returning
/// its end. Small outputs are formatted straight into the output buffer; larger ones in blocks
/// on all cores, written in order (at most `tokens` blocks of kBlockBytes in flight).
template <class Format>
void write_records(AtomicOutputFile& out, uint64_t count, size_t max_bytes, const Format& format) {
  const uint64_t per_block = kBlockBytes / max_bytes;
  if (count <= per_block) {
    const uint64_t per_prepare = AtomicOutputFile::kMaxPrepare / max_bytes;
    for (uint64_t i = 0; i < count;) {
      uint64_t end = std::min(count, i + per_prepare);
      char* begin = out.prepare(size_t(end - i) * max_bytes);
      char* p = begin;
      for (; i < end; ++i) p = format(p, i);
      out.advance(size_t(p - begin));
    }
    return;
  }
  struct Block {
    uint64_t first = 0, last = 0;
    char* data = nullptr;
    size_t size = 0;
  };
  const size_t tokens = size_t(std::max(2, 2 * tbb::this_task_arena::max_concurrency()));
  // Block k reuses buffer k mod tokens: the last stage is serial in order, so when block
  // k + tokens enters, block k has left the pipeline.
  std::vector<std::unique_ptr<char[]>> buffers(tokens);
  for (auto& b : buffers) b = std::make_unique_for_overwrite<char[]>(per_block * max_bytes);
  uint64_t next = 0, block_index = 0;
  tbb::parallel_pipeline(
      tokens,
      tbb::make_filter<void, Block>(tbb::filter_mode::serial_in_order,
                                    [&](tbb::flow_control& fc) {
                                      if (next >= count) {
                                        fc.stop();
                                        return Block{};
                                      }
                                      Block b{next, std::min(count, next + per_block),
                                              buffers[block_index++ % tokens].get(), 0};
                                      next = b.last;
                                      return b;
                                    }) &
          tbb::make_filter<Block, Block>(tbb::filter_mode::parallel,
                                         [&](Block b) {
                                           char* p = b.data;
                                           for (uint64_t i = b.first; i < b.last; ++i) p = format(p, i);
                                           b.size = size_t(p - b.data);
                                           return b;
                                         }) &
          tbb::make_filter<Block, void>(tbb::filter_mode::serial_in_order,
                                        [&](const Block& b) { out.write(b.data, b.size); }));
}

/// The comment split into lines, each written as `prefix + line + "\n"`.
void write_comment(AtomicOutputFile& out, std::string_view prefix, std::string_view comment) {
  while (!comment.empty()) {
    size_t end = comment.find_first_of("\r\n");
    std::string_view line = comment.substr(0, end);
    if (!line.empty()) {
      out.write(prefix);
      out.write(line);
      out.write("\n");
    }
    if (end == std::string_view::npos) break;
    comment.remove_prefix(end + 1);
  }
}

char* put_vertex_line(char* p, std::string_view lead, const float* xyz) {
  p = put_str(p, lead);
  p = put_float(p, xyz[0]);
  *p++ = ' ';
  p = put_float(p, xyz[1]);
  *p++ = ' ';
  p = put_float(p, xyz[2]);
  *p++ = '\n';
  return p;
}

// --- vertex attributes ------------------------------------------------------------------------

constexpr size_t kAttributeMax = 26;  // " " + the longest value: a double's shortest form (24)

// An attribute value as an integer type holds it: rounded, clamped to T's range (NaN → 0).
template <class T>
T to_integer(float x) {
  if (!(x == x)) return T(0);
  const double r = std::round(double(x));
  return T(std::clamp(r, double(std::numeric_limits<T>::min()), double(std::numeric_limits<T>::max())));
}

char* put_attribute_le(char* p, ScalarType type, float x) {
  switch (type) {
    case ScalarType::I8: return put_le(p, to_integer<int8_t>(x));
    case ScalarType::U8: return put_le(p, to_integer<uint8_t>(x));
    case ScalarType::I16: return put_le(p, to_integer<int16_t>(x));
    case ScalarType::U16: return put_le(p, to_integer<uint16_t>(x));
    case ScalarType::I32: return put_le(p, to_integer<int32_t>(x));
    case ScalarType::U32: return put_le(p, to_integer<uint32_t>(x));
    case ScalarType::F32: return put_le(p, x);
    case ScalarType::F64: return put_le(p, double(x));
  }
  return p;
}

char* put_attribute_ascii(char* p, ScalarType type, float x) {
  *p++ = ' ';
  switch (type) {
    case ScalarType::I8: return std::to_chars(p, p + 24, to_integer<int8_t>(x)).ptr;
    case ScalarType::U8: return std::to_chars(p, p + 24, to_integer<uint8_t>(x)).ptr;
    case ScalarType::I16: return std::to_chars(p, p + 24, to_integer<int16_t>(x)).ptr;
    case ScalarType::U16: return std::to_chars(p, p + 24, to_integer<uint16_t>(x)).ptr;
    case ScalarType::I32: return std::to_chars(p, p + 24, to_integer<int32_t>(x)).ptr;
    case ScalarType::U32: return std::to_chars(p, p + 24, to_integer<uint32_t>(x)).ptr;
    case ScalarType::F32: return put_float(p, x);
    case ScalarType::F64: return std::to_chars(p, p + 24, double(x)).ptr;
  }
  return p;
}

// An OBJ colour channel in [0, 1]: unsigned integer types (uchar 0..255...) divided by their
// maximum, floats (already 0..1 in practice) as they are.
float obj_colour(ScalarType type, float x) {
  const double max = type == ScalarType::U8 ? 255.0 : type == ScalarType::U16 ? 65535.0 : type == ScalarType::U32 ? 4294967295.0 : 0.0;
  return max > 0 ? float(std::clamp(double(x) / max, 0.0, 1.0)) : x;
}

char* put_face_line(char* p, std::string_view lead, const uint32_t* abc, uint64_t base) {
  p = put_str(p, lead);
  p = put_uint(p, abc[0] + base);
  *p++ = ' ';
  p = put_uint(p, abc[1] + base);
  *p++ = ' ';
  p = put_uint(p, abc[2] + base);
  *p++ = '\n';
  return p;
}

void write_ascii_vertices(AtomicOutputFile& out, const TriangleSoupView& mesh, std::string_view lead) {
  const float* pos = mesh.positions.data();
  write_records(out, mesh.vertex_count(), kVertexLineMax,
                [&](char* p, uint64_t v) { return put_vertex_line(p, lead, pos + 3 * v); });
}

void write_ascii_faces(AtomicOutputFile& out, const TriangleSoupView& mesh, std::string_view lead, uint64_t base) {
  const uint32_t* tri = mesh.triangles.data();
  write_records(out, mesh.face_count(), kFaceLineMax,
                [&](char* p, uint64_t f) { return put_face_line(p, lead, tri + 3 * f, base); });
}

// Binary PLY vertices without attributes: straight from the caller's array on little-endian hosts.
void write_binary_positions(AtomicOutputFile& out, const TriangleSoupView& mesh) {
  if constexpr (std::endian::native == std::endian::little) {
    out.write(mesh.positions.data(), mesh.positions.size_bytes());
  } else {
    const float* pos = mesh.positions.data();
    write_records(out, mesh.positions.size(), 4, [&](char* p, uint64_t i) { return put_le(p, pos[i]); });
  }
}

// PLY vertices with attribute columns: one record (ascii line or binary) per vertex.
void write_ply_vertices_with_attributes(AtomicOutputFile& out, const TriangleSoupView& mesh, const WriteOptions& options) {
  const std::span<const VertexAttribute> names = options.attributes.names;
  const size_t A = names.size();
  const float* pos = mesh.positions.data();
  const float* values = options.attributes.values.data();
  if (options.ascii) {
    write_records(out, mesh.vertex_count(), kVertexLineMax + kAttributeMax * A, [&](char* p, uint64_t v) {
      p = put_vertex_line(p, "", pos + 3 * v) - 1;  // the line's newline goes after the attributes
      for (size_t k = 0; k < A; ++k) p = put_attribute_ascii(p, names[k].type, values[A * v + k]);
      *p++ = '\n';
      return p;
    });
    return;
  }
  size_t record = 12;
  for (const VertexAttribute& a : names) record += scalar_type_bytes(a.type);
  write_records(out, mesh.vertex_count(), record, [&](char* p, uint64_t v) {
    for (int k = 0; k < 3; ++k) p = put_le(p, pos[3 * v + k]);
    for (size_t k = 0; k < A; ++k) p = put_attribute_le(p, names[k].type, values[A * v + k]);
    return p;
  });
}

void write_ply(AtomicOutputFile& out, const TriangleSoupView& mesh, const WriteOptions& options) {
  out.write(options.ascii ? "ply\nformat ascii 1.0\n" : "ply\nformat binary_little_endian 1.0\n");
  write_comment(out, "comment ", options.comment);
  const uint32_t v_count = mesh.vertex_count();
  std::string header = "element vertex " + std::to_string(v_count) + "\nproperty float x\nproperty float y\nproperty float z\n";
  for (const VertexAttribute& a : options.attributes.names)
    header += std::string("property ") + scalar_type_name(a.type) + " " + a.name + "\n";
  header += "element face " + std::to_string(mesh.face_count()) + "\nproperty list uchar " +
            // int holds indices up to 2^31 - 1; beyond that only uint is correct.
            (v_count <= uint32_t(std::numeric_limits<int32_t>::max()) ? "int" : "uint") + " vertex_indices\nend_header\n";
  out.write(header);
  if (!options.attributes.empty()) write_ply_vertices_with_attributes(out, mesh, options);
  else if (options.ascii) write_ascii_vertices(out, mesh, "");
  else write_binary_positions(out, mesh);
  if (options.ascii) {
    write_ascii_faces(out, mesh, "3 ", 0);
    return;
  }
  const uint32_t* tri = mesh.triangles.data();
  write_records(out, mesh.face_count(), 13, [&](char* p, uint64_t f) {
    *p++ = 3;
    p = put_le(p, tri[3 * f]);
    p = put_le(p, tri[3 * f + 1]);
    return put_le(p, tri[3 * f + 2]);
  });
}

void write_obj(AtomicOutputFile& out, const TriangleSoupView& mesh, const WriteOptions& options) {
  write_comment(out, "# ", options.comment);
  const std::vector<size_t> colours = attributes_written(MeshFormat::Obj, options.attributes.names);
  if (colours.empty()) {
    write_ascii_vertices(out, mesh, "v ");
  } else {  // "v x y z r g b"
    const size_t A = options.attributes.names.size();
    const float* pos = mesh.positions.data();
    const float* values = options.attributes.values.data();
    write_records(out, mesh.vertex_count(), kVertexLineMax + 3 * kAttributeMax, [&](char* p, uint64_t v) {
      p = put_vertex_line(p, "v ", pos + 3 * v) - 1;
      for (size_t k : colours) {
        *p++ = ' ';
        p = put_float(p, obj_colour(options.attributes.names[k].type, values[A * v + k]));
      }
      *p++ = '\n';
      return p;
    });
  }
  write_ascii_faces(out, mesh, "f ", 1);  // OBJ indices are 1-based
}

void write_off(AtomicOutputFile& out, const TriangleSoupView& mesh, const WriteOptions& options) {
  out.write("OFF\n");
  write_comment(out, "# ", options.comment);
  out.write(std::to_string(mesh.vertex_count()) + " " + std::to_string(mesh.face_count()) + " 0\n");
  write_ascii_vertices(out, mesh, "");
  write_ascii_faces(out, mesh, "3 ", 0);
}

void write_stl(AtomicOutputFile& out, const TriangleSoupView& mesh, const WriteOptions& options) {
  // 80-byte header that must not begin with "solid" (readers would take the file for ascii).
  char header[80] = {};
  std::string text = "binary STL, streamcvd";
  if (!options.comment.empty()) text += ": " + options.comment;
  for (char& c : text)
    if (c == '\n' || c == '\r') c = ' ';
  std::memcpy(header, text.data(), std::min(text.size(), sizeof(header)));
  out.write(header, sizeof(header));
  char count[4];
  put_le(count, uint32_t(mesh.face_count()));
  out.write(count, 4);
  const float* pos = mesh.positions.data();
  const uint32_t* tri = mesh.triangles.data();
  write_records(out, mesh.face_count(), 50, [&](char* p, uint64_t f) {
    const float* c[3] = {pos + 3 * size_t(tri[3 * f]), pos + 3 * size_t(tri[3 * f + 1]), pos + 3 * size_t(tri[3 * f + 2])};
    double e1[3], e2[3];
    for (int k = 0; k < 3; ++k) {
      e1[k] = double(c[1][k]) - c[0][k];
      e2[k] = double(c[2][k]) - c[0][k];
    }
    double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    for (double& x : n) x = len > 0 && std::isfinite(len) ? x / len : 0.0;  // degenerate → 0
    for (double x : n) p = put_le(p, float(x));
    for (const float* corner : c)
      for (int k = 0; k < 3; ++k) p = put_le(p, corner[k]);
    return put_le(p, uint16_t(0));
  });
}

/// Caller bugs (bad indices, NaN) would produce a file nobody can read: refuse them loudly.
void check_mesh(const std::string& path, const TriangleSoupView& mesh, MeshFormat format, const VertexAttributeRows& attributes) {
  const size_t options_attribute_count = attributes.names.size(), attribute_values = attributes.values.size();
  if (mesh.positions.size() % 3 != 0 || mesh.triangles.size() % 3 != 0)
    throw std::invalid_argument(path + ": positions and triangles must hold whole triples");
  if (mesh.positions.size() / 3 > std::numeric_limits<uint32_t>::max())
    throw std::invalid_argument(path + ": more than 2^32 - 1 vertices");
  const uint32_t v_count = mesh.vertex_count();
  if (v_count == 0) throw OutputError(error_at(path, "refusing to write a mesh without vertices"));
  if (format == MeshFormat::Stl && mesh.face_count() == 0)
    throw OutputError(error_at(path, "STL cannot store a mesh without triangles"));
  if (format == MeshFormat::Stl && mesh.face_count() > std::numeric_limits<uint32_t>::max())
    throw OutputError(error_at(path, "binary STL holds at most 2^32 - 1 triangles"));
  if (mesh.positions.size() / 3 * options_attribute_count != attribute_values)
    throw std::invalid_argument(path + ": " + std::to_string(attribute_values) + " attribute values for " +
                                std::to_string(v_count) + " vertices of " + std::to_string(options_attribute_count) +
                                " attributes");
  uint32_t max_index = 0;
  for (uint32_t i : mesh.triangles) max_index = std::max(max_index, i);
  if (!mesh.triangles.empty() && max_index >= v_count) {
    auto it = std::find_if(mesh.triangles.begin(), mesh.triangles.end(), [&](uint32_t i) { return i >= v_count; });
    uint64_t f = uint64_t(it - mesh.triangles.begin()) / 3;
    throw std::invalid_argument(path + ": face " + std::to_string(f) + " uses vertex " + std::to_string(*it) +
                                " of " + std::to_string(v_count));
  }
  // Exponent all ones ⇔ inf or NaN; OR-reducing a flag vectorises, unlike std::isfinite.
  uint32_t bad = 0;
  for (float x : mesh.positions) bad |= uint32_t((std::bit_cast<uint32_t>(x) & 0x7f800000u) == 0x7f800000u);
  if (bad) {
    auto it = std::find_if(mesh.positions.begin(), mesh.positions.end(), [](float x) { return !std::isfinite(x); });
    throw std::invalid_argument(path + ": vertex " + std::to_string((it - mesh.positions.begin()) / 3) +
                                " has a non-finite coordinate");
  }
}

}  // namespace

std::vector<size_t> attributes_written(MeshFormat format, std::span<const VertexAttribute> attributes) {
  std::vector<size_t> written;
  if (format == MeshFormat::Ply) {
    for (size_t k = 0; k < attributes.size(); ++k) written.push_back(k);
  } else if (format == MeshFormat::Obj) {
    for (const char* channel : {"red", "green", "blue"})
      for (size_t k = 0; k < attributes.size(); ++k)
        if (attributes[k].name == channel) {
          written.push_back(k);
          break;
        }
    if (written.size() != 3) written.clear();  // a colour needs all three channels
  }
  return written;
}

void write_mesh(const std::string& path, const TriangleSoupView& mesh, const WriteOptions& options) {
  MeshFormat format;
  try {
    format = format_from_path(path);
  } catch (const InputError& e) {
    throw OutputError(e.what());  // an unwritable name is an output failure, like a missing folder
  }
  check_mesh(path, mesh, format, options.attributes);
  AtomicOutputFile out(path, has_zst_extension(path), options.zstd_level);
  switch (format) {
    case MeshFormat::Ply: write_ply(out, mesh, options); break;
    case MeshFormat::Obj: write_obj(out, mesh, options); break;
    case MeshFormat::Off: write_off(out, mesh, options); break;
    case MeshFormat::Stl: write_stl(out, mesh, options); break;
  }
  out.commit();
}

}  // namespace streamcvd
