// Builds PLY files for the reader tests: any elements, scalar and list properties of any type,
// in ascii or binary little/big endian. Header-only (the test build compiles only *_test.cpp
// and test_util.cpp).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <charconv>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace streamcvd::test {

enum class Enc { Ascii, Le, Be };
inline constexpr Enc kAllEncodings[] = {Enc::Ascii, Enc::Le, Enc::Be};
inline const char* enc_name(Enc e) {
  return e == Enc::Ascii ? "ascii" : e == Enc::Le ? "binary_little_endian" : "binary_big_endian";
}

// A property: scalar when count_type is empty, else a list.
struct Prop {
  std::string type, name, count_type;
};
// One element: its properties and, per record, the values of each property (lists: all items).
struct Elem {
  std::string name;
  std::vector<Prop> props;
  std::vector<std::vector<std::vector<double>>> records;
};

template <class T>
inline void put_bytes(std::string& out, Enc enc, T v) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if ((enc == Enc::Be) == (std::endian::native == std::endian::little)) std::reverse(b, b + sizeof(T));
  out.append(b, sizeof(T));
}

// Appends one value of PLY type `type`; ascii floats use the shortest round-trip form.
inline void put(std::string& out, Enc enc, const std::string& type, double v) {
  const bool f32 = type == "float" || type == "float32", f64 = type == "double" || type == "float64";
  if (enc == Enc::Ascii) {
    char buf[64];
    auto r = f32 ? std::to_chars(buf, buf + 64, float(v)) : f64 ? std::to_chars(buf, buf + 64, v)
                                                               : std::to_chars(buf, buf + 64, int64_t(v));
    out.append(buf, r.ptr);
    out += ' ';
  } else if (f32) put_bytes(out, enc, float(v));
  else if (f64) put_bytes(out, enc, v);
  else if (type == "char" || type == "int8") put_bytes(out, enc, int8_t(int64_t(v)));  // via int64: wraps, no UB
  else if (type == "uchar" || type == "uint8") put_bytes(out, enc, uint8_t(int64_t(v)));
  else if (type == "short" || type == "int16") put_bytes(out, enc, int16_t(int64_t(v)));
  else if (type == "ushort" || type == "uint16") put_bytes(out, enc, uint16_t(int64_t(v)));
  else if (type == "int" || type == "int32") put_bytes(out, enc, int32_t(int64_t(v)));
  else if (type == "uint" || type == "uint32") put_bytes(out, enc, uint32_t(int64_t(v)));
  else ADD_FAILURE() << "bad test type " << type;
}

inline std::string build_ply(Enc enc, const std::vector<Elem>& elems, const std::string& extra_header = "") {
  std::string s = std::string("ply\nformat ") + enc_name(enc) + " 1.0\n" + extra_header;
  for (const Elem& e : elems) {
    s += "element " + e.name + " " + std::to_string(e.records.size()) + "\n";
    for (const Prop& p : e.props)
      s += p.count_type.empty() ? "property " + p.type + " " + p.name + "\n"
                                : "property list " + p.count_type + " " + p.type + " " + p.name + "\n";
  }
  s += "end_header\n";
  for (const Elem& e : elems)
    for (const auto& rec : e.records) {
      for (size_t k = 0; k < e.props.size(); ++k) {
        if (!e.props[k].count_type.empty()) put(s, enc, e.props[k].count_type, double(rec[k].size()));
        for (double v : rec[k]) put(s, enc, e.props[k].type, v);
      }
      if (enc == Enc::Ascii) s.back() = '\n';
    }
  return s;
}

}  // namespace streamcvd::test
