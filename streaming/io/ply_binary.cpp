// PLY binary bodies (little and big endian). Records are decoded straight out of
// InputStream::fill() windows into the emitter's blocks, with fast paths for the layouts of
// nearly every binary PLY: "float x y z" vertices (one memcpy per block) and "uchar count +
// int/uint indices" faces (a run copy, then one range test per triangle).
#include <fcntl.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <bit>
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

/// Any scalar as a float: coordinates, and attributes as stored (uchar 200 → 200.0f).
float load_float(const char* p, Scalar t, bool swap) {
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
    std::span<const char> s = in_.fill(std::max(n, kWindow));
    begin_ = p_ = s.data();
    end_ = p_ + s.size();
    return s.size() >= n;
  }
  const char* data() const { return p_; }
  size_t available() const { return size_t(end_ - p_); }
  void advance(size_t n) { p_ += n; }
  uint64_t offset() const { return in_.offset() + uint64_t(p_ - begin_); }

 private:
  static constexpr size_t kWindow = size_t(1) << 20;
  InputStream& in_;
  const char* begin_ = nullptr;
  const char* p_ = nullptr;
  const char* end_ = nullptr;
};

/// A scalar of a fixed-size record: where it is and what it is.
struct Field {
  size_t offset = 0;
  Scalar type = Scalar::F32;
};

struct BinaryReader {
  InputStream& in;
  const Header& h;
  BlockEmitter& out;
  bool swap;
  Cursor cur;
  uint32_t nv;

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
  [[gnu::noinline, noreturn]] void bad_index(const Element& e, uint64_t record, int64_t v, uint64_t offset) const {
    fail_at(offset, e.name + " " + std::to_string(record) + ": " + index_problem(v, nv));
  }
  // Names the item too, as the ascii reader does: a strip record is often one huge list.
  [[gnu::noinline, noreturn]] void bad_strip_index(const Element& e, uint64_t record, uint64_t item, int64_t v,
                                                   uint64_t offset) const {
    fail_at(offset, e.name + " " + std::to_string(record) + ": item " + std::to_string(item) + ": " + index_problem(v, nv));
  }
  void skip_bytes(uint64_t n, const Element& e, uint64_t i) {
    while (n > 0) {
      need(1, e, i);
      const size_t step = size_t(std::min<uint64_t>(n, cur.available()));
      cur.advance(step);
      n -= step;
    }
  }
  // Reads the count of list p of record i (which starts at byte `start`).
  uint64_t list_count(const Property& p, const Element& e, uint64_t i, uint64_t start) {
    need(scalar_size(p.count_type), e, i);
    const int64_t n = load_int(cur.data(), p.count_type, swap);
    if (n < 0) fail_at(start, e.name + " " + std::to_string(i) + ": negative list length " + std::to_string(n));
    cur.advance(scalar_size(p.count_type));
    return uint64_t(n);
  }
  // Skips property p of record i (which starts at byte `start`), scalar or list.
  void skip_property(const Property& p, const Element& e, uint64_t i, uint64_t start) {
    if (!p.is_list) return skip_bytes(scalar_size(p.type), e, i);
    const uint64_t n = list_count(p, e, i, start);
    skip_bytes(n * scalar_size(p.type), e, i);  // n < 2^32 and size ≤ 8: no overflow
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

  // ---- vertices

  void read_vertices(const Element& e) {
    if (!e.fixed) return read_vertices_generic(e);
    Field axis[3];
    std::vector<Field> attributes;  // in slot order: the header gives slots in file order
    size_t off = 0;
    for (const Property& p : e.props) {
      if (p.use == Use::X || p.use == Use::Y || p.use == Use::Z) axis[int(p.use) - int(Use::X)] = {off, p.type};
      if (p.use == Use::Attribute) attributes.push_back({off, p.type});
      off += scalar_size(p.type);
    }
    const size_t stride = e.record_bytes, na = attributes.size();
    const bool native_float = !swap && axis[0].type == Scalar::F32 && axis[1].type == Scalar::F32 &&
                              axis[2].type == Scalar::F32;
    const bool packed = native_float && stride == 12 && axis[0].offset == 0 && axis[1].offset == 4 && axis[2].offset == 8;
    // Whole windows of records at once; "float x y z" alone is one memcpy per block.
    for (uint64_t done = 0; done < e.count;) {
      need(stride, e, done);
      const size_t k = out.reserve_vertices(std::min<uint64_t>(e.count - done, cur.available() / stride));
      float* xyz = out.vertex_xyz();
      float* row = out.vertex_attributes();
      const char* src = cur.data();
      if (packed) {
        std::memcpy(xyz, src, 12 * k);
      } else if (native_float) {
        for (size_t i = 0; i < k; ++i, src += stride)
          for (int a = 0; a < 3; ++a) std::memcpy(xyz + 3 * i + a, src + axis[a].offset, 4);
      } else {
        for (size_t i = 0; i < k; ++i, src += stride)
          for (int a = 0; a < 3; ++a) xyz[3 * i + a] = load_float(src + axis[a].offset, axis[a].type, swap);
      }
      src = cur.data();
      for (size_t i = 0; na > 0 && i < k; ++i, src += stride, row += na)
        for (size_t j = 0; j < na; ++j) row[j] = load_float(src + attributes[j].offset, attributes[j].type, swap);
      check_finite(xyz, 3 * k, done, cur.offset(), stride);
      out.commit_vertices(k);
      cur.advance(k * stride);
      done += k;
    }
  }

  // Records with lists (rare for vertices): one property at a time.
  void read_vertices_generic(const Element& e) {
    for (uint64_t i = 0; i < e.count; ++i) {
      const uint64_t start = cur.offset();
      out.reserve_vertices(1);
      float* xyz = out.vertex_xyz();
      float* row = out.vertex_attributes();
      xyz[0] = xyz[1] = xyz[2] = 0;
      for (const Property& p : e.props) {
        if (p.use == Use::Skip) {
          skip_property(p, e, i, start);
          continue;
        }
        need(scalar_size(p.type), e, i);
        const float v = load_float(cur.data(), p.type, swap);
        if (p.use == Use::Attribute) row[p.slot] = v;
        else xyz[int(p.use) - int(Use::X)] = v;
        cur.advance(scalar_size(p.type));
      }
      check_finite(xyz, 3, i, start, 0);
      out.commit_vertices(1);
    }
  }

  // ---- faces

  // Fast path: copies the run of valid triangles starting at face f that the window holds,
  // 13 bytes each ("3" + three native int/uint indices); returns how many.
  uint64_t triangle_run(const Element& e, uint64_t f) {
    need(1, e, f);
    if (cur.available() < 13 && !cur.ensure(13)) return 0;  // the generic path reports the end of data
    const size_t most = out.reserve_triangles(std::min<uint64_t>(e.count - f, cur.available() / 13));
    uint32_t* t = out.triangle_corners();
    const char* p = cur.data();
    size_t k = 0;
    for (; k < most && p[0] == 3; ++k, p += 13, t += 3) {
      std::memcpy(t, p + 1, 12);
      if ((t[0] >= nv) | (t[1] >= nv) | (t[2] >= nv)) break;  // negative int indices too
    }
    out.commit_triangles(k);
    cur.advance(13 * k);
    return k;
  }

  void read_faces(const Element& e) {
    const Property* list = nullptr;
    for (const Property& p : e.props)
      if (p.use == Use::Corners) list = &p;
    // "uchar count + int/uint indices" and nothing else: the layout of nearly every binary PLY.
    const bool fast = e.props.size() == 1 && list->count_type == Scalar::U8 && scalar_size(list->type) == 4 && !swap;
    for (uint64_t f = 0; f < e.count;) {
      const uint64_t run = fast ? triangle_run(e, f) : 0;
      f += run;
      if (run == 0) read_face(e, f++);  // polygons and errors: the generic path, one face at a time
    }
  }

  void read_face(const Element& e, uint64_t f) {
    const uint64_t start = cur.offset();
    for (const Property& p : e.props) {
      if (p.use != Use::Corners) {
        skip_property(p, e, f, start);
        continue;
      }
      const uint64_t n = list_count(p, e, f, start);
      if (n < 3) fail_at(start, "face " + std::to_string(f) + " has " + std::to_string(n) + " vertices (at least 3 needed)");
      PolygonFan fan(out);
      const size_t isz = scalar_size(p.type);
      // At most 4096 indices per window, so that a huge count never needs a huge buffer.
      for (uint64_t j = 0; j < n;) {
        const uint64_t m = std::min<uint64_t>(n - j, 4096);
        need(m * isz, e, f);
        for (uint64_t q = 0; q < m; ++q) {
          const int64_t v = load_int(cur.data() + q * isz, p.type, swap);
          if (v < 0 || v >= int64_t(nv)) bad_index(e, f, v, start);
          fan.add(uint32_t(v));
        }
        cur.advance(m * isz);
        j += m;
      }
      fan.end();
    }
  }

  // ---- triangle strips

  void read_strips(const Element& e) {
    StripDecoder strip(out);
    for (uint64_t r = 0; r < e.count; ++r) {
      const uint64_t start = cur.offset();
      for (const Property& p : e.props) {
        if (p.use != Use::Corners) {
          skip_property(p, e, r, start);
          continue;
        }
        const uint64_t n = list_count(p, e, r, start);
        const size_t isz = scalar_size(p.type);
        const int64_t restart = strip_restart_alias(p.type, nv);
        for (uint64_t j = 0; j < n;) {  // windows of 4096 indices, as for faces
          const uint64_t m = std::min<uint64_t>(n - j, 4096);
          need(m * isz, e, r);
          for (uint64_t q = 0; q < m; ++q) {
            const int64_t v = load_int(cur.data() + q * isz, p.type, swap);
            if (v == -1 || v == restart) strip.restart();
            else if (v < 0 || v >= int64_t(nv)) bad_strip_index(e, r, j + q, v, cur.offset() + q * isz);
            else strip.add(uint32_t(v));
          }
          cur.advance(m * isz);
          j += m;
        }
        strip.restart();  // the list's end ends its last strip
      }
    }
  }

  void run() {
    for (size_t i = 0; i <= h.last_needed; ++i) {
      const Element& e = h.elements[i];
      switch (e.role) {
        case Role::Vertices: read_vertices(e); break;
        case Role::Faces: read_faces(e); break;
        case Role::Strips: read_strips(e); break;
        case Role::Skip: skip_element(e); break;
      }
      out.flush();  // an element's last partial blocks
    }
  }
};

/// Bounds and position sample of one block of the prescan (vertices [first, first + n)).
struct PrescanBlock {
  float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  std::vector<float> sample;
  bool ok = true;
};

// Reads block `b` (per_block vertices of `stride` bytes from byte `offset` of fd) into `buffer`
// and measures it: finite coordinates grow the bounds, every sample_stride-th vertex joins the
// sample. The packed "float x y z" layout skips the per-scalar type switch.
void prescan_block(int fd, uint64_t offset, uint64_t count, size_t stride, size_t per_block, const Field* axis,
                   bool swap, uint64_t sample_stride, uint64_t b, std::vector<char>& buffer, PrescanBlock& out) {
  const uint64_t first = b * per_block;
  const size_t n = size_t(std::min<uint64_t>(per_block, count - first)), bytes = n * stride;
  buffer.resize(per_block * stride);
  for (size_t got = 0; got < bytes;) {
    const ssize_t r = ::pread(fd, buffer.data() + got, bytes - got, off_t(offset + first * stride + got));
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) {
      out.ok = false;
      return;
    }
    got += size_t(r);
  }
  const bool packed = !swap && stride == 12 && axis[0].type == Scalar::F32 && axis[1].type == Scalar::F32 &&
                      axis[2].type == Scalar::F32 && axis[0].offset == 0 && axis[1].offset == 4 && axis[2].offset == 8;
  const char* src = buffer.data();
  for (size_t i = 0; i < n; ++i, src += stride) {
    float p[3];
    if (packed) {
      std::memcpy(p, src, 12);
    } else {
      for (int a = 0; a < 3; ++a) p[a] = load_float(src + axis[a].offset, axis[a].type, swap);
    }
    for (int a = 0; a < 3; ++a)
      if (std::isfinite(p[a])) out.lo[a] = std::min(out.lo[a], p[a]), out.hi[a] = std::max(out.hi[a], p[a]);
  }
  // The sample's ids are multiples of sample_stride: the first at or after `first`.
  for (uint64_t v = (first + sample_stride - 1) / sample_stride * sample_stride; v < first + n; v += sample_stride) {
    float p[3];
    for (int a = 0; a < 3; ++a) p[a] = load_float(buffer.data() + (v - first) * stride + axis[a].offset, axis[a].type, swap);
    out.sample.insert(out.sample.end(), p, p + 3);
  }
}

}  // namespace

void prescan_vertex_bounds(InputStream& in, const Header& h, BlockEmitter& out) {
  if (in.compressed() || in.file_size() == 0 || in.path() == "stdin" || in.path() == "-") return;
  uint64_t offset = in.offset();  // uncompressed: bytes of the file consumed by the header
  const Element* vertices = nullptr;
  for (size_t i = 0; i <= h.last_needed && !vertices; ++i) {
    const Element& e = h.elements[i];
    if (!e.fixed) return;  // an element of lists before the vertices: no known offset
    if (e.role == Role::Vertices) vertices = &e;
    else offset += e.count * e.record_bytes;
  }
  if (!vertices || vertices->count == 0) return;
  const Element& e = *vertices;
  const bool swap = (h.encoding == Encoding::BinaryBig) != (std::endian::native == std::endian::big);
  Field axis[3];
  size_t off = 0;
  for (const Property& p : e.props) {
    if (p.use == Use::X || p.use == Use::Y || p.use == Use::Z) axis[int(p.use) - int(Use::X)] = {off, p.type};
    off += scalar_size(p.type);
  }
  const size_t stride = e.record_bytes;
  if (offset + e.count * stride > in.file_size()) return;
  const int fd = ::open(in.path().c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return;
  MeshHeaderInfo& info = out.header();
  uint64_t sample_stride = 1;
  while (e.count / sample_stride > (uint64_t(1) << 17)) sample_stride *= 2;
  // Blocks of ~4 MiB measured in parallel: this pass runs before any other work starts (the
  // whole build waits for it), so it uses every core. Bounds are combined and samples
  // concatenated in block order: the same result whatever the threads.
  const size_t per_block = std::max<size_t>(1, (size_t(4) << 20) / stride);
  const uint64_t blocks = (e.count + per_block - 1) / per_block;
  std::vector<PrescanBlock> parts(blocks);
  tbb::enumerable_thread_specific<std::vector<char>> buffers;
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, blocks, 1), [&](const tbb::blocked_range<uint64_t>& r) {
    for (uint64_t b = r.begin(); b != r.end(); ++b)
      prescan_block(fd, offset, e.count, stride, per_block, axis, swap, sample_stride, b, buffers.local(), parts[b]);
  });
  ::posix_fadvise(fd, off_t(offset), off_t(e.count * stride), POSIX_FADV_DONTNEED);
  ::close(fd);
  float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  std::vector<float> sample;
  for (const PrescanBlock& part : parts) {
    if (!part.ok) return;
    for (int a = 0; a < 3; ++a) lo[a] = std::min(lo[a], part.lo[a]), hi[a] = std::max(hi[a], part.hi[a]);
    sample.insert(sample.end(), part.sample.begin(), part.sample.end());
  }
  info.has_bounds = true;
  std::copy(lo, lo + 3, info.bounds_lo);
  std::copy(hi, hi + 3, info.bounds_hi);
  info.position_sample = std::move(sample);
  info.sample_stride = sample_stride;
}

void read_binary_body(InputStream& in, const Header& h, BlockEmitter& out) {
  const bool file_big = h.encoding == Encoding::BinaryBig;
  BinaryReader{in, h, out, file_big != (std::endian::native == std::endian::big), Cursor(in), h.vertex_count}.run();
}

}  // namespace streamcvd::ply
