// STL reader, ascii and binary. STL stores each facet's three corners by value, so vertices are
// rebuilt by merging bitwise-identical coordinates (-0.0 == +0.0) with an open-addressing hash
// table over the positions array, in order of first appearance.
#include <fast_float/fast_float.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "core/errors.h"
#include "streaming/input_stream.h"
#include "streaming/text_tokens.h"
#include "streaming/mesh_io.h"

namespace streamcvd {

namespace {

using text::parse_coordinate;
using text::quoted;

constexpr uint64_t kMaxVertices = std::numeric_limits<uint32_t>::max();
constexpr size_t kHeaderBytes = 84;  // 80-byte header + uint32 facet count
constexpr size_t kRecordBytes = 50;  // normal, 3 corners (12 float32) + uint16 attribute

/// Deduplicates vertices: slots hold vertex index + 1 (0 = empty), keys live in `positions`, so
/// the table costs 8-16 bytes per vertex. Linear probing, load factor kept at or below 1/2.
class VertexMerger {
 public:
  VertexMerger(std::vector<float>& positions, uint64_t expected_vertices) : positions_(positions) {
    uint64_t size = 1024;
    while (size < 2 * expected_vertices) size *= 2;
    slots_.assign(size, 0);
    mask_ = size - 1;
  }

  /// Index of the vertex xyz[0..2], appending it when new; -0.0 is stored as +0.0. Returns
  /// false when the mesh would exceed 2^32-1 vertices.
  bool insert(const float* xyz, uint32_t& index) {
    uint32_t key[3] = {bits(xyz[0]), bits(xyz[1]), bits(xyz[2])};
    for (uint64_t s = hash(key) & mask_;; s = (s + 1) & mask_) {
      uint32_t slot = slots_[s];
      if (slot == 0) {
        uint64_t count = positions_.size() / 3;
        if (count >= kMaxVertices) return false;
        index = uint32_t(count);
        slots_[s] = index + 1;
        float stored[3];
        std::memcpy(stored, key, sizeof stored);
        positions_.insert(positions_.end(), stored, stored + 3);
        if (2 * (count + 1) > slots_.size()) grow();
        return true;
      }
      if (std::memcmp(&positions_[3 * uint64_t(slot - 1)], key, sizeof key) == 0) {
        index = slot - 1;
        return true;
      }
    }
  }

 private:
  static uint32_t bits(float v) {
    if (v == 0.0f) v = 0.0f;  // -0.0 compares equal to 0.0: fold it onto +0.0
    return std::bit_cast<uint32_t>(v);
  }
  static uint64_t hash(const uint32_t* k) {
    uint64_t h = (uint64_t(k[0]) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(k[1]) * 0xC2B2AE3D27D4EB4Full) ^
                 (uint64_t(k[2]) * 0x165667B19E3779F9ull);
    h ^= h >> 29;
    h *= 0xBF58476D1CE4E5B9ull;
    return h ^ (h >> 32);
  }
  void grow() {
    slots_.assign(slots_.size() * 2, 0);
    mask_ = slots_.size() - 1;
    uint32_t count = uint32_t(positions_.size() / 3);
    for (uint32_t v = 0; v < count; ++v) {
      uint32_t key[3];
      std::memcpy(key, &positions_[3 * uint64_t(v)], sizeof key);
      uint64_t s = hash(key) & mask_;
      while (slots_[s] != 0) s = (s + 1) & mask_;
      slots_[s] = v + 1;
    }
  }

  std::vector<float>& positions_;
  std::vector<uint32_t> slots_;
  uint64_t mask_ = 0;
};

// Ascii STL is read token by token across lines, so a line break is blank here too.
inline bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\v' || c == '\f';
}

/// Case-insensitive comparison with a lowercase keyword.
inline bool is_keyword(std::string_view tok, std::string_view lower) {
  if (tok.size() != lower.size()) return false;
  for (size_t i = 0; i < tok.size(); ++i)
    if ((tok[i] | 0x20) != lower[i]) return false;
  return true;
}

/// Binary unless the data starts with "solid" and reads as text: many binary writers also put
/// "solid" in their header, so an exact binary size wins; otherwise (and always for zstd input,
/// whose decompressed size is unknown) the bytes after the 80-byte header decide. In a binary
/// file they hold the facet count and float32 data, which contain control bytes (a count below
/// 2^24 has a zero high byte); an ascii STL holds only text there.
bool looks_ascii(InputStream& in) {
  constexpr size_t kSniff = 4096;
  std::span<const char> head = in.fill(kSniff);
  std::string_view s(head.data(), std::min(head.size(), kSniff));
  size_t p = 0;
  while (p < s.size() && is_space(s[p])) ++p;
  if (!is_keyword(s.substr(p, 5), "solid")) return false;
  if (!in.compressed() && in.file_size() >= kHeaderBytes && s.size() >= kHeaderBytes) {
    uint32_t count;
    std::memcpy(&count, s.data() + 80, 4);
    if constexpr (std::endian::native == std::endian::big) count = __builtin_bswap32(count);
    if (kHeaderBytes + kRecordBytes * uint64_t(count) == in.file_size()) return false;
  }
  for (size_t i = 80; i < s.size(); ++i) {
    unsigned char c = static_cast<unsigned char>(s[i]);
    if ((c < 0x20 && !is_space(char(c))) || c == 0x7f) return false;
  }
  return true;
}

/// The 9 corner coordinates of a 50-byte binary record (the facet normal is skipped).
void corners(const char* record, float* c) {
  std::memcpy(c, record + 12, 9 * sizeof(float));
  if constexpr (std::endian::native == std::endian::big)
    for (int k = 0; k < 9; ++k) c[k] = std::bit_cast<float>(__builtin_bswap32(std::bit_cast<uint32_t>(c[k])));
}

MeshBuffers read_binary(InputStream& in) {
  char header[kHeaderBytes];
  size_t got = in.read(header, kHeaderBytes);
  if (got < kHeaderBytes)
    throw InputError(error_at_byte(in.path(), got, "file too short for a binary STL (" + std::to_string(got) +
                                                       " bytes, header needs 84)"));
  uint32_t count;
  std::memcpy(&count, header + 80, 4);
  if constexpr (std::endian::native == std::endian::big) count = __builtin_bswap32(count);
  const uint64_t needed = kHeaderBytes + kRecordBytes * uint64_t(count);
  if (!in.compressed() && in.file_size() < needed)
    throw InputError(error_at_byte(in.path(), 80,
                                   "truncated binary STL: header declares " + std::to_string(count) +
                                       " triangles (" + std::to_string(needed) + " bytes) but the file has " +
                                       std::to_string(in.file_size()) + " bytes"));
  // Bytes past the declared triangles (some writers pad) are ignored.
  if (count == 0) throw InputError(error_at_byte(in.path(), 80, "binary STL declares 0 triangles"));

  MeshBuffers mesh;
  const uint64_t bounded = std::min<uint64_t>(count, in.max_elements(kRecordBytes));
  mesh.triangles.reserve(3 * bounded);
  mesh.positions.reserve(3 * (bounded / 2 + 3));  // a closed mesh has V ≈ F/2
  VertexMerger merger(mesh.positions, bounded / 2 + 3);
  uint64_t done = 0;
  while (done < count) {
    std::span<const char> buf = in.fill(kRecordBytes * std::min<uint64_t>(count - done, 1 << 16));
    uint64_t n = std::min<uint64_t>(buf.size() / kRecordBytes, count - done);
    if (n == 0)
      throw InputError(error_at_byte(in.path(), kHeaderBytes + kRecordBytes * done,
                                     "unexpected end of file after " + std::to_string(done) + " of " +
                                         std::to_string(count) + " triangles"));
    for (uint64_t r = 0; r < n; ++r) {
      float c[9];
      corners(buf.data() + kRecordBytes * r, c);
      for (int k = 0; k < 9; ++k)
        if (!std::isfinite(c[k]))
          throw InputError(error_at_byte(in.path(), kHeaderBytes + kRecordBytes * (done + r) + 12 + 4 * k,
                                         "coordinate is not finite in triangle " + std::to_string(done + r)));
      for (int k = 0; k < 3; ++k) {
        uint32_t v;
        if (!merger.insert(c + 3 * k, v))
          throw InputError(error_at_byte(in.path(), kHeaderBytes + kRecordBytes * (done + r),
                                         "more than 4294967295 vertices"));
        mesh.triangles.push_back(v);
      }
    }
    in.consume(kRecordBytes * n);
    done += n;
  }
  return mesh;
}

/// Whitespace-separated tokens over the stream's lines.
class Tokens {
 public:
  explicit Tokens(InputStream& in) : in_(in) {}
  bool next(std::string_view& tok) {
    for (;;) {
      while (p_ < e_ && is_space(*p_)) ++p_;
      if (p_ < e_) {
        const char* s = p_;
        while (p_ < e_ && !is_space(*p_)) ++p_;
        tok = {s, size_t(p_ - s)};
        return true;
      }
      std::string_view line;
      if (!in_.next_line(line)) return false;
      p_ = line.data();
      e_ = p_ + line.size();
    }
  }
  void drop_line() { p_ = e_; }
  /// Returns `tok`, the last token next() gave, to the stream.
  void unget(std::string_view tok) { p_ = tok.data(); }

 private:
  InputStream& in_;
  const char* p_ = nullptr;
  const char* e_ = nullptr;
};

/// Token grammar, tolerant to any whitespace and to several solids:
///   solid [name] { facet [normal nx ny nz] outer loop {vertex x y z}≥3 endloop endfacet } endsolid [name]
/// A facet with more than 3 vertices is fan-triangulated.
MeshBuffers read_ascii(InputStream& in) {
  MeshBuffers mesh;
  VertexMerger merger(mesh.positions, 1 << 15);
  Tokens tokens(in);
  std::string_view tok;
  bool in_solid = false, in_facet = false, in_loop = false;
  std::vector<uint32_t> corners;
  while (tokens.next(tok)) {
    if (in_loop && is_keyword(tok, "vertex")) {
      float xyz[3];
      for (float& c : xyz) {
        if (!tokens.next(tok)) in.fail("file ends inside a vertex");
        c = parse_coordinate(in, tok);
      }
      uint32_t v;
      if (!merger.insert(xyz, v)) in.fail("more than 4294967295 vertices");
      corners.push_back(v);
    } else if (in_loop && is_keyword(tok, "endloop")) {
      in_loop = false;
    } else if (in_facet && !in_loop && is_keyword(tok, "outer")) {
      if (!tokens.next(tok) || !is_keyword(tok, "loop")) in.fail("expected 'loop' after 'outer'");
      if (!corners.empty()) in.fail("second 'outer loop' in one facet");
      in_loop = true;
    } else if (in_facet && !in_loop && is_keyword(tok, "endfacet")) {
      if (corners.size() < 3)
        in.fail("facet with " + std::to_string(corners.size()) + " vertices (at least 3 needed)");
      for (size_t i = 1; i + 1 < corners.size(); ++i)
        mesh.triangles.insert(mesh.triangles.end(), {corners[0], corners[i], corners[i + 1]});
      if (corners.size() > 3) ++mesh.polygons_split;
      in_facet = false;
    } else if (in_solid && !in_facet && is_keyword(tok, "facet")) {
      in_facet = true;
      corners.clear();
      // "normal nx ny nz" is skipped unparsed: normals are recomputed downstream and some
      // writers emit "nan" there.
      if (tokens.next(tok)) {
        if (is_keyword(tok, "normal")) {
          for (int k = 0; k < 3; ++k)
            if (!tokens.next(tok)) in.fail("file ends inside a facet normal");
        } else {
          tokens.unget(tok);
        }
      }
    } else if (!in_facet && is_keyword(tok, "endsolid")) {
      if (!in_solid) in.fail("'endsolid' without 'solid'");
      in_solid = false;
      tokens.drop_line();  // optional name
    } else if (!in_solid && is_keyword(tok, "solid")) {
      in_solid = true;
      tokens.drop_line();  // optional name
    } else {
      in.fail("unexpected " + quoted(tok) + (in_loop ? " inside a facet loop" : in_facet ? " inside a facet" : ""));
    }
  }
  if (in_facet) in.fail("file ends inside a facet");
  if (mesh.triangles.empty()) throw InputError(error_at(in.path(), "no facets in ascii STL"));
  return mesh;
}

}  // namespace

MeshBuffers read_stl(InputStream& in) { return looks_ascii(in) ? read_ascii(in) : read_binary(in); }

}  // namespace streamcvd
