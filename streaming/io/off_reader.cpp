// Geomview OFF reader ([ST][C][N][4][n]OFF), ascii only, polygons fan-triangulated.
// Each vertex / face is read as tokens (so values may spill onto the next line) and the rest of
// its line is then dropped: that skips colours, normals and texture coordinates whatever their
// count (C may mean 3 or 4 values, so they cannot be counted reliably).
#include <fast_float/fast_float.h>

#include <algorithm>
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

/// Whitespace-separated tokens over the stream's lines, '#' starting a comment anywhere.
class Tokens {
 public:
  explicit Tokens(InputStream& in) : in_(in) {}

  /// Next token, moving to later lines as needed; false at end of data.
  bool next(std::string_view& tok) {
    for (;;) {
      if (next_on_line(tok)) return true;
      std::string_view line;
      if (!in_.next_line(line)) return false;
      p_ = line.data();
      e_ = p_ + line.size();
    }
  }
  /// Next token of the current line only.
  bool next_on_line(std::string_view& tok) {
    while (p_ < e_ && is_space(*p_)) ++p_;
    if (p_ == e_ || *p_ == '#') {
      p_ = e_;
      return false;
    }
    const char* s = p_;
    while (p_ < e_ && !is_space(*p_) && *p_ != '#') ++p_;
    tok = {s, size_t(p_ - s)};
    return true;
  }
  /// Forgets what is left of the current line.
  void drop_line() { p_ = e_; }

 private:
  InputStream& in_;
  const char* p_ = nullptr;
  const char* e_ = nullptr;
};

uint64_t parse_count(InputStream& in, std::string_view tok, const char* what) {
  uint64_t v = 0;
  auto r = std::from_chars(tok.data(), tok.data() + tok.size(), v);
  if (r.ec != std::errc() || r.ptr != tok.data() + tok.size())
    in.fail(std::string("bad ") + what + " " + quoted(tok));
  return v;
}

/// The header keyword's prefix letters, in the only order Geomview allows.
struct OffKind {
  bool homogeneous = false;  // "4": x y z w
  bool n_dim = false;        // "n": a dimension follows the keyword
};

bool parse_keyword(std::string_view tok, OffKind& kind) {
  if (tok.size() < 3 || tok.substr(tok.size() - 3) != "OFF") return false;
  std::string_view s = tok.substr(0, tok.size() - 3);
  auto take = [&s](std::string_view p) {
    if (s.substr(0, p.size()) != p) return false;
    s.remove_prefix(p.size());
    return true;
  };
  take("ST");
  take("C");
  take("N");
  kind.homogeneous = take("4");
  kind.n_dim = take("n");
  return s.empty();
}

}  // namespace

void stream_off(InputStream& in, BlockEmitter& out) {
  Tokens tokens(in);
  std::string_view tok;
  if (!tokens.next(tok)) throw InputError(error_at(in.path(), "no OFF header (only blank lines and comments)"));
  OffKind kind;
  bool keyword = tok.find("OFF") != std::string_view::npos;
  if (keyword) {
    if (!parse_keyword(tok, kind)) in.fail("unknown OFF keyword " + quoted(tok));
    if (kind.n_dim) {
      if (!tokens.next(tok)) in.fail("missing dimension after nOFF keyword");
      if (parse_count(in, tok, "dimension") != 3) in.fail("only 3-dimensional OFF is supported");
    }
    if (!tokens.next(tok)) in.fail("missing vertex and face counts");
    if (tok == "BINARY") in.fail("binary OFF is not supported");
  } else if (tok.empty() || !(tok[0] >= '0' && tok[0] <= '9')) {
    in.fail("not an OFF file: expected the OFF keyword, found " + quoted(tok));
  }
  // The keyword is optional (Geomview); tok now holds the vertex count.
  const uint64_t vertex_count = parse_count(in, tok, "vertex count");
  if (!tokens.next(tok)) in.fail("missing face count");
  const uint64_t face_count = parse_count(in, tok, "face count");
  if (tokens.next_on_line(tok)) parse_count(in, tok, "edge count");  // optional and unused
  tokens.drop_line();
  if (vertex_count == 0) in.fail("OFF header declares 0 vertices");
  if (vertex_count > std::numeric_limits<uint32_t>::max()) in.fail("more than 4294967295 vertices");

  MeshHeaderInfo& header = out.header();
  header.vertices = vertex_count;
  header.faces = face_count;
  header.vertices_before_triangles = true;
  out.begin();
  const int coordinates = kind.homogeneous ? 4 : 3;
  for (uint64_t i = 0; i < vertex_count; ++i) {
    float xyzw[4] = {0, 0, 0, 1};
    for (int k = 0; k < coordinates; ++k) {
      if (!tokens.next(tok))
        in.fail("file ends after " + std::to_string(i) + " of " + std::to_string(vertex_count) + " vertices");
      xyzw[k] = parse_coordinate(in, tok);
    }
    if (kind.homogeneous) {
      if (xyzw[3] == 0) in.fail("homogeneous coordinate w is 0");
      for (int k = 0; k < 3; ++k) xyzw[k] /= xyzw[3];
      if (!std::isfinite(xyzw[0]) || !std::isfinite(xyzw[1]) || !std::isfinite(xyzw[2]))
        in.fail("vertex x/w is not finite");
    }
    out.add_vertex(xyzw[0], xyzw[1], xyzw[2]);
    tokens.drop_line();  // colour, normal, texture coordinates
  }
  out.flush();

  for (uint64_t f = 0; f < face_count; ++f) {
    if (!tokens.next(tok))
      in.fail("file ends after " + std::to_string(f) + " of " + std::to_string(face_count) + " faces");
    uint64_t n = parse_count(in, tok, "face corner count");
    if (n < 3) in.fail("face with " + std::to_string(n) + " corners (at least 3 needed)");
    PolygonFan fan(out);
    for (uint64_t k = 0; k < n; ++k) {
      if (!tokens.next(tok)) in.fail("file ends inside face " + std::to_string(f));
      uint64_t v = parse_count(in, tok, "vertex index");
      if (v >= vertex_count)
        in.fail("vertex index " + std::to_string(v) + " is out of range (" + std::to_string(vertex_count) +
                " vertices)");
      fan.add(uint32_t(v));
    }
    fan.end();
    tokens.drop_line();  // optional face colour
  }
  // Anything after the faces (edges, trailing comments) is ignored.
  out.flush();
}

}  // namespace streamcvd
