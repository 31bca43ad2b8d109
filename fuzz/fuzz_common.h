// Shared plumbing of the libFuzzer targets: the readers and the store loader read files, so each
// input is written to a scratch file (in /dev/shm when it exists, so no disk I/O) and read back
// through the public entry points. InputError is the expected outcome for most inputs; any
// other exception, a crash, a leak, a sanitizer report, a broken MeshSink contract or a timeout
// is a finding. RecordingSink also serves the reader tests (tests/mesh_stream_test.cpp).
#pragma once

#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/io/mesh_reader.h"
#include "streamcvd/streaming/store/store.h"
#include "streamcvd/streaming/store/store_clean.h"

namespace streamcvd::fuzz {

/// A private scratch folder of this fuzzing process, removed at exit.
inline const std::string& scratch_dir() {
  static const std::string dir = [] {
    std::error_code ec;
    std::filesystem::path base = std::filesystem::is_directory("/dev/shm", ec) ? "/dev/shm" : "/tmp";
    std::filesystem::path p = base / ("streamcvd_fuzz_" + std::to_string(::getpid()));
    std::filesystem::create_directories(p);
    static struct Remove {
      std::filesystem::path p;
      ~Remove() {
        std::error_code e;
        std::filesystem::remove_all(p, e);
      }
    } remove{p};
    return p.string();
  }();
  return dir;
}

/// Writes `bytes` to `path` (replacing it); aborts on an I/O error (not a finding of the target).
inline void write_bytes(const std::string& path, std::string_view bytes) {
  FILE* f = std::fopen(path.c_str(), "wb");
  if (!f || (!bytes.empty() && std::fwrite(bytes.data(), 1, bytes.size(), f) != bytes.size()) || std::fclose(f) != 0) {
    std::perror(path.c_str());
    std::abort();
  }
}

/// One zstd frame of `bytes` (level 1: the fuzzer wants speed, not ratio).
inline std::string zstd_compress(std::string_view bytes) {
  std::string out(ZSTD_compressBound(bytes.size()), '\0');
  size_t n = ZSTD_compress(out.data(), out.size(), bytes.data(), bytes.size(), 1);
  if (ZSTD_isError(n)) std::abort();
  out.resize(n);
  return out;
}

/// The mesh-file targets: the first byte of the input chooses how the rest is presented.
///   bit 0: compress it with zstd first (the decompressing InputStream path)
///   bit 1: name the file without an extension (format sniffed from the content)
/// Returns the path written.
inline std::string write_mesh_input(const uint8_t* data, size_t size, const char* extension) {
  if (size == 0) return {};
  const uint8_t mode = data[0];
  std::string_view body(reinterpret_cast<const char*>(data + 1), size - 1);
  std::string path = scratch_dir() + "/input" + ((mode & 2) ? std::string() : std::string(extension));
  if (mode & 1) {
    path += (mode & 2) ? "" : ".zst";
    write_bytes(path, zstd_compress(body));
  } else {
    write_bytes(path, body);
  }
  return path;
}

/// Records what read_mesh_stream hands out and checks the MeshSink contract (mesh_reader.h) as
/// the blocks arrive: begin() first and once, blocks of 1 to `block` elements, attribute rows
/// of header.attributes.size() floats, ids below header.vertices where the reader checks them
/// (PLY, OFF), corners_by_value ids 3t, 3t+1, 3t+2 after their vertices, no vertex block after
/// a triangle block when vertices_before_triangles, end() once with matching counts, and every
/// id (OBJ forward references too) below the final vertex count by then. `violation` names the
/// first rule broken (empty: none).
struct RecordingSink final : MeshSink {
  explicit RecordingSink(uint32_t block_size) : block(block_size) {}

  uint32_t block;
  MeshHeaderInfo header;
  ReadStats stats;
  std::vector<float> xyz, attributes;
  std::vector<uint32_t> corners;
  std::vector<size_t> vertex_blocks, triangle_blocks;  ///< block sizes, in vertices / triangles
  int begins = 0, ends = 0;
  std::string violation;

  void check(bool ok, const char* rule) {
    if (!ok && violation.empty()) violation = rule;
  }
  void begin(const MeshHeaderInfo& h) override {
    check(begins == 0 && ends == 0 && vertex_blocks.empty() && triangle_blocks.empty(), "begin() not first and once");
    ++begins;
    header = h;
  }
  void vertices(std::span<const float> v, std::span<const float> a) override {
    check(begins == 1 && ends == 0, "vertices() outside begin()/end()");
    check(v.size() % 3 == 0 && v.size() >= 3 && v.size() <= 3 * size_t(block), "vertex block size");
    check(a.size() == header.attributes.size() * (v.size() / 3), "attribute row size");
    check(!header.vertices_before_triangles || triangle_blocks.empty(), "vertices after triangles");
    for (float x : v) check(std::isfinite(x), "non-finite coordinate");
    vertex_blocks.push_back(v.size() / 3);
    xyz.insert(xyz.end(), v.begin(), v.end());
    attributes.insert(attributes.end(), a.begin(), a.end());
  }
  void triangles(std::span<const uint32_t> t) override {
    check(begins == 1 && ends == 0, "triangles() outside begin()/end()");
    check(t.size() % 3 == 0 && t.size() >= 3 && t.size() <= 3 * size_t(block), "triangle block size");
    const bool bounded = header.format == MeshFormat::Ply || header.format == MeshFormat::Off;
    for (uint32_t id : t) {
      if (bounded) check(id < header.vertices, "id not below the announced vertex count");
      if (header.corners_by_value) {
        check(id == corners.size(), "corners_by_value ids are not 3t, 3t+1, 3t+2");
        check(id < xyz.size() / 3, "corners_by_value triangle before its vertices");
      }
      corners.push_back(id);
    }
    triangle_blocks.push_back(t.size() / 3);
  }
  void end(const ReadStats& s) override {
    check(begins == 1 && ends == 0, "end() not last and once");
    ++ends;
    stats = s;
    check(s.vertices == xyz.size() / 3 && s.triangles == corners.size() / 3, "ReadStats counts");
    check(s.triangles > 0, "end() without triangles");
    for (uint32_t id : corners) check(id < xyz.size() / 3, "id past the last vertex at end()");
  }
};

/// Runs `body`; InputError is an accepted outcome, anything else escaping is a finding.
template <class Body>
void expect_input_error_or_success(Body body) {
  try {
    body();
  } catch (const InputError&) {
  }
}

/// Store inputs: a whole store laid end to end.
///   byte 0      mode: bit 0 set = leave out file number (mode >> 1) % 10 (0 = header.bin)
///   104 bytes   header.bin
///   then        the arrays in the order of store.h, each as long as the header says (clamped
///               to what is left, so short inputs give short files)
/// Writes the store into `dir` (emptied first).
inline void write_store_input(const uint8_t* data, size_t size, const std::string& dir) {
  struct FileSpec {
    const char* name;
    uint64_t element;
  };
  static constexpr FileSpec kFiles[] = {{"positions.f32", 4}, {"triangles.u32", 4}, {"vv_offsets.u64", 8},
                                        {"vv.u32", 4},        {"vf_offsets.u64", 8}, {"vf.u32", 4},
                                        {"flags.u8", 1},      {"chunks.bin", 64},    {"original_ids.u32", 4}};
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
  std::filesystem::create_directories(dir);
  if (size == 0) return;
  const uint8_t mode = data[0];
  const int left_out = (mode & 1) ? (mode >> 1) % 10 : -1;
  const char* p = reinterpret_cast<const char*>(data + 1);
  size_t rest = size - 1;
  StoreHeader h;
  const size_t header_bytes = std::min(rest, sizeof(StoreHeader));
  std::memcpy(&h, p, header_bytes);
  if (left_out != 0) write_bytes(dir + "/header.bin", std::string_view(p, header_bytes));
  p += header_bytes;
  rest -= header_bytes;
  const uint64_t entries[9] = {3 * h.vertex_count, 3 * h.face_count,    h.vertex_count + 1,
                               h.vertex_vertex_count, h.vertex_count + 1, h.vertex_face_count,
                               h.vertex_count,     h.chunk_count,       h.vertex_count};
  for (int i = 0; i < 9; ++i) {
    const size_t n = entries[i] > rest / kFiles[i].element ? rest : size_t(entries[i] * kFiles[i].element);
    if (left_out != i + 1) write_bytes(dir + "/" + kFiles[i].name, std::string_view(p, n));
    p += n;
    rest -= n;
  }
}

/// One input of a mesh-reader target: read_mesh_stream in small blocks (3 to 10 elements, from
/// the mode byte) through a RecordingSink, then the in-RAM collector, which must agree with it
/// (same success, same soup and attributes); then (when
/// it reads) the topology statistics and the in-RAM store (adjacency of whatever soup came out:
/// repeated indices, non-manifold fans, isolated vertices). Aborts on a contract violation.
inline void run_mesh_input(const uint8_t* data, size_t size, const char* extension) {
  const std::string path = write_mesh_input(data, size, extension);
  if (path.empty()) return;
  ReadOptions read_options;
  read_options.block = 3 + (data[0] >> 2) % 8;
  RecordingSink sink(read_options.block);
  bool streamed = false;
  expect_input_error_or_success([&] {
    read_mesh_stream(path, sink, read_options);
    streamed = true;
  });
  if (!sink.violation.empty()) {
    std::fprintf(stderr, "MeshSink contract broken: %s\n", sink.violation.c_str());
    std::abort();
  }
  MeshWithAttributes read;
  bool collected = false;
  expect_input_error_or_success([&] {
    read = read_mesh_with_attributes(path, read_options);  // same attribute choice: same checks
    collected = true;
  });
  // Same file, same answer: the collector keeps the blocks as they came (STL: merges corners).
  if (streamed != collected || (streamed && sink.ends != 1)) std::abort();
  if (!collected) return;
  const MeshBuffers& mesh = read.mesh;
  if (sink.stats.triangles != mesh.face_count() || read.values.size() != sink.attributes.size()) std::abort();
  if (!sink.header.corners_by_value && (mesh.positions != sink.xyz || mesh.triangles != sink.corners)) std::abort();
  expect_input_error_or_success([&] {
    TopologyStats stats = compute_topology_stats(mesh.view());
    if (stats.vertices != mesh.vertex_count() || stats.faces != mesh.face_count()) std::abort();
    StoreBuildOptions options;
    options.faces_per_chunk = 4;  // several chunks even for tiny meshes
    options.clean_topology = false;
    MeshStore store = MeshStore::build(mesh.view(), options);
    if (store.view().vertex_count() != mesh.vertex_count()) std::abort();
    // The topology cleaning of that store (streaming/store/store_clean.h): it adds one vertex per
    // extra fan and drops faces, never vertices.
    StoreBuildReport report;
    MeshStore cleaned = clean_store_topology(std::move(store), options, report, {});
    if (cleaned.view().vertex_count() != mesh.vertex_count() + report.cleaning.vertex_copies) std::abort();
    if (cleaned.view().face_count() > mesh.face_count()) std::abort();
  });
}

/// One input of the store target: MeshStore::open, then a walk over every CSR range and index
/// of the opened store (must stay in bounds) and the topology statistics.
inline void run_store_input(const uint8_t* data, size_t size) {
  const std::string dir = scratch_dir() + "/store";
  write_store_input(data, size, dir);
  expect_input_error_or_success([&] {
    MeshStore store = MeshStore::open(dir);
    const MeshView m = store.view();
    uint64_t sum = 0;
    for (uint32_t v = 0; v < m.vertex_count(); ++v) {
      for (uint32_t u : m.neighbours(v)) sum += m.positions[3 * size_t(u)] != 0;
      for (uint32_t f : m.faces_of(v)) sum += m.triangles[3 * size_t(f)];
      sum += m.vertex_flags[v] + store.original_vertex_ids()[v];
    }
    for (const Chunk& c : m.chunks) sum += c.vertex_end - c.vertex_begin;
    TopologyStats stats = compute_topology_stats(m.soup());
    if (stats.vertices != m.vertex_count() || sum == 1) std::abort();  // sum: keep the walk
  });
}

}  // namespace streamcvd::fuzz
