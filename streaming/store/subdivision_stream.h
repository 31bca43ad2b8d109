// Linear 1→4 subdivision (paper §VI-F: remeshing by over-sampling, so that N can approach or
// exceed the input vertex count), streamed from a store into any MeshSink — in practice the store
// builder, so the subdivided mesh is built in bounded memory like an ingested file.
#pragma once

#include <cstdint>

#include "streamcvd/core/mesh/large_array.h"
#include "streamcvd/core/mesh/mesh_buffers.h"
#include "streamcvd/core/mesh/mesh_view.h"
#include "streamcvd/streaming/io/mesh_reader.h"

namespace streamcvd {

/// Streams one level of linear subdivision of `mesh` into `sink`, as a reader would: first the
/// V input vertices unchanged, then one midpoint per undirected edge {v, u} (v < u) in the order
/// of the store's sorted neighbour lists (v ascending, then u), then four triangles per face
/// (orientation kept; a face repeating a vertex is copied unchanged). V' = V + E, F' ≤ 4F.
/// `attributes` (rows of the V input vertices, or empty) go along: a vertex keeps its row, a
/// midpoint gets the mean of its edge's two (header.attributes = their names).
/// Memory: one 8-byte edge offset per vertex from `storage` plus a block; time O(V + F) with a
/// binary search per face edge; parallel within blocks. Throws InputError when V' ≥ 2^32.
void stream_subdivision(const MeshView& mesh, MeshSink& sink, ArrayStorage& storage = ram_storage(),
                        VertexAttributeRows attributes = {}, uint32_t block = 1u << 16);

/// Convenience for tests and small meshes: one level of subdivision of a soup (vertices first in
/// their order, then the midpoints by edge (lo, hi); face f becomes faces 4f..4f+3, or one face
/// when it repeats a vertex). O(V + F).
MeshBuffers subdivide_linear(const TriangleSoupView& mesh);

}  // namespace streamcvd
