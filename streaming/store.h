// The compact mesh store: flat little-endian arrays in one directory, memory-mapped.
// Layout (DESIGN.md §2), one file per array, each mapped read-only:
//   header.bin        StoreHeader (magic, version, counts, bbox, chunk count)
//   positions.f32     float32[3V]   vertices renumbered along a 3D Hilbert curve
//   triangles.u32     uint32[3F]    faces sorted by owner (smallest vertex id), orientation kept
//   vv_offsets.u64 / vv.u32         CSR vertex→vertex (sorted neighbours)
//   vf_offsets.u64 / vf.u32         CSR vertex→face (ascending face ids)
//   flags.u8          uint8[V]      VertexFlag bits
//   chunks.bin        Chunk[C]      contiguous vertex ranges of ~1M owned faces
//   original_ids.u32  uint32[V]     input vertex id of each store vertex
// The in-RAM build writes exactly these arrays, so an external-memory build can replace it
// without changing anything downstream.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "core/mesh_buffers.h"
#include "core/mesh_view.h"

namespace streamcvd {

struct StoreHeader {
  char magic[8] = {'S', 'C', 'V', 'D', 'S', 'T', 'O', 'R'};
  uint32_t version = 1;
  uint32_t chunk_count = 0;
  uint64_t vertex_count = 0;
  uint64_t face_count = 0;
  uint64_t vertex_vertex_count = 0;  ///< entries of vv.u32
  uint64_t vertex_face_count = 0;    ///< entries of vf.u32 (= 3F)
  float bbox_min[3] = {0, 0, 0};
  float bbox_max[3] = {0, 0, 0};
  uint64_t reserved[4] = {0, 0, 0, 0};
};

struct StoreBuildOptions {
  uint64_t faces_per_chunk = uint64_t(1) << 20;  ///< target owned faces per chunk (~1M)
  bool hilbert_order = true;                     ///< false keeps input order (for tests)
};

/// Owns the arrays of a store, in RAM (built from a soup) or memory-mapped (opened from disk).
/// Thread-safety: immutable after construction; view() may be shared by any number of threads.
class MeshStore {
 public:
  MeshStore();
  ~MeshStore();
  MeshStore(MeshStore&&) noexcept;
  MeshStore& operator=(MeshStore&&) noexcept;

  /// Builds the store in RAM: Hilbert renumbering (ties broken by input id), faces remapped with
  /// their corner order kept and counting-sorted by owner (stable), CSR adjacency, flags, chunks
  /// of ~faces_per_chunk owned faces with bbox and halo counts (halo1: faces not owned by the
  /// chunk touching its vertices; halo3: not owned, touching a vertex ≤ 2 edges from the chunk).
  /// O(V log V + F) time, TBB-parallel, output independent of the thread count. Peak memory
  /// beyond the soup ≈ 1.1-1.2× the store size (most temporaries are freed before the adjacency
  /// is built; vertex→vertex needs V extra entries while it runs). Throws InputError for
  /// indices ≥ V, V or F ≥ 2^32, or faces_per_chunk == 0.
  static MeshStore build(const TriangleSoupView& soup, const StoreBuildOptions& options = {});
  /// Same, consuming `soup`: its arrays are freed as soon as they have been copied into the
  /// store, which lowers the peak memory of ingesting a file by the soup's size.
  static MeshStore build(MeshBuffers&& soup, const StoreBuildOptions& options = {});
  /// build(std::move(soup)) followed by write(directory), except that each array is written
  /// (by one background thread) as soon as it is final, so the disk works while the rest is
  /// built. Same result, same crash safety; the old store in `directory` is invalidated only
  /// once the soup has passed its checks. Throws InputError / OutputError.
  static MeshStore build_and_write(MeshBuffers&& soup, const std::string& directory,
                                   const StoreBuildOptions& options = {});
  /// Maps a store directory written by write(). Throws InputError "<dir>/<file>: <problem>"
  /// (missing file, bad magic/version, sizes that disagree with the header). Also validates,
  /// in one parallel O(V + F) pass over the index arrays, everything that would make an
  /// algorithm read out of bounds: CSR offsets monotone and ending at the entry count,
  /// triangle, neighbour and original ids < V, vertex-face entries < F, chunks tiling [0,V) and [0,F).
  static MeshStore open(const std::string& directory);

  /// Writes every array into `directory` (created if needed). An existing header.bin is removed
  /// first and the new one written last, each array through a temporary file that is synced
  /// before any is renamed (streaming/store_writer.h), so an interrupted write never leaves a
  /// valid-looking store. Throws OutputError.
  void write(const std::string& directory) const;

  MeshView view() const;
  const StoreHeader& header() const;
  /// Input vertex id of each store vertex (store order → file order).
  std::span<const uint32_t> original_vertex_ids() const;
  /// Bytes of all arrays (the store's size on disk).
  uint64_t size_bytes() const;

 private:
  static MeshStore build_from(const TriangleSoupView& soup, const StoreBuildOptions& options, MeshBuffers* consumed,
                              const std::string* directory);

  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// True when `path` is a store directory (holds header.bin with the store magic).
bool is_store_directory(const std::string& path);

/// Opens `path` as a store directory, or reads it as a mesh file and builds the store in RAM.
MeshStore load_mesh_or_store(const std::string& path, const StoreBuildOptions& options = {});

}  // namespace streamcvd
