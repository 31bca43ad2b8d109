// read_mesh and read_mesh_with_attributes: a MeshSink that appends read_mesh_stream's blocks to
// a MeshBuffers, merging STL corners (sent by value) into shared vertices, then validate_soup.
#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <thread>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/mesh_reader.h"

namespace streamcvd {

namespace {

constexpr uint64_t kMaxVertices = std::numeric_limits<uint32_t>::max();

/// Deduplicates vertices: slots hold vertex index + 1 (0 = empty), keys live in `positions`, so
/// the table costs 8-16 bytes per vertex. Linear probing, load factor kept at or below 1/2.
/// Keys are bit patterns: the reader has already folded -0.0 onto +0.0.
class VertexMerger {
 public:
  explicit VertexMerger(std::vector<float>& positions) : positions_(positions) {}

  /// Sizes the table for about `expected_vertices` (it grows past that when needed).
  void expect(uint64_t expected_vertices) {
    uint64_t size = 1024;
    while (size < 2 * expected_vertices) size *= 2;
    slots_.assign(size, 0);
    mask_ = size - 1;
  }

  /// Index of the vertex xyz[0..2], appending it when new. Returns false when the mesh would
  /// exceed 2^32-1 vertices.
  bool insert(const float* xyz, uint32_t& index) {
    uint32_t key[3];
    std::memcpy(key, xyz, sizeof key);
    for (uint64_t s = hash(key) & mask_;; s = (s + 1) & mask_) {
      uint32_t slot = slots_[s];
      if (slot == 0) {
        uint64_t count = positions_.size() / 3;
        if (count >= kMaxVertices) return false;
        index = uint32_t(count);
        slots_[s] = index + 1;
        positions_.insert(positions_.end(), xyz, xyz + 3);
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

/// Pages in the arrays reserved for the mesh from a second thread while the reading thread
/// fills them: madvise(MADV_POPULATE_WRITE) maps pages without changing their contents, so the
/// copy of each block does not stop for a page fault every 4 KiB (~0.06 s of a 190 MB binary
/// PLY). Best effort: failures (old kernel) end it quietly; arrays under 8 MiB are skipped.
/// stop() before an array is reallocated or freed.
class PageIn {
 public:
  PageIn() = default;
  PageIn(const PageIn&) = delete;
  PageIn& operator=(const PageIn&) = delete;
  ~PageIn() { stop(); }

  /// Starts on the ranges [data, data + bytes), in order.
  void start(std::vector<std::pair<const void*, size_t>> ranges) {
    stop();
    std::erase_if(ranges, [](const auto& r) { return r.second < (size_t(8) << 20); });
    if (ranges.empty()) return;
    stop_.store(false);
    thread_ = std::thread([this, ranges = std::move(ranges)] {
      const uintptr_t page = uintptr_t(::sysconf(_SC_PAGESIZE));
      for (const auto& [data, bytes] : ranges) {
        const uintptr_t lo = (uintptr_t(data) + page - 1) & ~(page - 1), hi = (uintptr_t(data) + bytes) & ~(page - 1);
        for (uintptr_t p = lo; p < hi && !stop_.load(std::memory_order_relaxed); p += kStep)
          if (::madvise(reinterpret_cast<void*>(p), std::min(kStep, hi - p), MADV_POPULATE_WRITE) != 0) return;
      }
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

/// At most how many records of `min_bytes` the input can hold: header counts size the arrays
/// only up to this (a lying header must not allocate; zstd is assumed to inflate ≤ 64×).
uint64_t records_bound(const MeshHeaderInfo& h, uint64_t count, uint64_t min_bytes) {
  if (count == MeshHeaderInfo::kUnknown || h.input_bytes == 0) return 0;
  return std::min(count, h.input_bytes * (h.compressed ? 64 : 1) / min_bytes);
}

class Collector final : public MeshSink {
 public:
  Collector(std::string name, MeshWithAttributes& out, bool keep_attributes, uint64_t memory_limit)
      : name_(std::move(name)),
        out_(out),
        keep_attributes_(keep_attributes),
        memory_limit_(memory_limit),
        merger_(out.mesh.positions) {}

  // Throws when the soup would outgrow the memory limit.
  void check_memory(uint64_t vertices, uint64_t triangles) const {
    const uint64_t bytes = 12 * vertices + 12 * triangles + (merge_ ? 16 * vertices : 0);
    if (memory_limit_ == 0 || bytes <= memory_limit_) return;
    throw InputError(error_at(name_, "the whole mesh needs more than --memory " + format_size(memory_limit_) +
                                         " in RAM for this command (" + std::to_string(vertices) + " vertices, " +
                                         std::to_string(triangles) + " triangles); raise --memory, or ingest it into "
                                         "a store and give the store"));
  }
  static std::string format_size(uint64_t b) { return std::to_string((b + (1 << 20) - 1) >> 20) + " MiB"; }

  void begin(const MeshHeaderInfo& header) override {
    if (header.vertices != MeshHeaderInfo::kUnknown && header.faces != MeshHeaderInfo::kUnknown)
      check_memory(header.vertices, header.faces);
    merge_ = header.corners_by_value;
    out_.attributes = header.attributes;
    MeshBuffers& m = out_.mesh;
    // Binary records are at least 3 bytes a vertex (uchar x y z) and 4 a face (uchar 3 + 3 uchar).
    if (merge_) {
      const uint64_t faces = records_bound(header, header.faces, 50);
      m.triangles.reserve(3 * faces);
      m.positions.reserve(3 * (faces / 2 + 3));  // a closed mesh has V ≈ F/2
      merger_.expect(faces / 2 + 3);
    } else {
      const uint64_t vertices = records_bound(header, header.vertices, 3);
      m.positions.reserve(3 * vertices);
      m.triangles.reserve(3 * records_bound(header, header.faces, 4));
      if (keep_attributes_) out_.values.reserve(vertices * header.attributes.size());
    }
    // In the order the file fills them.
    std::pair<const void*, size_t> positions{m.positions.data(), m.positions.capacity() * sizeof(float)};
    std::pair<const void*, size_t> triangles{m.triangles.data(), m.triangles.capacity() * sizeof(uint32_t)};
    if (header.vertices_before_triangles) page_in_.start({positions, triangles});
    else page_in_.start({triangles, positions});
  }

  void vertices(std::span<const float> xyz, std::span<const float> attributes) override {
    MeshBuffers& m = out_.mesh;
    check_memory(m.positions.size() / 3 + xyz.size() / 3, m.triangles.size() / 3);
    if (m.positions.size() + xyz.size() > m.positions.capacity()) page_in_.stop();  // it will move
    if (keep_attributes_) out_.values.insert(out_.values.end(), attributes.begin(), attributes.end());
    if (!merge_) {
      m.positions.insert(m.positions.end(), xyz.begin(), xyz.end());
      return;
    }
    // STL: corner 3t+k of triangle t becomes the merged id of its coordinates.
    if (m.triangles.size() + xyz.size() / 3 > m.triangles.capacity()) page_in_.stop();
    for (size_t i = 0; i < xyz.size(); i += 3) {
      uint32_t id;
      if (!merger_.insert(&xyz[i], id)) throw InputError(error_at(name_, "more than 4294967295 vertices"));
      m.triangles.push_back(id);
    }
  }

  void triangles(std::span<const uint32_t> corners) override {
    check_memory(out_.mesh.positions.size() / 3, out_.mesh.triangles.size() / 3 + corners.size() / 3);
    if (!merge_) {
      std::vector<uint32_t>& t = out_.mesh.triangles;
      if (t.size() + corners.size() > t.capacity()) page_in_.stop();  // it will move
      t.insert(t.end(), corners.begin(), corners.end());
      return;
    }
    // Already added from the corners; the ids must be the implicit 3t, 3t+1, 3t+2.
    for (uint32_t c : corners)
      if (c != corners_seen_++) throw std::logic_error("STL reader broke the corners_by_value order");
  }

  void end(const ReadStats& stats) override {
    page_in_.stop();
    out_.mesh.polygons_split = stats.polygons_split;
  }

 private:
  std::string name_;  // for messages
  MeshWithAttributes& out_;
  bool keep_attributes_;
  uint64_t memory_limit_;
  bool merge_ = false;
  VertexMerger merger_;
  uint64_t corners_seen_ = 0;
  PageIn page_in_;  // last: stopped before anything else goes
};

MeshWithAttributes collect(const std::string& path, const ReadOptions& options, bool keep_attributes) {
  const std::string name = path == "-" ? "stdin" : path;  // as InputStream names it
  MeshWithAttributes result;
  Collector sink(name, result, keep_attributes, options.memory_limit);
  read_mesh_stream(path, sink, options);
  validate_soup(name, result.mesh);
  return result;
}

}  // namespace

MeshBuffers read_mesh(const std::string& path) { return read_mesh(path, ReadOptions{}); }

MeshBuffers read_mesh(const std::string& path, const ReadOptions& read) {
  ReadOptions options = read;
  options.attributes = ReadOptions::Attributes::None;
  return std::move(collect(path, options, false).mesh);
}

MeshWithAttributes read_mesh_with_attributes(const std::string& path, const ReadOptions& options) {
  return collect(path, options, true);
}

void validate_soup(const std::string& path, const MeshBuffers& mesh) {
  if (mesh.positions.size() % 3 != 0)
    throw InputError(error_at(path, "position array length " + std::to_string(mesh.positions.size()) + " is not a multiple of 3"));
  if (mesh.triangles.size() % 3 != 0)
    throw InputError(error_at(path, "index array length " + std::to_string(mesh.triangles.size()) + " is not a multiple of 3"));
  const uint64_t v = mesh.positions.size() / 3;
  if (v == 0) throw InputError(error_at(path, "no vertices"));
  if (v > 0xFFFFFFFFull) throw InputError(error_at(path, "more than 2^32-1 vertices (" + std::to_string(v) + ")"));
  // Cheap whole-array tests first (they vectorize); the slow loops only run to name the culprit.
  uint32_t non_finite = 0;  // exponent bits all set: inf or nan (std::isfinite does not vectorize)
  for (float x : mesh.positions) non_finite |= (std::bit_cast<uint32_t>(x) & 0x7f800000u) == 0x7f800000u;
  if (non_finite)
    for (size_t i = 0; i < mesh.positions.size(); ++i)
      if (!std::isfinite(mesh.positions[i]))
        throw InputError(error_at(path, "vertex " + std::to_string(i / 3) + " has a non-finite coordinate (" +
                                            std::to_string(mesh.positions[i]) + ")"));
  uint32_t max_index = 0;
  for (uint32_t t : mesh.triangles) max_index = t > max_index ? t : max_index;
  if (!mesh.triangles.empty() && max_index >= v)
    for (size_t i = 0; i < mesh.triangles.size(); ++i)
      if (mesh.triangles[i] >= v)
        throw InputError(error_at(path, "face " + std::to_string(i / 3) + " uses vertex " +
                                            std::to_string(mesh.triangles[i]) + " of " + std::to_string(v)));
}

}  // namespace streamcvd
