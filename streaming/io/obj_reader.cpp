// Wavefront OBJ reader: `v` (with optional per-vertex colours "v x y z r g b") and `f` records
// only, polygons fan-triangulated. One pass over next_line() views with a hand tokenizer and
// fast_float; no iostreams. Faces may name vertices defined later: the largest such forward
// reference is checked against the total once the file has ended.
#include <fast_float/fast_float.h>

#include <charconv>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/block_emitter.h"
#include "streamcvd/streaming/io/input_stream.h"
#include "streamcvd/streaming/io/text_tokens.h"

namespace streamcvd {

namespace {

using text::is_space;
using text::parse_coordinate;
using text::quoted;

constexpr uint64_t kMaxVertices = std::numeric_limits<uint32_t>::max();

/// Next whitespace-separated token of [p, e), advancing p; empty at the end of the line or at
/// a '#' comment.
inline std::string_view next_token(const char*& p, const char* e) {
  while (p < e && is_space(*p)) ++p;
  if (p == e || *p == '#') {
    p = e;
    return {};
  }
  const char* s = p;
  while (p < e && !is_space(*p)) ++p;
  return {s, size_t(p - s)};
}

/// Where a positive index points past the vertices defined so far; checked at the end, when the
/// total is known (the largest such index is the only one that matters).
struct ForwardReference {
  uint64_t index = 0;  // 1-based, as written
  uint64_t line = 0;
};

/// One face corner "v", "v/vt", "v/vt/vn" or "v//vn" → 0-based vertex index. Negative indices
/// count back from the last vertex defined so far.
uint32_t parse_corner(InputStream& in, std::string_view tok, uint64_t defined, ForwardReference& forward) {
  const char* p = tok.data();
  const char* e = p + tok.size();
  if (p < e && *p == '+') ++p;
  int64_t v = 0;
  auto r = std::from_chars(p, e, v);
  if (r.ec == std::errc::result_out_of_range) in.fail("face index out of range " + quoted(tok));
  if (r.ec != std::errc() || (r.ptr != e && *r.ptr != '/')) in.fail("bad face index " + quoted(tok));
  if (v == 0) in.fail("face index 0 (OBJ indices start at 1)");
  if (v < 0) {
    uint64_t back = uint64_t(-(v + 1)) + 1;  // |v| without overflow at INT64_MIN
    if (back > defined)
      in.fail("relative face index " + std::to_string(v) + " refers before the first vertex (" +
              std::to_string(defined) + " defined so far)");
    return uint32_t(defined - back);
  }
  if (uint64_t(v) > kMaxVertices) in.fail("face index " + std::to_string(v) + " is too large");
  if (uint64_t(v) > defined && uint64_t(v) > forward.index) forward = {uint64_t(v), in.line_number()};
  return uint32_t(v - 1);
}

}  // namespace

void stream_obj(InputStream& in, BlockEmitter& out) {
  out.header().vertices_before_triangles = false;  // faces may come first and point forward
  // Colour columns: the first `v` record decides whether there are any ("v x y z r g b").
  constexpr const char* kColours[3] = {"red", "green", "blue"};
  int colour_slot[3] = {-1, -1, -1};  // attribute column of r, g, b, or -1 when not carried
  ForwardReference forward;
  std::string joined;  // a logical line assembled from backslash-continued physical lines
  std::string_view line;
  while (in.next_line(line)) {
    if (!line.empty() && line.back() == '\\') {
      // Rare: "\" at the end of a line continues the record on the next one.
      joined.assign(line.substr(0, line.size() - 1));
      std::string_view more;
      bool again = true;
      while (again && in.next_line(more)) {
        again = !more.empty() && more.back() == '\\';
        joined.push_back(' ');
        joined.append(more.substr(0, more.size() - (again ? 1 : 0)));
      }
      line = joined;
    }
    const char* p = line.data();
    const char* e = p + line.size();
    std::string_view key = next_token(p, e);
    if (key.size() != 1) continue;  // blank, comment, vt, vn, vp, usemtl, mtllib, ...
    if (key[0] == 'v') {
      float xyz[3];
      for (float& c : xyz) {
        std::string_view tok = next_token(p, e);
        if (tok.empty()) in.fail("vertex needs 3 coordinates");
        c = parse_coordinate(in, tok);
      }
      // Then an optional w, or three colour values; any other count carries no colour.
      std::string_view extra[4];
      int extras = 0;
      while (extras < 4 && !(extra[extras] = next_token(p, e)).empty()) ++extras;
      if (!out.begun()) {
        for (int k = 0; k < 3 && extras == 3; ++k)
          if (attribute_selected(out.options(), kColours[k])) {
            colour_slot[k] = int(out.header().attributes.size());
            out.header().attributes.push_back({kColours[k], ScalarType::F32});
          }
        out.begin();
      }
      if (out.vertex_count() >= kMaxVertices) in.fail("more than 4294967295 vertices");
      float* row = out.add_vertex(xyz[0], xyz[1], xyz[2]);
      // Colours as written (0..1 or 0..255, not checked). A vertex without colours in a
      // coloured file gets 0 (black) rather than failing.
      for (int k = 0; k < 3; ++k)
        if (colour_slot[k] >= 0) row[colour_slot[k]] = extras == 3 ? parse_coordinate(in, extra[k]) : 0.0f;
    } else if (key[0] == 'f') {
      const uint64_t defined = out.vertex_count();
      PolygonFan fan(out);  // emits nothing before the third corner
      uint64_t corners = 0;
      for (std::string_view tok = next_token(p, e); !tok.empty(); tok = next_token(p, e), ++corners)
        fan.add(parse_corner(in, tok, defined, forward));
      if (corners < 3) in.fail("face with " + std::to_string(corners) + " corners (at least 3 needed)");
      fan.end();
    }
    // Other one-letter records (g, o, s, l, p) are ignored.
  }
  const uint64_t vertices = out.vertex_count();
  if (vertices == 0) throw InputError(error_at(in.path(), "no vertices ('v' records) in OBJ file"));
  // Before end(): the sink may hold triangles pointing past the last vertex until this passes.
  if (forward.index > vertices)
    throw InputError(error_at_line(in.path(), forward.line,
                                   "face index " + std::to_string(forward.index) + " is out of range (the file defines " +
                                       std::to_string(vertices) + " vertices)"));
  out.flush();
}

}  // namespace streamcvd
