// The topology of a clustering's dual mesh (paper §VI-C) as a K-sized list of oriented triples
// of cluster ids, and the manifold test on such a list: the one mechanism behind
// build_dual_mesh, find_manifold_defects (core/dual/dual_mesh.cpp) and the checks of the repair
// loop (core/dual/defect_tracker.cpp). The input mesh is read chunk by chunk (DESIGN.md §6): each
// chunk emits the triples of the faces it owns, the K-sized list is deduplicated by one sort;
// nothing is sized by V or F. Internal to core/.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "streamcvd/core/dual/dual_mesh.h"  // Face, Triples
#include "streamcvd/core/mesh/chunked_components.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd::dual {

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

/// Sorts `v` and drops its repeated entries. O(n log n), serial.
template <class T>
void sort_unique(std::vector<T>& v) {
  std::sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
}

/// Adds `more` (any order, repeats allowed) to `faces` (sorted, unique) so that it stays sorted
/// and unique: how the strip faces join the interior ones, in build_dual_mesh and in the repair's
/// checks. O(D + S log S) for D faces and S more.
void merge_faces(std::vector<Face>& faces, std::vector<Face> more);

/// Faces [begin, end) of one block of chunk-wise work.
struct FaceRange {
  uint64_t begin = 0, end = 0;
};

/// The chunks' owned faces (a view without chunks is one chunk) cut into blocks of at most
/// `max_faces`, in chunk order. Depends on the chunk table only (not on the threads). Throws
/// InputError when the chunks' face ranges do not tile [0, F).
std::vector<FaceRange> chunk_face_blocks(const MeshView& mesh, uint64_t max_faces = uint64_t(1) << 16);

/// Vertices per cluster (K entries; labels −1 are not counted), in parallel over the chunks'
/// vertex ranges. Throws std::invalid_argument unless labels.size() == V.
std::vector<uint32_t> cluster_sizes(const MeshView& mesh, std::span<const int32_t> labels, uint32_t cluster_count);

/// The dual faces of every input face with three distinct labels: chunk by chunk in parallel
/// (TBB; each block of a chunk's owned faces sorted and deduplicated on its own), merged in
/// chunk order and deduplicated by one sort of the K-sized list. The result depends on the
/// labels only: not on the chunks, the threads or the storage. O(F) reads + O(D log D) for D
/// dual faces; memory O(D). With `neighbour_pairs`, the same pass also lists the clusters that
/// meet along an input edge (for unjoined_pairs, no second read of the mesh).
Triples collect_triples(const MeshView& mesh, std::span<const int32_t> labels, bool neighbour_pairs = false);

/// The dual faces of the input faces around `vertices` that have a corner in a cluster c with
/// in_set[c] (size K): every dual face with a corner in the set when `vertices` lists all the
/// set's members. Rotated, sorted, unique; `repeats`, when given, receives the copies past the
/// first (as Triples::repeats). Parallel over blocks of `vertices`; deterministic.
/// O(Σ faces of the vertices).
std::vector<Face> triples_around(const MeshView& mesh, std::span<const int32_t> labels,
                                 std::span<const uint32_t> vertices, std::span<const uint8_t> in_set,
                                 std::vector<Face>* repeats = nullptr);

/// Replaces in `triples` (faces and repeats, as collect_triples gives them) every face with a
/// corner c where in_set[c] by `faces` and `repeats`, which must be all the faces with such a
/// corner under the new labels (triples_around of the set's members): the dual of a clustering
/// kept up to date through a repair without a read of the whole mesh. O(D + new faces).
void replace_triples(Triples& triples, std::span<const uint8_t> in_set, std::vector<Face> faces,
                     std::vector<Face> repeats);

/// Of the cluster pairs `neighbour_pairs` (sorted, packed a << 32 | b, a < b, joined by an input
/// edge), those joined by no edge of `faces` (the dual faces, strip faces included; ids ≥
/// cluster_count are strip vertices): their frontier meets no third cluster. The dual may stay
/// manifold, yet one input component gives two output pieces there (a group of clusters
/// ringed by a single one at a thin neck). The faces must hold every dual face with a corner in
/// a cluster of the pairs. Sorted, unique. O(P + D log D); memory O(D). Deterministic.
std::vector<uint64_t> unjoined_pairs(std::span<const uint64_t> neighbour_pairs, std::span<const Face> faces,
                                     uint32_t cluster_count);

/// The cluster pairs joined by an edge at one of `vertices` (any order), sorted, unique: the
/// neighbour_pairs of collect_triples for a part of the mesh. Parallel over blocks of the list.
/// O(edges of the vertices · log).
std::vector<uint64_t> neighbour_pairs_around(const MeshView& mesh, std::span<const int32_t> labels,
                                             std::span<const uint32_t> vertices);

/// Scratch of fan_defective (one per thread).
struct FanScratch {
  std::vector<uint64_t> entries;
  std::vector<uint32_t> parent;
};

/// True when the faces around vertex x (each holds x once) are not a manifold neighbourhood:
/// an edge at x in more than two faces or twice in one direction, faces in more than one fan
/// (around a vertex, corners only join through its own edges), or two faces on one vertex set.
/// O(n log n) for n faces.
bool fan_defective(uint32_t x, std::span<const Face> fan, FanScratch& scratch);

/// The fans round vertex x, each as its link vertices (sorted), when every edge at x is in two
/// faces, one each way (none otherwise): two or more for a pinch, e.g. the dual vertex of a
/// cluster ringing a thin feature. O(n log n) for n faces.
std::vector<std::vector<uint32_t>> closed_fans(uint32_t x, std::span<const Face> fan, FanScratch& scratch);

struct FanVerdict {
  uint32_t vertex = 0;
  bool defective = false;
};

/// fan_defective of every vertex with faces in a CSR vertex → faces: vertex k is ids[k] (k
/// itself when `ids` is empty) and its faces are faces[face_of[offsets[k] .. offsets[k + 1])].
/// In parallel over blocks of vertices: one verdict per such vertex, in the order of k.
std::vector<FanVerdict> check_fan_csr(std::span<const Face> faces, std::span<const uint32_t> ids,
                                      std::span<const uint32_t> offsets, std::span<const uint32_t> face_of);

/// The manifold verdict of every vertex of `faces` (no face may repeat an index) that
/// selected(x) accepts: one per such vertex that has faces, ascending. A vertex's verdict
/// depends only on the faces that hold it. Deterministic. A counting sort of the corners by
/// vertex: O(D + largest id), or O(D log D) when the ids are sparse (a few faces of a large
/// dual), so a re-check of a small region costs what the region holds.
template <class Selected>
std::vector<FanVerdict> check_fans(std::span<const Face> faces, const Selected& selected) {
  uint32_t top = 0;
  for (const Face& f : faces) top = std::max({top, f[0] + 1, f[1] + 1, f[2] + 1});
  std::vector<uint32_t> ids;  // sparse: the selected ids, and each corner's position among them
  const bool sparse = top > 24 * faces.size() + 4096;
  if (sparse) {
    for (const Face& f : faces)
      for (uint32_t x : f)
        if (selected(x)) ids.push_back(x);
    std::sort(ids.begin(), ids.end());
    ids.erase(std::unique(ids.begin(), ids.end()), ids.end());
  }
  auto slot = [&](uint32_t x) {
    return sparse ? uint32_t(std::lower_bound(ids.begin(), ids.end(), x) - ids.begin()) : x;
  };
  const uint32_t n = sparse ? uint32_t(ids.size()) : top;
  std::vector<uint32_t> offsets(size_t(n) + 1, 0);
  for (const Face& f : faces)
    for (uint32_t x : f)
      if (selected(x)) ++offsets[slot(x) + 1];
  for (uint32_t k = 0; k < n; ++k) offsets[k + 1] += offsets[k];
  std::vector<uint32_t> face_of(offsets[n]);
  std::vector<uint32_t> at(offsets.begin(), offsets.end() - 1);
  for (uint32_t i = 0; i < faces.size(); ++i)
    for (uint32_t x : faces[i])
      if (selected(x)) face_of[at[slot(x)]++] = i;
  return check_fan_csr(faces, ids, offsets, face_of);
}

}  // namespace streamcvd::dual
