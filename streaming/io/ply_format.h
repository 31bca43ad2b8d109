// Internal to the PLY reader (G. Turk, "The PLY polygon file format", 1994): the parsed header
// that the header parser (ply_reader.cpp) hands to the body readers (ply_binary.cpp,
// ply_ascii.cpp), each property already told what to become, and the triangle-strip decoder
// both body readers share.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "streamcvd/streaming/io/block_emitter.h"
#include "streamcvd/streaming/io/input_stream.h"
#include "streamcvd/streaming/io/mesh_reader.h"

namespace streamcvd::ply {

enum class Encoding { Ascii, BinaryLittle, BinaryBig };
using Scalar = ScalarType;

inline size_t scalar_size(Scalar t) { return scalar_type_bytes(t); }
inline bool is_integer(Scalar t) { return t != Scalar::F32 && t != Scalar::F64; }

/// What the body reader does with a property.
enum class Use : uint8_t { Skip, X, Y, Z, Attribute, Corners };

struct Property {
  std::string name;
  Scalar type = Scalar::F32;  ///< value type; for a list, the item type
  bool is_list = false;
  Scalar count_type = Scalar::U8;
  Use use = Use::Skip;
  uint32_t slot = 0;  ///< Use::Attribute: its column in the attribute row
};

/// What the body reader does with an element: `face` lists are polygons, `tristrips` lists are
/// triangle strips; anything else is skipped.
enum class Role : uint8_t { Skip, Vertices, Faces, Strips };

struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<Property> props;
  bool fixed = true;        ///< no list property: every record has record_bytes bytes
  size_t record_bytes = 0;  ///< binary: scalars + list counts (= the record size when fixed)
  Role role = Role::Skip;
};

struct Header {
  Encoding encoding = Encoding::Ascii;
  std::vector<Element> elements;
  uint32_t vertex_count = 0;  ///< records of the vertex element: every index must be below it
  size_t last_needed = 0;     ///< elements after this one are never read
};

/// Parses the header up to "end_header", marking vertex attributes selected by `options`, and
/// fills in out.header(). Throws InputError "<file>: line N: ..." for a malformed header, one
/// without vertices, or one with no element readable as faces (naming the elements found).
Header parse_header(InputStream& in, const ReadOptions& options, BlockEmitter& out);
/// Binary PLY from a regular uncompressed file whose vertex element has fixed-size records at a
/// known offset: reads that element once ahead (pread on its own descriptor, blocks in
/// parallel: the build waits for it) for its bounds and a position sample
/// (MeshHeaderInfo::has_bounds). Best effort: anything unusual skips it, and the streamed read
/// then reports every problem as usual. O(vertex element bytes).
void prescan_vertex_bounds(InputStream& in, const Header& h, BlockEmitter& out);
/// Fails fast when the header promises more records than the rest of an uncompressed file can
/// hold (e.g. "element vertex 4000000000" in a 100-byte file), before reading the body.
void check_counts_fit(InputStream& in, const Header& h);

/// The body readers: every element up to h.last_needed, in file order, into `out`.
void read_binary_body(InputStream& in, const Header& h, BlockEmitter& out);
void read_ascii_body(InputStream& in, const Header& h, BlockEmitter& out);

/// Why corner index `v` is not a vertex id below `nv` (the body readers add the position).
std::string index_problem(int64_t v, uint32_t nv);

/// The value besides -1 that restarts a strip of indices of type `t`: -1 written into an unsigned
/// type reads as its all-ones value (255, 65535, 2^32-1), which restarts the strip unless it is a
/// vertex id (below nv, so no valid file changes meaning); signed types only have -1 itself.
inline int64_t strip_restart_alias(Scalar t, uint32_t nv) {
  const int64_t ones = t == Scalar::U8 ? 0xFF : t == Scalar::U16 ? 0xFFFF : t == Scalar::U32 ? 0xFFFFFFFF : -1;
  return ones >= int64_t(nv) ? ones : -1;
}

/// Decodes the index lists of a `tristrips` element: -1 restarts the strip (so does the end of a
/// list); within a strip s, triangle i is (s[i], s[i+1], s[i+2]) for even i and
/// (s[i+1], s[i], s[i+2]) for odd i, so that all share one orientation. Triangles with a
/// repeated index (the joins between strips) are dropped and counted.
class StripDecoder {
 public:
  explicit StripDecoder(BlockEmitter& out) : out_(out) {}
  /// Next index of the strip, already checked to be a vertex id.
  void add(uint32_t v) {
    if (have_ < 2) {
      (have_ == 0 ? a_ : b_) = v;
      odd_ = false;
      ++have_;
      return;
    }
    if (a_ == b_ || b_ == v || a_ == v) ++out_.stats().strip_triangles_dropped;
    else if (odd_) out_.add_triangle(b_, a_, v);
    else out_.add_triangle(a_, b_, v);
    a_ = b_;
    b_ = v;
    odd_ = !odd_;
  }
  /// A -1 in the list, or the list's end.
  void restart() { have_ = 0; }

 private:
  BlockEmitter& out_;
  uint32_t a_ = 0, b_ = 0;  // the last two indices of the strip
  uint32_t have_ = 0;       // how many of them the current strip has (0, 1 or 2)
  bool odd_ = false;        // parity of the next triangle within the strip
};

}  // namespace streamcvd::ply
