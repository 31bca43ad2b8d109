// Token helpers shared by the text readers (OBJ, OFF, ascii STL): whitespace, quoting a token
// for a one-line error message, and parsing a coordinate that must be a finite number.
#pragma once

#include <fast_float/fast_float.h>

#include <cmath>
#include <string>
#include <string_view>
#include <system_error>

#include "streamcvd/streaming/io/input_stream.h"

namespace streamcvd::text {

/// Blank characters between tokens (a line's terminator is already stripped).
inline bool is_space(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

/// `tok` in quotes for an error message: at most 40 characters, control bytes shown as '?'.
inline std::string quoted(std::string_view tok) {
  constexpr size_t kShown = 40;  // keep error messages one short line
  std::string s(tok.substr(0, kShown));
  for (char& c : s)
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) c = '?';
  return "'" + s + (tok.size() > kShown ? "...'" : "'");
}

/// One coordinate: the whole token must be a finite number; otherwise `in` fails with the
/// token quoted. fast_float rejects a leading '+', which writers do emit: it is skipped.
inline float parse_coordinate(InputStream& in, std::string_view tok) {
  const char* p = tok.data();
  const char* e = p + tok.size();
  if (p < e && *p == '+' && p + 1 < e && p[1] != '-') ++p;
  float v = 0;
  auto r = fast_float::from_chars(p, e, v);
  if (r.ec != std::errc() || r.ptr != e) in.fail("bad number " + quoted(tok));
  if (!std::isfinite(v)) in.fail("coordinate is not finite: " + quoted(tok));
  return v;
}

}  // namespace streamcvd::text
