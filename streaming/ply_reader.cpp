// PLY reader (G. Turk, "The PLY polygon file format", 1994): ascii, binary_little_endian and
// binary_big_endian, any elements and properties in any order. Only vertex x/y/z and the face
// list "vertex_indices"/"vertex_index" are kept; everything else is skipped without allocating.
// Speed: binary records are decoded straight out of InputStream::fill() blocks, with fast paths
// for "float x y z ..." vertices and "uchar count + int/uint indices" faces; ascii lines are
// tokenized by hand and numbers parsed with fast_float (no iostreams).
#include <fast_float/fast_float.h>

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <string>
#include <string_view>
#include <thread>
#include <vector>

#include "core/errors.h"
#include "streaming/input_stream.h"
#include "streaming/mesh_io.h"

namespace streamcvd {

namespace {

enum class Encoding { Ascii, BinaryLittle, BinaryBig };
enum class Scalar : uint8_t { I8, U8, I16, U16, I32, U32, F32, F64 };

struct ScalarName {
  std::string_view name;
  Scalar type;
};
constexpr ScalarName kScalarNames[] = {
    {"char", Scalar::I8},    {"int8", Scalar::I8},     {"uchar", Scalar::U8},   {"uint8", Scalar::U8},
    {"short", Scalar::I16},  {"int16", Scalar::I16},   {"ushort", Scalar::U16}, {"uint16", Scalar::U16},
    {"int", Scalar::I32},    {"int32", Scalar::I32},   {"uint", Scalar::U32},   {"uint32", Scalar::U32},
    {"float", Scalar::F32},  {"float32", Scalar::F32}, {"double", Scalar::F64}, {"float64", Scalar::F64}};

size_t scalar_size(Scalar t) {
  constexpr size_t kSize[] = {1, 1, 2, 2, 4, 4, 4, 8};
  return kSize[static_cast<int>(t)];
}
bool is_integer(Scalar t) { return t != Scalar::F32 && t != Scalar::F64; }

struct Property {
  std::string name;
  Scalar type = Scalar::F32;  // value type; for a list, the item type
  bool is_list = false;
  Scalar count_type = Scalar::U8;
};

struct Element {
  std::string name;
  uint64_t count = 0;
  std::vector<Property> props;
  bool fixed = true;        // no list property: every record has record_bytes bytes
  size_t record_bytes = 0;  // binary: scalars + list counts (= the record size when fixed)
};

struct Header {
  Encoding encoding = Encoding::Ascii;
  std::vector<Element> elements;
  int vertex = -1, face = -1;        // element indices
  int px = -1, py = -1, pz = -1;     // x, y, z property indices in the vertex element
  int indices = -1;                  // vertex index list in the face element
  size_t last_needed = 0;            // elements after this one are never read
};

// ---- header ------------------------------------------------------------------------------

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

Header parse_header(InputStream& in) {
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

  for (size_t i = 0; i < h.elements.size(); ++i) {
    Element& e = h.elements[i];
    for (const Property& p : e.props) {
      e.fixed = e.fixed && !p.is_list;
      e.record_bytes += scalar_size(p.is_list ? p.count_type : p.type);
    }
    if (e.name == "vertex" && h.vertex < 0) h.vertex = int(i);
    else if (e.name == "face" && h.face < 0) h.face = int(i);
    else if (e.name == "vertex" || e.name == "face") fail("duplicate element '" + e.name + "'");
  }
  if (h.vertex < 0 || h.elements[h.vertex].count == 0) fail("no vertices (element vertex is missing or empty)");
  const Element& ve = h.elements[h.vertex];
  if (ve.count > 0xFFFFFFFFull) fail("more than 2^32-1 vertices (" + std::to_string(ve.count) + ")");
  for (size_t k = 0; k < ve.props.size(); ++k) {
    int* slot = ve.props[k].name == "x" ? &h.px : ve.props[k].name == "y" ? &h.py : ve.props[k].name == "z" ? &h.pz : nullptr;
    if (!slot) continue;
    if (ve.props[k].is_list) fail("vertex property " + ve.props[k].name + " is a list");
    *slot = int(k);
  }
  if (h.px < 0 || h.py < 0 || h.pz < 0) fail("element vertex lacks an x, y or z property");
  h.last_needed = size_t(h.vertex);
  if (h.face >= 0) {
    const Element& fe = h.elements[h.face];
    for (size_t k = 0; k < fe.props.size(); ++k)
      if (fe.props[k].name == "vertex_indices" || fe.props[k].name == "vertex_index") {
        if (!fe.props[k].is_list) fail("face property " + fe.props[k].name + " is not a list");
        if (!is_integer(fe.props[k].type)) fail("face vertex indices must have an integer type");
        h.indices = int(k);
        break;
      }
    if (h.indices < 0) fail("element face has no vertex_indices list");
    h.last_needed = std::max(h.last_needed, size_t(h.face));
  }
  return h;
}

// Fails fast when the header promises more records than the rest of an uncompressed file can
// hold (e.g. "element vertex 4000000000" in a 100-byte file), before any allocation.
void check_counts_fit(InputStream& in, const Header& h) {
  if (in.compressed() || in.file_size() == 0) return;  // no exact bound on decompressed size
  const bool ascii = h.encoding == Encoding::Ascii;
  double need = 0;  // double: counts × sizes may exceed 2^64
  for (size_t i = 0; i <= h.last_needed; ++i) {
    const Element& e = h.elements[i];
    // ascii: at least one character and one separator per value; faces need 1 + 3 values.
    double bytes = ascii ? 2.0 * double(e.props.size()) : double(e.record_bytes);
    if (int(i) == h.face) bytes += ascii ? 6.0 : 3.0 * double(scalar_size(e.props[h.indices].type));
    need += bytes * double(e.count);
  }
  if (ascii) need -= 1;  // the last line may lack its newline
  const uint64_t left = in.max_elements(1);
  if (need > double(left))
    throw InputError(error_at_byte(in.path(), in.offset(),
                                   "header counts need at least " + std::to_string(uint64_t(std::min(need, 1e19))) +
                                       " bytes of data but only " + std::to_string(left) + " follow"));
}

// ---- binary body -------------------------------------------------------------------------

template <class T>
T load(const char* p, bool swap) {
  if constexpr (sizeof(T) == 1) {
    T v;
    std::memcpy(&v, p, 1);
    return v;
  } else {
    using U = std::conditional_t<sizeof(T) == 2, uint16_t, std::conditional_t<sizeof(T) == 4, uint32_t, uint64_t>>;
    U u;
    std::memcpy(&u, p, sizeof u);
    if (swap) {
      if constexpr (sizeof(T) == 2) u = __builtin_bswap16(u);
      else if constexpr (sizeof(T) == 4) u = __builtin_bswap32(u);
      else u = __builtin_bswap64(u);
    }
    return std::bit_cast<T>(u);
  }
}

int64_t load_int(const char* p, Scalar t, bool swap) {
  switch (t) {
    case Scalar::I8: return load<int8_t>(p, swap);
    case Scalar::U8: return load<uint8_t>(p, swap);
    case Scalar::I16: return load<int16_t>(p, swap);
    case Scalar::U16: return load<uint16_t>(p, swap);
    case Scalar::I32: return load<int32_t>(p, swap);
    case Scalar::U32: return load<uint32_t>(p, swap);
    default: return 0;  // the header parser only lets integer types reach here
  }
}

float load_coord(const char* p, Scalar t, bool swap) {
  if (t == Scalar::F32) return load<float>(p, swap);
  if (t == Scalar::F64) return static_cast<float>(load<double>(p, swap));
  return static_cast<float>(load_int(p, t, swap));
}

// A window over the stream's buffer: readers look at up to a few MiB at once and consume
// them in one go, instead of copying record by record.
class Cursor {
 public:
  explicit Cursor(InputStream& in) : in_(in) {}
  ~Cursor() { in_.consume(size_t(p_ - begin_)); }
  /// Makes at least n bytes available at data(); false when the data ends first.
  bool ensure(size_t n) {
    if (size_t(end_ - p_) >= n) return true;
    in_.consume(size_t(p_ - begin_));
    std::span<const char> s = in_.fill(std::max(n, kBlock));
    begin_ = p_ = s.data();
    end_ = p_ + s.size();
    return s.size() >= n;
  }
  const char* data() const { return p_; }
  size_t available() const { return size_t(end_ - p_); }
  void advance(size_t n) { p_ += n; }
  uint64_t offset() const { return in_.offset() + uint64_t(p_ - begin_); }

 private:
  static constexpr size_t kBlock = size_t(1) << 20;
  InputStream& in_;
  const char* begin_ = nullptr;
  const char* p_ = nullptr;
  const char* end_ = nullptr;
};

// Fan triangulation (v0, v[j-1], v[j]) of a polygon whose corners arrive one by one.
struct Fan {
  std::vector<uint32_t>& out;
  uint32_t first = 0, prev = 0;
  uint64_t corners = 0;
  void add(uint32_t v) {
    if (corners == 0) first = v;
    else if (corners >= 2) out.insert(out.end(), {first, prev, v});
    prev = v;
    ++corners;
  }
};

// Pages in an array's reserved capacity from a second thread while the (serial) parse fills it:
// madvise(MADV_POPULATE_WRITE) maps the pages without changing their contents, so the parse does
// not stop for a page fault every 4 KiB (~0.07 s of a 190 MB binary PLY). Best effort: failures
// (old kernel) are ignored, small arrays skipped.
class Prefault {
 public:
  Prefault() = default;
  Prefault(const Prefault&) = delete;
  Prefault& operator=(const Prefault&) = delete;
  ~Prefault() { stop(); }

  void start(const void* data, size_t bytes) {
    stop();
    if (bytes < (size_t(8) << 20)) return;
    const uintptr_t page = uintptr_t(::sysconf(_SC_PAGESIZE));
    const uintptr_t lo = (uintptr_t(data) + page - 1) & ~(page - 1), hi = (uintptr_t(data) + bytes) & ~(page - 1);
    stop_.store(false);
    thread_ = std::thread([this, lo, hi] {
      for (uintptr_t p = lo; p < hi && !stop_.load(std::memory_order_relaxed); p += kStep)
        if (::madvise(reinterpret_cast<void*>(p), std::min(kStep, hi - p), MADV_POPULATE_WRITE) != 0) return;
    });
  }
  void stop() {
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
  }

 private:
  static constexpr uintptr_t kStep = uintptr_t(2) << 20;  // checks for stop() between steps
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

struct BinaryReader {
  InputStream& in;
  const Header& h;
  MeshBuffers& mesh;
  bool swap;
  Cursor cur;
  uint32_t nv;
  Prefault prefault{};  // of the array being filled

  [[noreturn]] void fail_at(uint64_t offset, const std::string& problem) const {
    throw InputError(error_at_byte(in.path(), offset, problem));
  }
  // Makes n bytes available at cur.data(); the check is inline, the refill and the error are not.
  void need(size_t n, const Element& e, uint64_t i) {
    if (cur.available() < n) [[unlikely]] refill(n, e, i);
  }
  [[gnu::noinline]] void refill(size_t n, const Element& e, uint64_t i) {
    if (!cur.ensure(n))
      fail_at(cur.offset() + cur.available(), "unexpected end of file in " + e.name + " " + std::to_string(i) + " of " +
                                                  std::to_string(e.count));
  }
  void check_finite(const float* xyz, size_t n, uint64_t first_vertex, uint64_t first_offset, size_t stride) {
    uint32_t bad = 0;  // bit test instead of std::isfinite so the loop vectorizes
    for (size_t i = 0; i < n; ++i) bad |= (std::bit_cast<uint32_t>(xyz[i]) & 0x7f800000u) == 0x7f800000u;
    if (!bad) return;
    for (size_t i = 0; i < n; ++i)
      if (!std::isfinite(xyz[i]))
        fail_at(first_offset + (i / 3) * stride,
                "vertex " + std::to_string(first_vertex + i / 3) + " has a non-finite coordinate");
  }
  // Checks index v of face `face` (whose record starts at byte `start`) and adds it to the fan.
  void corner(Fan& fan, int64_t v, uint64_t face, uint64_t start) const {
    if (v < 0) fail_at(start, "face " + std::to_string(face) + " has negative vertex index " + std::to_string(v));
    if (v >= int64_t(nv))
      fail_at(start, "face " + std::to_string(face) + " uses vertex " + std::to_string(v) + " of " + std::to_string(nv));
    fan.add(uint32_t(v));
  }
  void skip_bytes(uint64_t n, const Element& e, uint64_t i) {
    while (n > 0) {
      need(1, e, i);
      const size_t step = size_t(std::min<uint64_t>(n, cur.available()));
      cur.advance(step);
      n -= step;
    }
  }
  // Skips property p of record i (which starts at byte `start`), scalar or list.
  void skip_property(const Property& p, const Element& e, uint64_t i, uint64_t start) {
    if (!p.is_list) return skip_bytes(scalar_size(p.type), e, i);
    need(scalar_size(p.count_type), e, i);
    const int64_t n = load_int(cur.data(), p.count_type, swap);
    if (n < 0) fail_at(start, e.name + " " + std::to_string(i) + ": negative list length " + std::to_string(n));
    cur.advance(scalar_size(p.count_type));
    skip_bytes(uint64_t(n) * scalar_size(p.type), e, i);  // n < 2^32 and size ≤ 8: no overflow
  }
  void skip_element(const Element& e) {
    if (e.fixed) {
      const uint64_t limit = ~uint64_t(0) / std::max<size_t>(e.record_bytes, 1);
      return skip_bytes(e.count > limit ? ~uint64_t(0) : e.count * e.record_bytes, e, 0);
    }
    for (uint64_t i = 0; i < e.count; ++i) {
      const uint64_t start = cur.offset();
      for (const Property& p : e.props) skip_property(p, e, i, start);
    }
  }

  void read_vertices(const Element& e) {
    mesh.positions.reserve(3 * std::min<uint64_t>(e.count, in.max_elements(e.record_bytes)));
    prefault.start(mesh.positions.data(), mesh.positions.capacity() * sizeof(float));
    if (!e.fixed) return read_vertices_generic(e);
    const Property &px = e.props[h.px], &py = e.props[h.py], &pz = e.props[h.pz];
    size_t ox = 0, oy = 0, oz = 0, off = 0;
    for (size_t k = 0; k < e.props.size(); ++k) {
      if (int(k) == h.px) ox = off;
      if (int(k) == h.py) oy = off;
      if (int(k) == h.pz) oz = off;
      off += scalar_size(e.props[k].type);
    }
    const size_t stride = e.record_bytes;
    const bool native_float = !swap && px.type == Scalar::F32 && py.type == Scalar::F32 && pz.type == Scalar::F32;
    // Whole blocks of records at once; "float x y z" alone is one memcpy per block.
    for (uint64_t done = 0; done < e.count;) {
      need(stride, e, done);
      const uint64_t k = std::min<uint64_t>(e.count - done, cur.available() / stride);
      const size_t old = mesh.positions.size();
      mesh.positions.resize(old + 3 * k);
      float* out = mesh.positions.data() + old;
      const char* src = cur.data();
      if (native_float && stride == 12 && ox == 0 && oy == 4 && oz == 8) {
        std::memcpy(out, src, 12 * k);
      } else if (native_float) {
        for (uint64_t i = 0; i < k; ++i, src += stride) {
          std::memcpy(out + 3 * i, src + ox, 4);
          std::memcpy(out + 3 * i + 1, src + oy, 4);
          std::memcpy(out + 3 * i + 2, src + oz, 4);
        }
      } else {
        for (uint64_t i = 0; i < k; ++i, src += stride) {
          out[3 * i] = load_coord(src + ox, px.type, swap);
          out[3 * i + 1] = load_coord(src + oy, py.type, swap);
          out[3 * i + 2] = load_coord(src + oz, pz.type, swap);
        }
      }
      check_finite(out, 3 * k, done, cur.offset(), stride);
      cur.advance(k * stride);
      done += k;
    }
  }

  void read_vertices_generic(const Element& e) {
    for (uint64_t i = 0; i < e.count; ++i) {
      const uint64_t start = cur.offset();
      float xyz[3] = {0, 0, 0};
      for (size_t k = 0; k < e.props.size(); ++k) {
        const Property& p = e.props[k];
        const int axis = int(k) == h.px ? 0 : int(k) == h.py ? 1 : int(k) == h.pz ? 2 : -1;
        if (axis < 0) {
          skip_property(p, e, i, start);
          continue;
        }
        need(scalar_size(p.type), e, i);
        xyz[axis] = load_coord(cur.data(), p.type, swap);
        cur.advance(scalar_size(p.type));
      }
      check_finite(xyz, 3, i, start, 0);
      mesh.positions.insert(mesh.positions.end(), xyz, xyz + 3);
    }
  }

  // Fast path: copies the run of valid triangles starting at face f that the window holds,
  // 13 bytes each ("3" + three native int/uint indices); returns how many.
  uint64_t triangle_run(const Element& e, uint64_t f) {
    need(1, e, f);
    if (cur.available() < 13 && !cur.ensure(13)) return 0;  // the generic path reports the end of data
    const uint64_t most = std::min<uint64_t>(e.count - f, cur.available() / 13);
    const size_t old = mesh.triangles.size();
    mesh.triangles.resize(old + 3 * most);
    uint32_t* out = mesh.triangles.data() + old;
    const char* p = cur.data();
    uint64_t k = 0;
    for (; k < most && p[0] == 3; ++k, p += 13, out += 3) {
      std::memcpy(out, p + 1, 12);
      if ((out[0] >= nv) | (out[1] >= nv) | (out[2] >= nv)) break;
    }
    mesh.triangles.resize(old + 3 * k);
    cur.advance(13 * k);
    return k;
  }

  void read_faces(const Element& e) {
    const Property& list = e.props[h.indices];
    const size_t isz = scalar_size(list.type);
    mesh.triangles.reserve(3 * std::min<uint64_t>(e.count, in.max_elements(e.record_bytes + 3 * isz)));
    prefault.start(mesh.triangles.data(), mesh.triangles.capacity() * sizeof(uint32_t));
    // "uchar count + int/uint indices" and nothing else: the layout of nearly every binary PLY.
    const bool fast = e.props.size() == 1 && list.count_type == Scalar::U8 && isz == 4 && !swap;
    for (uint64_t f = 0; f < e.count;) {
      const uint64_t run = fast ? triangle_run(e, f) : 0;
      f += run;
      if (run == 0) read_face(e, f++);  // polygons and errors: the generic path, one face at a time
    }
  }

  void read_face(const Element& e, uint64_t f) {
    const uint64_t start = cur.offset();
    for (size_t k = 0; k < e.props.size(); ++k) {
      const Property& p = e.props[k];
      if (int(k) != h.indices) {
        skip_property(p, e, f, start);
        continue;
      }
      const size_t csz = scalar_size(p.count_type), isz = scalar_size(p.type);
      need(csz, e, f);
      const int64_t n = load_int(cur.data(), p.count_type, swap);
      if (n < 3)
        fail_at(start, "face " + std::to_string(f) + " has " + std::to_string(n) + " vertices (at least 3 needed)");
      cur.advance(csz);
      Fan fan{mesh.triangles};
      // At most 4096 indices per window, so that a huge count never needs a huge buffer.
      for (uint64_t j = 0; j < uint64_t(n);) {
        const uint64_t m = std::min<uint64_t>(uint64_t(n) - j, 4096);
        need(m * isz, e, f);
        for (uint64_t q = 0; q < m; ++q) corner(fan, load_int(cur.data() + q * isz, p.type, swap), f, start);
        cur.advance(m * isz);
        j += m;
      }
      if (n > 3) ++mesh.polygons_split;
    }
  }

  void run() {
    for (size_t i = 0; i <= h.last_needed; ++i) {
      const Element& e = h.elements[i];
      if (int(i) == h.vertex) read_vertices(e);
      else if (int(i) == h.face) read_faces(e);
      else skip_element(e);
    }
  }
};

// ---- ascii body --------------------------------------------------------------------------
// A tokenizer over fill() blocks rather than next_line(): each block is cut after its last line
// break, so every line in [p, e) ends with '\n' or '\r' and that break is the sentinel that stops
// every scan without bounds checks. Line numbers are counted here.

inline bool is_blank(char c) { return c == ' ' || c == '\t' || c == '\v' || c == '\f'; }
inline bool is_break(char c) { return c == '\n' || c == '\r'; }
inline const char* skip_blanks(const char* q) {
  while (is_blank(*q)) ++q;
  return q;
}

enum class Action : uint8_t { X, Y, Z, Indices, Scalar, List };

struct AsciiReader {
  InputStream& in;
  const Header& h;
  MeshBuffers& mesh;
  uint32_t nv;
  uint64_t line = 0;              // number of the line at p
  const char* block = nullptr;    // start of the current block in the stream's buffer
  const char* p = nullptr;        // parse position
  const char* e = nullptr;        // end of the complete lines of the block
  std::string tail;               // last unterminated line + '\n', at end of data
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
    while (!is_blank(*t) && !is_break(*t) && t - q < 40) ++t;
    fail(problem + " '" + std::string(q, t) + "'");
  }

  // Next block of complete lines; false at end of data.
  bool refill() {
    if (block) in.consume(size_t(p - block));
    block = nullptr;
    constexpr size_t kBlock = size_t(1) << 20, kMaxLine = size_t(256) << 20;
    for (size_t want = kBlock;; want *= 2) {
      std::span<const char> s = in.fill(want);
      if (s.empty()) return false;
      const bool end_of_data = s.size() < want;
      const char* cut = static_cast<const char*>(memrchr(s.data(), '\n', s.size()));
      if (!cut) {  // old Mac files end lines with a lone '\r'
        cut = static_cast<const char*>(memrchr(s.data(), '\r', s.size() - (end_of_data ? 0 : 1)));
      }
      if (cut) {
        block = p = s.data();
        e = cut + 1;
        return true;
      }
      if (end_of_data) {
        tail.assign(s.data(), s.size());
        tail += '\n';
        in.consume(s.size());
        p = tail.data();
        e = p + tail.size();
        return true;
      }
      if (s.size() >= kMaxLine) {
        ++line;
        fail("line longer than 256 MiB");
      }
    }
  }
  // Skips blank lines up to the next record; false at end of data.
  bool start_record() {
    for (;;) {
      const char* q = p;
      while (q < e) {
        q = skip_blanks(q);
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
  const char* start_token(const char* q) {
    q = skip_blanks(q);
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

  const char* polygon(const char* q) {
    int64_t n;
    q = integer(q, n);
    if (n < 3) fail("has " + std::to_string(n) + " vertices (at least 3 needed)");
    Fan fan{mesh.triangles};
    for (int64_t j = 0; j < n; ++j) {
      int64_t v;
      q = integer(q, v);
      if (v < 0) fail("negative vertex index " + std::to_string(v));
      if (v >= int64_t(nv)) fail("uses vertex " + std::to_string(v) + " of " + std::to_string(nv));
      fan.add(uint32_t(v));
    }
    if (n > 3) ++mesh.polygons_split;
    return q;
  }

  void read_element(const Element& el, int role) {  // role: 0 skip, 1 vertex, 2 face
    elem = &el;
    std::vector<Action> plan;
    for (size_t k = 0; k < el.props.size(); ++k) {
      Action a = el.props[k].is_list ? Action::List : Action::Scalar;
      if (role == 1 && int(k) == h.px) a = Action::X;
      if (role == 1 && int(k) == h.py) a = Action::Y;
      if (role == 1 && int(k) == h.pz) a = Action::Z;
      if (role == 2 && int(k) == h.indices) a = Action::Indices;
      plan.push_back(a);
    }
    if (role == 1) mesh.positions.reserve(3 * std::min<uint64_t>(el.count, in.max_elements(2 * el.props.size())));
    if (role == 2) mesh.triangles.reserve(3 * std::min<uint64_t>(el.count, in.max_elements(8)));
    for (record = 0; record < el.count; ++record) {
      if (!start_record()) {
        fail("unexpected end of file (" + el.name + " " + std::to_string(record) + " of " +
             std::to_string(el.count) + " is missing)");
      }
      const char* q = p;
      if (role == 0) {  // one record per line; its content does not matter
        while (!is_break(*q)) ++q;
        p = end_line(q);
        continue;
      }
      float xyz[3];
      for (size_t k = 0; k < plan.size(); ++k) {
        switch (plan[k]) {
          case Action::X:
          case Action::Y:
          case Action::Z: {
            const char* s = skip_blanks(q);
            float& v = xyz[int(plan[k])];
            if (el.props[k].type == Scalar::F32) {
              q = real(q, v);
            } else {
              double d;
              q = real(q, d);
              v = static_cast<float>(d);
            }
            if (!std::isfinite(v)) fail_token(s, "non-finite coordinate");
            break;
          }
          case Action::Indices: q = polygon(q); break;
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
      q = skip_blanks(q);
      if (!is_break(*q)) fail_token(q, "more values on the line than the header declares:");
      p = end_line(q);
      if (role == 1) mesh.positions.insert(mesh.positions.end(), xyz, xyz + 3);
    }
  }

  void run() {
    line = in.line_number() + 1;
    for (size_t i = 0; i <= h.last_needed; ++i)
      read_element(h.elements[i], int(i) == h.vertex ? 1 : int(i) == h.face ? 2 : 0);
  }
};

}  // namespace

MeshBuffers read_ply(InputStream& in) {
  const Header h = parse_header(in);
  check_counts_fit(in, h);
  MeshBuffers mesh;
  const uint32_t nv = static_cast<uint32_t>(h.elements[h.vertex].count);
  if (h.encoding == Encoding::Ascii) {
    AsciiReader reader{in, h, mesh, nv, 0, nullptr, nullptr, nullptr, {}, nullptr, 0};
    reader.run();
  } else {
    const bool file_big = h.encoding == Encoding::BinaryBig;
    BinaryReader{in, h, mesh, file_big != (std::endian::native == std::endian::big), Cursor(in), nv}.run();
  }
  return mesh;
}

}  // namespace streamcvd
