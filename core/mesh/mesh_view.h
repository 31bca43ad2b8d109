// Flat-array views of a triangle mesh: the only way algorithms see a mesh.
// The same view points into RAM vectors or into a memory-mapped store (streaming/store/store.h),
// so every algorithm runs unchanged in core and out of core.
#pragma once

#include <algorithm>

#include <cstddef>
#include <cstdint>
#include <span>

namespace streamcvd {

/// Per-vertex flag bits stored in `MeshView::vertex_flags`.
enum VertexFlag : uint8_t {
  kVertexBoundary = 1u << 0,     ///< on an edge used by exactly one face
  kVertexNonManifold = 1u << 1,  ///< on a non-manifold edge, or its face fan is not one disc/half-disc
  kVertexIsolated = 1u << 2,     ///< referenced by no face
};

/// The owner of face f of a store's triangle array: its smallest-index corner. A store's faces
/// are sorted by owner, so a face range maps to a vertex range. O(1).
inline uint32_t face_owner(std::span<const uint32_t> triangles, uint64_t f) {
  return std::min({triangles[3 * f], triangles[3 * f + 1], triangles[3 * f + 2]});
}

/// One contiguous slice of the store: vertices [vertex_begin, vertex_end) and the faces they own
/// (a face is owned by its smallest-index vertex, faces sorted by owner) in [face_begin, face_end).
struct Chunk {
  uint32_t vertex_begin = 0;
  uint32_t vertex_end = 0;
  uint64_t face_begin = 0;
  uint64_t face_end = 0;
  float bbox_min[3] = {0, 0, 0};
  float bbox_max[3] = {0, 0, 0};
  /// Faces the chunk does not own that touch its vertices (its 1-ring halo), counted at build
  /// time so a scheduler can size halo buffers before loading them.
  uint64_t halo_faces = 0;
  /// Its neighbour chunks (sharing a face with it), ascending:
  /// MeshView::chunk_neighbours[neighbour_begin, neighbour_begin + neighbour_count).
  uint32_t neighbour_begin = 0;
  uint32_t neighbour_count = 0;
};
static_assert(sizeof(Chunk) == 64, "Chunk is a 64-byte on-disk record");

/// Triangle soup: what a reader produces and a writer consumes. Positions xyz float32,
/// triangles as three uint32 vertex indices (polygons already fan-triangulated).
struct TriangleSoupView {
  std::span<const float> positions;     ///< 3·V floats
  std::span<const uint32_t> triangles;  ///< 3·F indices, each < V
  uint32_t vertex_count() const { return static_cast<uint32_t>(positions.size() / 3); }
  uint64_t face_count() const { return triangles.size() / 3; }
};

/// Full indexed mesh with adjacency, as laid out by the compact store.
/// CSR arrays: the neighbours of vertex v are adj[offsets[v] .. offsets[v+1]).
/// Vertex ids [begin, end).
struct VertexRange {
  uint32_t begin = 0;
  uint32_t end = 0;
  uint32_t size() const { return end - begin; }
  bool contains(uint32_t v) const { return v - begin < end - begin; }
};

/// Residency hooks of a job whose arrays are mapped from files (streaming/schedule/chunk_scheduler.h): a
/// stage says which vertex range it is about to work on (the job reads its chunks' pages ahead)
/// and when it is done with it (the job may let them go once more than its resident budget is
/// held). Advice only: a missing call costs page faults, never a wrong result. Thread-safe.
class RangeResidency {
 public:
  virtual ~RangeResidency() = default;
  /// `arrays`: the MeshArray bits of the view's arrays the visit reads (the rest is not read ahead).
  virtual void enter(const char* stage, VertexRange range, uint8_t arrays) = 0;
  virtual void leave(const char* stage, VertexRange range) = 0;
  /// Brackets (nested calls count) a stretch whose reads outside range visits are scattered, as
  /// in the clustering's late rounds: a page fault should read its page only, not the kernel's
  /// read-around window, and a visit that reads arrays has them read ahead every time. Must not
  /// throw (ScatteredReads calls it from its destructor).
  virtual void scattered_reads(bool begin) { (void)begin; }
};

/// The arrays of a MeshView a range visit reads, for RangeVisit.
enum MeshArray : uint8_t {
  kReadsPositions = 1u << 0,
  kReadsTriangles = 1u << 1,      ///< the faces the range's vertices own
  kReadsNeighbours = 1u << 2,     ///< vertex_vertex_offsets and vertex_vertex
  kReadsVertexFaces = 1u << 3,    ///< vertex_face_offsets and vertex_face
  kReadsFlags = 1u << 4,
  kReadsAllArrays = 0x1f,
  /// None of the view's arrays, only the job's per-vertex work arrays (read ahead with any
  /// visit): says that the visit reads them all, for a pass that reads nothing else.
  kReadsWorkArrays = 1u << 5,
};

struct MeshView {
  std::span<const float> positions;                 ///< 3·V floats (Hilbert vertex order)
  std::span<const uint32_t> triangles;              ///< 3·F indices, faces sorted by owner vertex
  std::span<const uint64_t> vertex_vertex_offsets;  ///< V+1
  std::span<const uint32_t> vertex_vertex;          ///< sorted neighbour ids per vertex
  std::span<const uint64_t> vertex_face_offsets;    ///< V+1
  std::span<const uint32_t> vertex_face;            ///< incident face ids per vertex, ascending
  std::span<const uint8_t> vertex_flags;            ///< V, VertexFlag bits
  std::span<const Chunk> chunks;                    ///< contiguous vertex ranges covering [0, V)
  std::span<const uint32_t> chunk_neighbours;       ///< neighbour chunk ids (see Chunk::neighbour_begin)
  RangeResidency* residency = nullptr;              ///< the job's residency hooks; null: all resident

  uint32_t vertex_count() const { return static_cast<uint32_t>(positions.size() / 3); }
  uint64_t face_count() const { return triangles.size() / 3; }
  TriangleSoupView soup() const { return {positions, triangles}; }
  std::span<const uint32_t> neighbours(uint32_t v) const {
    return vertex_vertex.subspan(vertex_vertex_offsets[v], vertex_vertex_offsets[v + 1] - vertex_vertex_offsets[v]);
  }
  std::span<const uint32_t> faces_of(uint32_t v) const {
    return vertex_face.subspan(vertex_face_offsets[v], vertex_face_offsets[v + 1] - vertex_face_offsets[v]);
  }
  /// Whether v is on no face: its kVertexIsolated flag (one byte, kReadsFlags), or its face
  /// list in a view without flags.
  bool is_isolated(uint32_t v) const {
    return vertex_flags.empty() ? faces_of(v).empty() : (vertex_flags[v] & kVertexIsolated) != 0;
  }
};

/// Tells the view's residency hooks (if any) that `range` is worked on during its lifetime.
class RangeVisit {
 public:
  RangeVisit(const MeshView& mesh, const char* stage, VertexRange range, uint8_t arrays)
      : hooks_(mesh.residency), stage_(stage), range_(range) {
    if (hooks_) hooks_->enter(stage_, range_, arrays);
  }
  ~RangeVisit() {
    if (hooks_) hooks_->leave(stage_, range_);
  }
  RangeVisit(const RangeVisit&) = delete;
  RangeVisit& operator=(const RangeVisit&) = delete;

 private:
  RangeResidency* hooks_;
  const char* stage_;
  VertexRange range_;
};

/// Marks its lifetime as a stretch of scattered reads for the view's residency hooks (if any).
class ScatteredReads {
 public:
  explicit ScatteredReads(const MeshView& mesh) : hooks_(mesh.residency) {
    if (hooks_) hooks_->scattered_reads(true);
  }
  ~ScatteredReads() {
    if (hooks_) hooks_->scattered_reads(false);
  }
  ScatteredReads(const ScatteredReads&) = delete;
  ScatteredReads& operator=(const ScatteredReads&) = delete;

 private:
  RangeResidency* hooks_;
};

}  // namespace streamcvd
