// PLY ascii bodies: a hand tokenizer over InputStream::fill() windows, numbers parsed with
// fast_float (no iostreams, no per-line copies). Each window is cut after its last line break,
// so every line in [p, e) ends with '\n' or '\r' and that break is the sentinel that stops every
// scan without bounds checks. A line longer than a window (a `tristrips` element is often one
// record: millions of indices on one line) is taken in pieces instead: a piece is copied up to
// its last blank and ends in a NUL sentinel at e, where the token scans also stop; reaching e
// then means "the line goes on in the next window". Line numbers are counted here.
#include <fast_float/fast_float.h>

#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/block_emitter.h"
#include "streamcvd/streaming/io/input_stream.h"
#include "streamcvd/streaming/io/ply_format.h"

namespace streamcvd::ply {

namespace {

inline bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\v' || c == '\f'; }
inline bool is_break(char c) { return c == '\n' || c == '\r'; }
inline const char* skip_blanks(const char* q) {
  while (is_blank(*q)) ++q;
  return q;
}

// What to do with one property of a record (Use, with lists told apart).
enum class Action : uint8_t { X, Y, Z, Attribute, Polygon, Strip, Scalar, List };

struct AsciiReader {
  InputStream& in;
  const Header& h;
  BlockEmitter& out;
  uint32_t nv;
  uint64_t line = 0;              // number of the line at p
  const char* block = nullptr;    // the window's start in the stream's buffer; null for a copy
  const char* p = nullptr;        // parse position (start of the current record)
  const char* e = nullptr;        // end of the window
  bool partial = false;           // the window ends inside a line, at a NUL sentinel
  std::string copy;               // the window when it is a copy (last line, piece of a long line)
  const Element* elem = nullptr;
  uint64_t record = 0;

  ~AsciiReader() {
    if (block) in.consume(size_t(p - block));
  }

  [[noreturn]] void fail(const std::string& problem) const {
    throw InputError(error_at_line(in.path(), line, elem->name + " " + std::to_string(record) + ": " + problem));
  }
  [[noreturn]] void fail_token(const char* q, const std::string& problem) const {
    const char* t = q;
    while (!is_blank(*t) && !is_break(*t) && *t != '\0' && t - q < 40) ++t;
    fail(problem + " '" + std::string(q, t) + "'");
  }

  // Next window; false at end of data.
  bool refill() {
    if (block) in.consume(size_t(p - block));
    block = nullptr;
    partial = false;
    constexpr size_t kWindow = size_t(1) << 20;
    std::span<const char> s = in.fill(kWindow);
    if (s.empty()) return false;
    const bool end_of_data = s.size() < kWindow;
    const char* cut = static_cast<const char*>(memrchr(s.data(), '\n', s.size()));
    if (!cut) {  // old Mac files end lines with a lone '\r' (one kept back: it may precede a '\n')
      cut = static_cast<const char*>(memrchr(s.data(), '\r', s.size() - (end_of_data ? 0 : 1)));
    }
    if (cut) {
      block = p = s.data();
      e = cut + 1;
      return true;
    }
    if (end_of_data) {  // a last line without terminator: a copy with one
      copy.assign(s.data(), s.size());
      copy += '\n';
      in.consume(s.size());
      p = copy.data();
      e = p + copy.size();
      return true;
    }
    // No line break in a whole window: a piece of a long line, up to its last blank.
    const char* blank = s.data() + s.size();
    while (blank > s.data() && !is_blank(blank[-1])) --blank;
    if (blank == s.data()) fail("a value longer than 1 MiB");
    copy.assign(s.data(), size_t(blank - s.data()));
    copy += '\0';
    in.consume(size_t(blank - s.data()));
    p = copy.data();
    e = p + copy.size() - 1;
    partial = true;
    return true;
  }
  // Reached e inside a line: where it goes on. At end of data the line simply ends.
  [[gnu::noinline]] const char* continue_line() {
    static constexpr char kLineEnd[] = "\n";
    if (!refill()) {
      p = kLineEnd;
      e = kLineEnd + 1;
    }
    return p;
  }
  // Skips blanks, across pieces of a long line.
  const char* skip_blanks_across(const char* q) {
    q = skip_blanks(q);
    while (q == e && partial) q = skip_blanks(continue_line());
    return q;
  }
  // Skips blank lines up to the next record; false at end of data.
  bool start_record() {
    for (;;) {
      const char* q = p;
      while (q < e) {
        q = skip_blanks(q);
        if (q == e) break;  // a piece of a long line, all blanks
        if (!is_break(*q)) {
          p = q;
          return true;
        }
        q = end_line(q);
      }
      p = q;
      if (!refill()) return false;
    }
  }
  // Steps over the line break at q, counting the line.
  const char* end_line(const char* q) {
    q += (*q == '\r' && q + 1 < e && q[1] == '\n') ? 2 : 1;
    ++line;
    return q;
  }
  // Rest of a skipped record's line.
  const char* skip_line(const char* q) {
    for (;;) {
      if (!partial) {
        while (!is_break(*q)) ++q;
        return q;
      }
      while (q != e && !is_break(*q)) ++q;
      if (q != e) return q;
      q = continue_line();
    }
  }
  const char* start_token(const char* q) {
    q = skip_blanks_across(q);
    if (is_break(*q)) fail("too few values on the line");
    return q;
  }
  template <class T>
  const char* real(const char* q, T& v) {
    q = start_token(q);
    const char* s = (*q == '+' && q[1] != '-') ? q + 1 : q;  // fast_float rejects a leading '+'
    auto r = fast_float::from_chars(s, e, v);
    if (r.ec != std::errc() || !(is_blank(*r.ptr) || is_break(*r.ptr))) fail_token(q, "non-numeric value");
    return r.ptr;
  }
  const char* integer(const char* q, int64_t& v) {
    q = start_token(q);
    const char* s = q;
    const bool negative = *q == '-';
    q += (*q == '-' || *q == '+');
    const char* digits = q;
    uint64_t u = 0;
    while (unsigned(*q - '0') < 10) u = u * 10 + uint64_t(*q++ - '0');
    if (q == digits || q - digits > 18 || !(is_blank(*q) || is_break(*q))) fail_token(s, "not an integer:");
    v = negative ? -int64_t(u) : int64_t(u);
    return q;
  }
  // Any scalar value as a float (attributes as stored: uchar 200 → 200.0f).
  const char* value(const char* q, Scalar type, float& v) {
    if (type == Scalar::F32) return real(q, v);
    double d;
    q = real(q, d);
    v = static_cast<float>(d);
    return q;
  }

  const char* polygon(const char* q) {
    int64_t n;
    q = integer(q, n);
    if (n < 3) fail("has " + std::to_string(n) + " vertices (at least 3 needed)");
    PolygonFan fan(out);
    for (int64_t j = 0; j < n; ++j) {
      int64_t v;
      q = integer(q, v);
      if (v < 0 || v >= int64_t(nv)) fail(index_problem(v, nv));
      fan.add(uint32_t(v));
    }
    fan.end();
    return q;
  }

  const char* strip_list(const char* q, Scalar type, StripDecoder& strip) {
    int64_t n;
    q = integer(q, n);
    if (n < 0) fail("negative list length");
    const int64_t restart = strip_restart_alias(type, nv);  // "255" in a uchar list, as in binary
    for (int64_t j = 0; j < n; ++j) {
      int64_t v;
      q = integer(q, v);
      if (v == -1 || v == restart) strip.restart();
      else if (v < 0 || v >= int64_t(nv)) fail("item " + std::to_string(j) + ": " + index_problem(v, nv));
      else strip.add(uint32_t(v));
    }
    strip.restart();  // the list's end ends its last strip
    return q;
  }

  void read_element(const Element& el) {
    elem = &el;
    std::vector<Action> plan;
    for (const Property& prop : el.props) {
      Action a = prop.is_list ? Action::List : Action::Scalar;
      switch (prop.use) {
        case Use::X: a = Action::X; break;
        case Use::Y: a = Action::Y; break;
        case Use::Z: a = Action::Z; break;
        case Use::Attribute: a = Action::Attribute; break;
        case Use::Corners: a = el.role == Role::Strips ? Action::Strip : Action::Polygon; break;
        case Use::Skip: break;
      }
      plan.push_back(a);
    }
    StripDecoder strip(out);
    for (record = 0; record < el.count; ++record) {
      if (!start_record()) {
        fail("unexpected end of file (" + el.name + " " + std::to_string(record) + " of " +
             std::to_string(el.count) + " is missing)");
      }
      const char* q = p;
      if (el.role == Role::Skip) {  // one record per line; its content does not matter
        p = end_line(skip_line(q));
        continue;
      }
      float* xyz = nullptr;
      float* row = nullptr;
      if (el.role == Role::Vertices) {
        out.reserve_vertices(1);
        xyz = out.vertex_xyz();
        row = out.vertex_attributes();
      }
      for (size_t k = 0; k < plan.size(); ++k) {
        const Property& prop = el.props[k];
        switch (plan[k]) {
          case Action::X:
          case Action::Y:
          case Action::Z: {
            const char* s = skip_blanks_across(q);
            float& v = xyz[int(plan[k])];
            q = value(s, prop.type, v);
            if (!std::isfinite(v)) fail_token(s, "non-finite coordinate");
            break;
          }
          case Action::Attribute: q = value(q, prop.type, row[prop.slot]); break;
          case Action::Polygon: q = polygon(q); break;
          case Action::Strip: q = strip_list(q, prop.type, strip); break;
          case Action::Scalar: {
            double d;
            q = real(q, d);
            break;
          }
          case Action::List: {
            int64_t n;
            q = integer(q, n);
            if (n < 0) fail("negative list length");
            for (double d; n > 0; --n) q = real(q, d);
            break;
          }
        }
      }
      q = skip_blanks_across(q);
      if (!is_break(*q)) fail_token(q, "more values on the line than the header declares:");
      p = end_line(q);
      if (el.role == Role::Vertices) out.commit_vertices(1);
    }
  }

  void run() {
    line = in.line_number() + 1;
    for (size_t i = 0; i <= h.last_needed; ++i) {
      read_element(h.elements[i]);
      out.flush();  // an element's last partial blocks
    }
  }
};

}  // namespace

void read_ascii_body(InputStream& in, const Header& h, BlockEmitter& out) {
  AsciiReader reader{in, h, out, h.vertex_count};
  reader.run();
}

}  // namespace streamcvd::ply
