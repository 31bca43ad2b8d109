// Topology figures of a mesh laid out as the compact store (DESIGN.md §2), chunk by chunk in
// bounded memory: what `streamcvd info` prints for a store directory.
#pragma once

#include "core/mesh_stats.h"
#include "core/mesh_view.h"

namespace streamcvd {

/// Every TopologyStats field, equal to compute_topology_stats(mesh.soup()) (same conventions,
/// core/mesh_stats.cpp), from the store's vertex→face lists instead of a global sort: each
/// vertex's fan gives its edges with their face counts, orientation and bowtie test; duplicates
/// are found among the faces a vertex owns; components and boundary loops by a chunk-wise
/// union-find (core/chunked_components.h). TBB-parallel over vertex ranges of the chunks;
/// O(V + F) time. Memory: per thread, one range's union-find arrays (≤ 8 MB) and one fan; in
/// all, O(pieces + chunk frontiers + boundary vertices on frontiers), never O(V) or O(F) beyond
/// the mapped store, which is read once, range by range. Thread-safe (pure).
/// Precondition: a valid view (MeshStore::build / open check its arrays); throws InputError if
/// the vertex→face lists disagree with the triangles, std::logic_error if the chunks do not tile.
TopologyStats compute_topology_stats(const MeshView& mesh);

}  // namespace streamcvd
