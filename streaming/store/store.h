// The compact mesh store: flat little-endian arrays in one directory, memory-mapped.
// Layout (DESIGN.md §2), one file per array, each mapped read-only:
//   header.bin             StoreHeader (magic, version, counts, bbox, chunk count)
//   positions.f32          float32[3V]   vertices renumbered along a 3D Hilbert curve
//   triangles.u32          uint32[3F]    faces sorted by owner (smallest vertex id), orientation kept
//   vv_offsets.u64 / vv.u32              CSR vertex→vertex (sorted neighbours)
//   vf_offsets.u64 / vf.u32              CSR vertex→face (ascending face ids)
//   flags.u8               uint8[V]      VertexFlag bits
//   chunks.bin             Chunk[C]      contiguous vertex ranges of ~1M owned faces
//   chunk_neighbours.u32   uint32[]      each chunk's neighbour chunks (Chunk::neighbour_*)
//   original_ids.u32       uint32[V]     input vertex id of each store vertex (STL: first corner)
//   vertex_attributes.f32  float32[A·V]  per-vertex attributes (colour, scalars), row-major
//   attributes.txt                       their names and file types, one "name type" line each
// Built by the external-memory builder (streaming/store/store_build.h), in RAM or on disk: the same
// code, the same bytes.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/mesh_buffers.h"
#include "streamcvd/core/mesh/mesh_view.h"
#include "streamcvd/streaming/io/mesh_reader.h"
#include "streamcvd/streaming/store/store_build.h"

namespace streamcvd {

struct StoreHeader {
  char magic[8] = {'S', 'C', 'V', 'D', 'S', 'T', 'O', 'R'};
  uint32_t version = 2;
  uint32_t chunk_count = 0;
  uint64_t vertex_count = 0;
  uint64_t face_count = 0;
  uint64_t vertex_vertex_count = 0;  ///< entries of vv.u32
  uint64_t vertex_face_count = 0;    ///< entries of vf.u32 (= 3F)
  float bbox_min[3] = {0, 0, 0};
  float bbox_max[3] = {0, 0, 0};
  uint64_t chunk_neighbour_count = 0;  ///< entries of chunk_neighbours.u32
  uint64_t input_vertex_count = 0;     ///< vertex records read (original ids are below it)
  uint32_t attribute_count = 0;        ///< attributes per vertex in vertex_attributes.f32
  uint32_t reserved0 = 0;
  uint64_t reserved[1] = {0};
};

/// Owns the arrays of a store, in RAM (built from a soup or a file) or memory-mapped (opened
/// from disk). Thread-safety: immutable after construction; view() and the validate_*/advise
/// calls may be used by any number of threads.
class MeshStore {
 public:
  MeshStore();
  ~MeshStore();
  MeshStore(MeshStore&&) noexcept;
  MeshStore& operator=(MeshStore&&) noexcept;

  /// Builds the store in RAM from a soup (the builder with everything resident, unless
  /// options.memory_limit makes it spill). Throws InputError for indices ≥ V, V or F ≥ 2^32,
  /// faces_per_chunk == 0. O(V + F) expected time, TBB-parallel, bytes independent of threads
  /// and memory.
  static MeshStore build(const TriangleSoupView& soup, const StoreBuildOptions& options = {});
  /// Same, freeing `soup` once its arrays have been streamed into the builder.
  static MeshStore build(MeshBuffers&& soup, const StoreBuildOptions& options = {});
  /// Streams the mesh file `input` ("-" = standard input) into a temporary store: in RAM when
  /// it fits half of options.memory_limit (or there is no limit), else in anonymous files of
  /// options.work_directory (default TMPDIR), mapped, which vanish with the store (even after
  /// SIGKILL). Either way the build stays within the limit.
  static MeshStore build_from_file(const std::string& input, const StoreBuildOptions& options = {},
                                   const ReadOptions& read = {}, StoreBuildReport* report = nullptr,
                                   std::function<void(const BuildProgress&)> progress = {});
  /// Same as build_from_file for any producer of blocks: `produce(sink)` streams a mesh into
  /// the sink it is given (a reader, a subdivision of another store...).
  static MeshStore build_from_stream(const std::function<void(MeshSink&)>& produce, const StoreBuildOptions& options = {},
                                     StoreBuildReport* report = nullptr,
                                     std::function<void(const BuildProgress&)> progress = {});
  /// Streams the mesh file `input` ("-" = standard input) into the store directory `directory`
  /// in bounded memory (options.memory_limit), then opens it. Crash-safe: the old header is
  /// removed first, arrays are synced before any rename and the header is written last, so an
  /// interrupted ingest never leaves a valid-looking store; scratch files are anonymous.
  /// Throws InputError (bad input, memory below the minimum) or OutputError (cannot write).
  static MeshStore ingest(const std::string& input, const std::string& directory, const StoreBuildOptions& options = {},
                          const ReadOptions& read = {}, StoreBuildReport* report = nullptr,
                          std::function<void(const BuildProgress&)> progress = {});
  /// Maps a store directory. Cheap: checks the header, the file sizes and the chunk and
  /// neighbour tables (O(C)), not the big arrays; each chunk's arrays are checked by
  /// validate_chunk() when first used. Throws InputError "<dir>/<file>: <problem>".
  static MeshStore open(const std::string& directory);

  /// Writes every array into `directory` (created if needed), with the crash-safety protocol of
  /// ingest(). Throws OutputError.
  void write(const std::string& directory) const;

  /// Checks, once per chunk (later calls return at once), everything that would make an
  /// algorithm read out of bounds in chunk c: its CSR offsets monotone and in range, its
  /// triangle, neighbour and original ids < V (resp. input vertices), its vertex-face entries
  /// < F. O(chunk size). Throws InputError naming the file and the entry. Thread-safe.
  void validate_chunk(uint32_t c) const;
  /// validate_chunk for every chunk, in parallel. O(V + F).
  void validate_all() const;

  enum class Advice { WillNeed, DontNeed, Sequential, Random, Normal, Cold };
  /// madvise over the chunk's slices of every mapped array (WillNeed before a visit, Cold or
  /// DontNeed after), or over whole arrays with chunk = kAllChunks. A no-op for a store in RAM.
  static constexpr uint32_t kAllChunks = ~uint32_t(0);
  /// `arrays` (MeshArray bits) limits the advice to those arrays of the chunk; original ids and
  /// attributes are advised only with kReadsAllArrays.
  void advise(uint32_t chunk, Advice advice, uint8_t arrays = kReadsAllArrays) const;

  MeshView view() const;
  const StoreHeader& header() const;
  /// Input vertex id of each store vertex (store order → file order).
  std::span<const uint32_t> original_vertex_ids() const;
  /// header().attribute_count floats per vertex, store order.
  std::span<const float> vertex_attributes() const;
  const std::vector<VertexAttribute>& attributes() const;
  /// A store rebuilt by the topology cleaning (streaming/store/store_clean.h) keeps the input's figures
  /// as read and what the cleaning did (cleaning.txt in its directory): fills `out`'s
  /// topology_checked, input_topology and cleaning (not cleaning.cleaned) and returns true; false
  /// for any other store (a clean input's, one built without cleaning). O(1).
  bool cleaning_report(StoreBuildReport& out) const;
  /// Bytes of all arrays (the store's size on disk).
  uint64_t size_bytes() const;
  /// Bytes of the arrays held in RAM (0 for a store mapped from files).
  uint64_t ram_bytes() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  friend struct StoreAssembly;
  friend MeshStore clean_store_topology(MeshStore&& built, const StoreBuildOptions& options, StoreBuildReport& report,
                                        const std::function<void(const BuildProgress&)>& progress);
};

/// True when `path` is a store directory (holds header.bin with the store magic).
bool is_store_directory(const std::string& path);

/// Opens `path` as a store directory (validating every chunk), or streams it as a mesh file into
/// a store in RAM.
MeshStore load_mesh_or_store(const std::string& path, const StoreBuildOptions& options = {});

}  // namespace streamcvd
