// Topology figures of a mesh laid out as the compact store (DESIGN.md §2), chunk by chunk in
// bounded memory: what `streamcvd info` prints for a store directory.
#pragma once

#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

/// Every TopologyStats field, equal to compute_topology_stats(mesh.soup()) (same conventions),
/// from each vertex's fan (vertex→face) instead of a global sort, components and boundary loops
/// by a chunk-wise union-find (core/mesh/chunked_components.h); how: core/measure/store_stats.cpp.
/// O(V + F) time, TBB-parallel over the chunks, thread-safe (pure). Memory: ≤ 8 MB of union-find
/// per thread plus O(pieces + chunk frontiers), never O(V) or O(F) beyond the mapped store,
/// which is read once, chunk by chunk. Precondition: a valid view (MeshStore::build / open);
/// throws InputError if the chunks do not tile [0, V) or vertex→face disagrees with the triangles.
TopologyStats compute_topology_stats(const MeshView& mesh);

}  // namespace streamcvd
