// The topology of a clustering's dual mesh (paper §VI-C) as a K-sized list of oriented triples
// of cluster ids, and the manifold test on such a list: the one mechanism behind
// build_dual_mesh, find_manifold_defects (core/dual_mesh.cpp) and the checks of the repair loop
// (core/repair.cpp). The input mesh is read chunk by chunk (DESIGN.md §6): each chunk emits the
// triples of the faces it owns, the K-sized list is deduplicated by one sort; nothing is sized
// by V or F. Internal to core/.
#pragma once

#include <array>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "core/chunked_components.h"
#include "core/mesh_view.h"

namespace streamcvd::dual {

/// A dual face: three vertex (cluster) ids in the orientation of the input face.
using Face = std::array<uint32_t, 3>;

/// (a, b, c) rotated so the smallest id comes first, keeping the cyclic order (orientation): the
/// canonical form two copies of one oriented face share. Ids must be distinct.
inline Face rotate_smallest_first(uint32_t a, uint32_t b, uint32_t c) {
  if (a < b && a < c) return {a, b, c};
  if (b < a && b < c) return {b, c, a};
  return {c, a, b};
}

/// The dual face of input face `t` (3 vertex ids) under `labels`: true, with the rotated triple,
/// when its three labels are ≥ 0 and distinct (§VI-C).
inline bool face_triple(const uint32_t* t, std::span<const int32_t> labels, Face& out) {
  const int32_t a = labels[t[0]], b = labels[t[1]], c = labels[t[2]];
  if (a < 0 || b < 0 || c < 0 || a == b || b == c || a == c) return false;
  out = rotate_smallest_first(uint32_t(a), uint32_t(b), uint32_t(c));
  return true;
}

/// Faces [begin, end) of one block of chunk-wise work.
struct FaceRange {
  uint64_t begin = 0, end = 0;
};

/// The chunks' owned faces (a view without chunks is one chunk) cut into blocks of at most
/// `max_faces`, in chunk order. Depends on the chunk table only (not on the threads). Throws
/// InputError when the chunks' face ranges do not tile [0, F).
std::vector<FaceRange> chunk_face_blocks(const MeshView& mesh, uint64_t max_faces = uint64_t(1) << 16);

/// The chunks' vertex ranges (chunk_ranges; one range for a view without chunks). Throws
/// InputError when the chunks do not tile [0, V).
std::vector<VertexRange> chunk_vertex_blocks(const MeshView& mesh);

/// Vertices per cluster (K entries; labels −1 are not counted), in parallel over the chunks'
/// vertex ranges. Throws std::invalid_argument unless labels.size() == V.
std::vector<uint32_t> cluster_sizes(const MeshView& mesh, std::span<const int32_t> labels, uint32_t cluster_count);

struct Triples {
  std::vector<Face> faces;  ///< rotated, sorted, unique
  uint64_t emitted = 0;     ///< input faces with three distinct labels (before deduplication)
};

/// The dual faces of every input face with three distinct labels: chunk by chunk in parallel
/// (TBB; each block of a chunk's owned faces sorted and deduplicated on its own), merged in
/// chunk order and deduplicated by one sort of the K-sized list. The result depends on the
/// labels only: not on the chunks, the threads or the storage. O(F) reads + O(D log D) for D
/// dual faces; memory O(D).
Triples collect_triples(const MeshView& mesh, std::span<const int32_t> labels);

/// The dual faces of the input faces around `vertices` that have a corner in a cluster c with
/// in_set[c] (size K): every dual face with a corner in the set when `vertices` lists all the
/// set's members. Rotated, sorted, unique. Parallel over blocks of `vertices`; deterministic.
/// O(Σ faces of the vertices).
std::vector<Face> triples_around(const MeshView& mesh, std::span<const int32_t> labels,
                                 std::span<const uint32_t> vertices, std::span<const uint8_t> in_set);

/// Scratch of fan_defective (one per thread).
struct FanScratch {
  std::vector<std::array<uint32_t, 3>> entries;
  std::vector<uint32_t> parent;
  std::vector<Face> sets;
};

/// True when the faces around vertex x (each holds x once) are not a manifold neighbourhood:
/// an edge at x in more than two faces or twice in one direction, faces in more than one fan
/// (around a vertex, corners only join through its own edges), or two faces on one vertex set.
/// O(n log n) for n faces.
bool fan_defective(uint32_t x, std::span<const Face> fan, FanScratch& scratch);

struct FanVerdict {
  uint32_t vertex = 0;
  bool defective = false;
};

/// fan_defective of each vertex x of `around` (pairs {x, index of a face of `faces` holding x},
/// in any order; sorted here), in parallel over blocks of vertices: one verdict per vertex,
/// ascending.
std::vector<FanVerdict> check_fan_list(std::span<const Face> faces, std::vector<std::pair<uint32_t, uint32_t>>&& around);

/// The manifold verdict of every vertex of `faces` (no face may repeat an index) that
/// selected(x) accepts: one per such vertex that has faces, ascending. A vertex's verdict
/// depends only on the faces that hold it. Deterministic; O(D log D).
template <class Selected>
std::vector<FanVerdict> check_fans(std::span<const Face> faces, const Selected& selected) {
  std::vector<std::pair<uint32_t, uint32_t>> around;  // {vertex, face}
  around.reserve(3 * faces.size());
  for (uint32_t i = 0; i < faces.size(); ++i)
    for (uint32_t x : faces[i])
      if (selected(x)) around.push_back({x, i});
  return check_fan_list(faces, std::move(around));
}

}  // namespace streamcvd::dual
