// Connectivity of an indexed triangle mesh as flat CSR arrays (DESIGN.md §2): vertex→face,
// vertex→vertex, and per-vertex topology flags. Built by counting passes and prefix sums: no
// per-element allocation.
// All functions are TBB-parallel and deterministic (the output does not depend on the number of
// threads). Preconditions for every function: triangle indices < vertex_count, face count < 2^32.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/default_init_vector.h"

namespace streamcvd {

/// CSR vertex→face: faces of vertex v are faces[offsets[v] .. offsets[v+1]), ascending. Every
/// corner contributes one entry (faces.size() == triangles.size(), a face repeating a vertex is
/// listed twice there). offsets gets V+1 entries. O(F + V·T) time for T ≤ 8 threads, each
/// counting then placing a range of corners (no atomics, no sort), plus T·V 32-bit counts of
/// memory while it runs; the vectors are resized.
/// Offsets is std::vector<uint64_t> or DefaultInitVector<uint64_t>; Indices std::vector<uint32_t>.
template <typename Offsets, typename Indices>
void build_vertex_face_adjacency(std::span<const uint32_t> triangles, uint32_t vertex_count, Offsets& offsets,
                                 Indices& faces);

/// CSR vertex→vertex from the triangles and their vertex→face CSR: the neighbours of v (vertices
/// sharing a face with v, v itself excluded) in ascending order, each once. The result is
/// symmetric. One pass over each vertex's faces into slots of deg_f + 1 entries per vertex, then
/// an in-place move down to the exact offsets: O(F · log(valence)) time, memory = the output plus
/// V entries (more only for blocks of vertices with several fans). With a non-empty `flags`
/// (V entries) the pass also stores compute_vertex_flags' result (it computes it anyway).
/// Offsets/Indices: std::vector<uint64_t>/<uint32_t>, or both DefaultInitVector (no zero fill).
template <typename Offsets, typename Indices>
void build_vertex_vertex_adjacency(std::span<const uint32_t> triangles, std::span<const uint64_t> vf_offsets,
                                   std::span<const uint32_t> vertex_face, Offsets& offsets, Indices& neighbours,
                                   std::span<uint8_t> flags = {});

/// VertexFlag bits (core/mesh_view.h) of every vertex into `flags` (V entries):
///  - kVertexBoundary: v is on an edge {v,u} that exactly one face contains;
///  - kVertexNonManifold: v is on an edge contained in more than two faces, or its faces do not
///    form one fan (faces connected through edges {v,u}), e.g. the tip of a bowtie;
///  - kVertexIsolated: no face references v.
/// Faces that repeat a vertex count once per vertex; a face (v,v,v) adds no edge and is left out
/// of v's fan. O(F · log(valence)) time.
void compute_vertex_flags(std::span<const uint32_t> triangles, std::span<const uint64_t> vf_offsets,
                          std::span<const uint32_t> vertex_face, std::span<uint8_t> flags);

}  // namespace streamcvd
