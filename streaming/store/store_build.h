// The store builder (DESIGN.md §2): one external-memory builder for every input size. It is a
// MeshSink, so a reader streams blocks straight into it; memory is set by `memory_limit`, not by
// the input. Passes, one function each:
//   1. spill    vertices (and attributes) in file order, bounding box, a bounded key sample;
//               faces spilled raw unless the vertex order is already known
//   2. order    Hilbert key of every vertex, records bucketed by key range (ranges from the
//               sample), each bucket sorted in RAM by (key, input id) → positions, attributes,
//               original ids in store order, and the vertex map old → new
//   3. faces    corners remapped, each face bucketed by the vertex range of its owner (smallest
//               corner), in file order
//   4. ranges   per owner range, in order: faces counting-sorted by owner (stable), face ids;
//               faces with corners in later ranges sent there as "foreign" records; vertex→face
//               and vertex→vertex CSR and flags from the owned plus foreign faces (exact across
//               range and chunk frontiers); chunks cut as the owned counts stream by, with their
//               bounding box, halo and neighbour chunks
// With enough memory every bucket stays resident and nothing is spilled: the in-RAM build is
// this builder with resident buckets. The bytes of the store depend on neither the memory limit
// nor the number of threads.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/mesh/mesh_view.h"
#include "streamcvd/core/mesh/progress.h"
#include "streamcvd/streaming/io/mesh_reader.h"

namespace streamcvd {

class ArrayOutput;

struct StoreBuildOptions {
  uint64_t faces_per_chunk = uint64_t(1) << 20;  ///< target owned faces per chunk (~1M)
  bool hilbert_order = true;                     ///< false keeps input order (for tests)
  /// Bytes the build may keep resident (its buffers and buckets), 0 = unlimited. Decides bucket
  /// sizes and what spills to disk, never the result. Below the minimum (32 MiB + 4 bytes per
  /// input vertex) the build refuses to start with an InputError naming the minimum.
  uint64_t memory_limit = 0;
  /// Folder of the scratch files (anonymous files, nothing is left behind); "" = the store's
  /// folder, or TMPDIR (else /tmp) for a store built in RAM.
  std::string work_directory;
  /// Vertex range of one pass-4 unit when memory is unlimited (bounds the working set).
  uint32_t max_range_vertices = 1u << 20;
  /// MeshStore's builds (streaming/store/store.h): clean the input's topology (streaming/store/store_clean.h).
  /// A store with duplicate, degenerate or non-manifold elements is rebuilt from a cleaned soup;
  /// a clean one is left as built (same bytes). false keeps the input as read. StoreBuilder
  /// itself ignores it.
  bool clean_topology = true;
  /// Rewrites, in place and in store order, each block of the input ids before they go to
  /// original_ids.u32 (the cleaning's rebuild maps its input, the first store's vertices and
  /// their copies, back to the file's ids). Empty: the ids as read.
  std::function<void(std::span<uint32_t>)> map_original_ids;
  /// With map_original_ids: the input vertex count the store's header records (0: as read).
  uint64_t original_vertex_count = 0;
};

/// What the topology cleaning did (streaming/store/store_clean.h); all 0 for a clean input.
struct TopologyCleaning {
  bool rebuilt = false;                   ///< defects found: the store was rebuilt from the cleaned soup
  uint64_t duplicate_faces_dropped = 0;   ///< same vertex set as another face (one is kept, or none: below)
  /// Of those, faces of double layers dropped whole: a face and its reverse whose edges the
  /// faces around them already close in pairs (two sides of a wall collapsed onto one layer).
  uint64_t double_layer_faces_dropped = 0;
  uint64_t degenerate_faces_dropped = 0;  ///< a repeated index, or zero area at a non-manifold vertex
  uint64_t nonmanifold_edges_cut = 0;     ///< edges still used by > 2 faces after the drops, paired into sheets
  uint64_t unpaired_edge_faces = 0;       ///< faces of those edges left without a partner: a new boundary
  uint64_t vertices_split = 0;            ///< vertices whose faces fall into several fans
  uint64_t vertex_copies = 0;             ///< vertices added, one per fan beyond the first
  uint64_t unpaired_faces_dropped = 0;    ///< later rounds: unpaired faces of cuts that did not come apart
  uint64_t faces_flipped = 0;             ///< faces turned round so that the surface is consistently oriented
  uint64_t misoriented_edges_cut = 0;     ///< misoriented edges no flip mends (not orientable there), cut open
  uint64_t misoriented_edges_left = 0;    ///< misoriented edges neither mended nor cut (one alone inside a surface)
  uint32_t rounds = 0;                    ///< rebuilds (a second or third only when a cut did not come apart)
  double seconds = 0;                     ///< checks, plan, rebuild
  /// The figures of the store as cleaned (those of the input when nothing was rebuilt; unset
  /// when the build's screen found nothing: StoreBuildReport::input_topology_known).
  TopologyStats cleaned;
  /// Pieces the cut made: components of the cleaned store beyond those of the input.
  int64_t sheets_made(const TopologyStats& input) const { return int64_t(cleaned.components) - int64_t(input.components); }
};

/// Progress of a build (core/mesh/progress.h): `stage` is "read", "order", "faces", "adjacency";
/// `done` / `total` in the stage's own unit (bytes read, vertices, faces, vertex ranges). Called
/// between blocks, "read" from the reading thread, the others from the building one.
using BuildProgress = StageProgress;

/// What a build did: the figures `ingest --json` reports.
struct StoreBuildReport {
  uint64_t input_bytes = 0;      ///< (decompressed) bytes the reader consumed
  uint64_t input_vertices = 0;   ///< vertex records read (STL: corners)
  uint64_t vertices = 0, faces = 0, chunks = 0;
  uint64_t polygons_split = 0, strip_triangles_dropped = 0;
  uint32_t key_buckets = 0, vertex_ranges = 0;  ///< buckets of pass 2, ranges of pass 4
  uint64_t memory_limit = 0;                    ///< the limit planned with (0 = unlimited)
  uint64_t spilled_bytes = 0;                   ///< bytes written to scratch files
  double read_seconds = 0, order_seconds = 0, faces_seconds = 0, adjacency_seconds = 0;
  /// What the topology cleaning acts on, counted while the ranges are built (pass 4): vertices
  /// flagged non-manifold (every non-manifold edge flags its ends, and so does every duplicate
  /// face but an isolated pair), faces with a repeated index, and isolated twin faces (a face
  /// and its twin with no other face at their corners). All zero exactly when the store has
  /// no duplicate, repeated-index or non-manifold element: it then needs no cleaning, and its
  /// full figures are not computed.
  struct TopologyScreen {
    uint64_t nonmanifold_vertices = 0, repeated_index_faces = 0, isolated_twin_faces = 0;
    uint64_t misoriented_edges = 0;  ///< edges two faces run the same way (each found at its tail)
    bool any() const { return nonmanifold_vertices + repeated_index_faces + isolated_twin_faces + misoriented_edges > 0; }
  } screen;
  /// clean_topology ran: the screen's verdict, and what the cleaning did. Unset otherwise.
  bool topology_checked = false;
  /// The input's figures as read (compute_topology_stats of the first build, what `info`
  /// prints): computed only when the screen found something to clean.
  bool input_topology_known = false;
  TopologyStats input_topology;
  TopologyCleaning cleaning;
};

/// Where a build puts each array of the store, front to back (StoreDirectoryWriter streams for
/// a store on disk, RAM buffers for a store in memory). Arrays are named as in streaming/store/store.h.
class StoreOutputs {
 public:
  virtual ~StoreOutputs() = default;
  virtual ArrayOutput& array(const char* name) = 0;
  /// Announces the final size of an array (a RAM output allocates it once instead of growing).
  virtual void expect(const char* name, uint64_t bytes) { (void)name, (void)bytes; }
  /// Announces the store's size before the first array is created (V, and F or an estimate),
  /// so an output can choose between RAM and files.
  virtual void plan(uint64_t vertices, uint64_t faces) { (void)vertices, (void)faces; }
  /// Copies n bytes at `offset` of an array already appended (positions are read back by pass 4).
  virtual void read_back(const char* name, uint64_t offset, void* dst, size_t n) = 0;
};

/// The store header, chunk table and neighbour table a build ends with (small, written last).
struct StoreBuildResult {
  uint64_t vertex_count = 0, face_count = 0, vertex_vertex_count = 0;
  float bbox_min[3] = {0, 0, 0}, bbox_max[3] = {0, 0, 0};
  std::vector<Chunk> chunks;
  std::vector<uint32_t> chunk_neighbours;  ///< CSR entries (ranges in Chunk::neighbour_*)
  std::vector<VertexAttribute> attributes;
  StoreBuildReport report;
};

/// Builds a store from the blocks a reader hands it. Not thread-safe (one reading thread); its
/// passes are TBB-parallel. Throws InputError for inputs no store can hold (indices ≥ V, more
/// than 2^32−1 vertices or faces, a memory limit below the minimum) and OutputError when a
/// scratch or store file cannot be written.
class StoreBuilder final : public MeshSink {
 public:
  StoreBuilder(StoreOutputs& outputs, const StoreBuildOptions& options,
               std::function<void(const BuildProgress&)> progress = {});
  ~StoreBuilder() override;

  void begin(const MeshHeaderInfo& header) override;
  void vertices(std::span<const float> xyz, std::span<const float> attributes) override;
  void triangles(std::span<const uint32_t> corners) override;
  /// Runs the passes that need the whole input (order if not done yet, faces, ranges).
  void end(const ReadStats& stats) override;

  /// The result, once end() has returned.
  StoreBuildResult& result();

  struct State;  // the passes' shared state (streaming/store_build_*.cpp)

 private:
  std::unique_ptr<State> state_;
};

/// Blocks each output stream may keep waiting for the disk under `memory_limit` (0 = none): a
/// range's output is then written while the next range is built. The builder plans with
/// kStreamCount × that many blocks of StoreArrayStream::kBlockBytes.
uint32_t stream_blocks_in_flight(uint64_t memory_limit);
inline constexpr uint32_t kStreamCount = 6;  // arrays written at once (pass 4)

/// Feeds an in-RAM soup to `sink` in blocks, as a reader would (for MeshStore::build).
void stream_soup(const TriangleSoupView& soup, MeshSink& sink, uint32_t block = 1u << 16);

}  // namespace streamcvd
