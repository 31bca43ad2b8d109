// Connectivity of an indexed triangle mesh as flat CSR arrays (DESIGN.md §2): vertex→face,
// vertex→vertex, and per-vertex topology flags. Built by counting passes and prefix sums: no
// per-element allocation.
// All functions are TBB-parallel and deterministic (the output does not depend on the number of
// threads). Preconditions for every function: triangle indices < vertex_count, face count < 2^32.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "streamcvd/core/mesh/default_init_vector.h"

namespace streamcvd {

/// CSR vertex→face of the vertex range [first_vertex, first_vertex + vertex_count): the faces
/// of local vertex v (global id first_vertex + v) are faces[offsets[v] .. offsets[v+1]), as
/// indices into `triangles`, ascending; corners outside the range are skipped. Every corner in
/// the range contributes one entry (a face repeating a vertex is listed twice there). offsets gets
/// vertex_count+1 entries; both vectors are resized. O(corners + count·T) time for T ≤ 8 threads,
/// each counting then placing a range of corners (no atomics, no sort), plus T·count 32-bit
/// counts of memory while it runs. The whole mesh is the range [0, V).
/// Offsets is std::vector<uint64_t> or DefaultInitVector<uint64_t>; Indices the matching uint32_t vector.
template <typename Offsets, typename Indices>
void build_vertex_face_adjacency(std::span<const uint32_t> triangles, uint32_t first_vertex, uint32_t vertex_count,
                                 Offsets& offsets, Indices& faces);

/// CSR vertex→vertex of a vertex range from the triangles and the range's vertex→face CSR (as
/// built above): the neighbours of local vertex v (vertices sharing a face with global vertex
/// first_vertex + v, itself excluded) as global ids, ascending, each once. One pass over each
/// vertex's faces into slots of deg_f + 1 entries per vertex, then an in-place move down to the
/// exact offsets: O(F · log(valence)) time, memory = the output plus `count` entries (more only
/// for blocks of vertices with several fans). With a non-empty `flags` (count entries) the pass
/// also stores compute_vertex_flags' result (it computes it anyway).
/// Offsets/Indices: std::vector<uint64_t>/<uint32_t>, or both DefaultInitVector (no zero fill).
template <typename Offsets, typename Indices>
void build_vertex_vertex_adjacency(std::span<const uint32_t> triangles, uint32_t first_vertex,
                                   std::span<const uint64_t> vf_offsets, std::span<const uint32_t> vertex_face,
                                   Offsets& offsets, Indices& neighbours, std::span<uint8_t> flags = {});

/// VertexFlag bits (core/mesh/mesh_view.h) of every vertex into `flags` (V entries):
///  - kVertexBoundary: v is on an edge {v,u} that exactly one face contains;
///  - kVertexNonManifold: v is on an edge contained in more than two faces, or its faces do not
///    form one fan (faces connected through edges {v,u}), e.g. the tip of a bowtie;
///  - kVertexIsolated: no face references v.
/// Faces that repeat a vertex count once per vertex; a face (v,v,v) adds no edge and is left out
/// of v's fan. O(F · log(valence)) time.
void compute_vertex_flags(std::span<const uint32_t> triangles, std::span<const uint64_t> vf_offsets,
                          std::span<const uint32_t> vertex_face, std::span<uint8_t> flags);

}  // namespace streamcvd
