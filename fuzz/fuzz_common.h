// Shared plumbing of the libFuzzer targets: the readers and the store loader read files, so each
// input is written to a scratch file (in /dev/shm when it exists, so no disk I/O) and read back
// through the public entry points. InputError is the expected outcome for most inputs; any
// other exception, a crash, a leak, a sanitizer report or a timeout is a finding.
#pragma once

#include <unistd.h>
#include <zstd.h>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "core/errors.h"
#include "core/mesh_stats.h"
#include "streaming/mesh_io.h"
#include "streaming/store.h"

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

/// One input of a mesh-reader target: read_mesh, then (when it reads) the topology statistics
/// and the in-RAM store (adjacency of whatever soup came out: repeated indices, non-manifold
/// fans, isolated vertices). Aborts on a contract violation.
inline void run_mesh_input(const uint8_t* data, size_t size, const char* extension) {
  const std::string path = write_mesh_input(data, size, extension);
  if (path.empty()) return;
  expect_input_error_or_success([&] {
    MeshBuffers mesh = read_mesh(path);
    TopologyStats stats = compute_topology_stats(mesh.view());
    if (stats.vertices != mesh.vertex_count() || stats.faces != mesh.face_count()) std::abort();
    StoreBuildOptions options;
    options.faces_per_chunk = 4;  // several chunks even for tiny meshes
    MeshStore store = MeshStore::build(mesh.view(), options);
    if (store.view().vertex_count() != mesh.vertex_count()) std::abort();
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
