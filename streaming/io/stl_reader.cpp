// STL reader, ascii and binary. STL stores each facet's three corners by value and so does this
// reader (MeshHeaderInfo::corners_by_value): triangle t is vertices 3t, 3t+1, 3t+2, with -0.0
// folded onto +0.0 so that equal coordinates are equal bits. Merging them into shared vertices
// is the consumer's job (a sort in the store builder, a hash table in read_mesh): no table of
// every vertex here, so memory stays O(block).
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

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/block_emitter.h"
#include "streamcvd/streaming/io/input_stream.h"
#include "streamcvd/streaming/io/text_tokens.h"

namespace streamcvd {

namespace {

using text::parse_coordinate;
using text::quoted;

constexpr uint64_t kMaxVertices = std::numeric_limits<uint32_t>::max();
constexpr size_t kHeaderBytes = 84;  // 80-byte header + uint32 facet count
constexpr size_t kRecordBytes = 50;  // normal, 3 corners (12 float32) + uint16 attribute

/// Hands out one triangle by value: its corners as three new vertices (-0.0 folded onto +0.0:
/// x + 0.0f is +0.0 for either zero and x otherwise), then the triangle of their ids. False
/// when the ids would pass 2^32-1.
bool emit_by_value(BlockEmitter& out, const float* a, const float* b, const float* c) {
  const uint64_t id = out.vertex_count();
  if (id + 2 >= kMaxVertices) return false;
  out.add_vertex(a[0] + 0.0f, a[1] + 0.0f, a[2] + 0.0f);
  out.add_vertex(b[0] + 0.0f, b[1] + 0.0f, b[2] + 0.0f);
  out.add_vertex(c[0] + 0.0f, c[1] + 0.0f, c[2] + 0.0f);
  out.add_triangle(uint32_t(id), uint32_t(id + 1), uint32_t(id + 2));
  return true;
}

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

void read_binary(InputStream& in, BlockEmitter& out) {
  char header[kHeaderBytes];
  size_t got = in.read(header, kHeaderBytes);
  if (got < kHeaderBytes)
    throw InputError(error_at_byte(in.path(), got, "file too short for a binary STL (" + std::to_string(got) +
                                                       " bytes, header needs 84)"));
  uint32_t count;
  std::memcpy(&count, header + 80, 4);
  if constexpr (std::endian::native == std::endian::big) count = __builtin_bswap32(count);
  const uint64_t needed = kHeaderBytes + kRecordBytes * uint64_t(count);
  // The size check only for a file on disk (a pipe's size is unknown: the loop finds the end).
  if (!in.compressed() && in.file_size() > 0 && in.file_size() < needed)
    throw InputError(error_at_byte(in.path(), 80,
                                   "truncated binary STL: header declares " + std::to_string(count) +
                                       " triangles (" + std::to_string(needed) + " bytes) but the file has " +
                                       std::to_string(in.file_size()) + " bytes"));
  // Bytes past the declared triangles (some writers pad) are ignored.
  if (count == 0) throw InputError(error_at_byte(in.path(), 80, "binary STL declares 0 triangles"));

  out.header().faces = count;
  out.begin();
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
      if (!emit_by_value(out, c, c + 3, c + 6))
        throw InputError(error_at_byte(in.path(), kHeaderBytes + kRecordBytes * (done + r),
                                       "more than 4294967295 vertices (corners of " + std::to_string(done + r) +
                                           " triangles)"));
    }
    in.consume(kRecordBytes * n);
    done += n;
  }
  out.flush();
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
void read_ascii(InputStream& in, BlockEmitter& out) {
  out.begin();
  Tokens tokens(in);
  std::string_view tok;
  bool in_solid = false, in_facet = false, in_loop = false;
  std::vector<float> loop;  // xyz of the current facet's corners (3 of them, nearly always)
  while (tokens.next(tok)) {
    if (in_loop && is_keyword(tok, "vertex")) {
      float xyz[3];
      for (float& c : xyz) {
        if (!tokens.next(tok)) in.fail("file ends inside a vertex");
        c = parse_coordinate(in, tok);
      }
      loop.insert(loop.end(), xyz, xyz + 3);
    } else if (in_loop && is_keyword(tok, "endloop")) {
      in_loop = false;
    } else if (in_facet && !in_loop && is_keyword(tok, "outer")) {
      if (!tokens.next(tok) || !is_keyword(tok, "loop")) in.fail("expected 'loop' after 'outer'");
      if (!loop.empty()) in.fail("second 'outer loop' in one facet");
      in_loop = true;
    } else if (in_facet && !in_loop && is_keyword(tok, "endfacet")) {
      const size_t n = loop.size() / 3;
      if (n < 3) in.fail("facet with " + std::to_string(n) + " vertices (at least 3 needed)");
      // A polygon facet is fanned, each triangle again with its corners by value.
      for (size_t i = 1; i + 1 < n; ++i)
        if (!emit_by_value(out, &loop[0], &loop[3 * i], &loop[3 * i + 3])) in.fail("more than 4294967295 vertices");
      if (n > 3) ++out.stats().polygons_split;
      in_facet = false;
    } else if (in_solid && !in_facet && is_keyword(tok, "facet")) {
      in_facet = true;
      loop.clear();
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
  if (out.vertex_count() == 0) throw InputError(error_at(in.path(), "no facets in ascii STL"));
  out.flush();
}

}  // namespace

void stream_stl(InputStream& in, BlockEmitter& out) {
  out.header().corners_by_value = true;
  out.header().vertices_before_triangles = false;  // interleaved, each triangle after its corners
  looks_ascii(in) ? read_ascii(in, out) : read_binary(in, out);
}

}  // namespace streamcvd
