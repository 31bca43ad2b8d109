// Topology cleaning of a built store (issue 16): what MeshStore's builds do when the input as
// read has duplicate, degenerate or non-manifold elements, so that clustering and the dual see a
// manifold with boundary.
//   - exact duplicate faces (same vertex set, either orientation) are dropped, the first kept;
//     a face and its reverse whose edges the faces around them already close in pairs (the two
//     sides of a wall collapsed onto one layer, as vertex clustering leaves them) are dropped
//     both, so the surfaces on either side stay closed instead of a cut opening a hole;
//   - faces with a repeated index are dropped, and zero-area faces (core/measure/mesh_stats.h's threshold)
//     at a non-manifold vertex; a zero-area face elsewhere stays: it weighs nothing, and dropping
//     it from a manifold would open a slit (a clean scan such as the dragon, 367 of them, keeps
//     its store byte for byte);
//   - around an edge still used by more than two faces, the faces are sorted by their angle about
//     the edge and neighbours of opposite edge direction are paired into sheets (the pairing with
//     more pairs, then the flatter one, then the one whose pairs enclose the space behind their
//     normals: the inside of a closed, outward-oriented surface), so a fin or a second surface
//     becomes a piece of its own and the main surface stays closed; faces left without a partner
//     get a boundary there; a face and its near copy (opposite direction, close in angle and
//     apex: a double layer a subdivision or jitter made inexact) are paired with each other
//     first, when the others then pair up completely, since their order about the edge is noise;
//   - each fan of faces around a vertex (faces joined across the vertex's edges: two-face edges
//     of consistent orientation, the edges above by their pairs) beyond the first gets its own
//     copy of the vertex (same position and attributes), as CGAL's
//     duplicate_non_manifold_vertices does;
//   - of a face and its reverse (a double layer), the orientation its neighbours agree with is
//     kept; a cut that did not come apart gets another round, dropping its unpaired faces;
//   - last, on the manifold the cuts leave, faces run the wrong way round (two faces running an
//     edge the same way) are turned back, the smaller region their edges bound
//     (plan_face_flips, streaming/store/store_orient.cpp).
// The cleaned soup (the store's vertices, then the copies; its faces in store order, dropped or
// rewritten) is streamed into the store builder again: the cleaned store is an ordinary store.
// A cut whose two ends stay joined around both of them (an unpaired face, or a second sheet,
// reaching the surface again through manifold edges at each end) cannot come apart at a vertex:
// the later round drops its unpaired faces and every pair but the first on that edge (a hole
// of a face or two rather than a non-manifold edge, which the dual could never make manifold).
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/streaming/io/mesh_reader.h"
#include "streamcvd/streaming/store/store.h"

namespace streamcvd {

/// True when the store `mesh`, whose figures are `as_read` (compute_topology_stats), has anything
/// the cleaning drops or cuts: duplicate faces, non-manifold edges or vertices, faces with a
/// repeated index (zero-area faces of a manifold are kept: see the module comment). O(1), or one
/// parallel pass over the faces when there are degenerate faces and nothing else. Thread-safe.
bool needs_topology_cleaning(const TopologyStats& as_read, const MeshView& mesh);

/// Which corners of which faces move to a vertex copy, and the vertex each copy repeats.
struct CleaningPlan {
  uint32_t vertices = 0;                 ///< of the store (copies are numbered from here)
  uint64_t kept_faces = 0;               ///< faces of the cleaned soup
  double zero_area = 0;                  ///< the degenerate-face threshold used
  bool drop_unpaired = false;            ///< faces a cut left unpaired are dropped (later rounds)
  std::vector<uint32_t> copy_source;     ///< store vertex of copy i (vertex id vertices + i)
  std::vector<uint64_t> moved_corners;   ///< face << 2 | corner slot, ascending
  std::vector<uint32_t> moved_to;        ///< the copy each moved corner takes
  std::vector<uint64_t> flipped_faces;   ///< faces written the other way round (plan_face_flips), ascending
};

/// The faces of the manifold store `mesh` to flip so that it is consistently oriented: from
/// each edge two faces run the same way, the smaller of the two regions that misoriented edges
/// bound, grown a face at a time from either side (at most max_region_faces each). Edges
/// whose floods meet (a surface not orientable there) are left and counted in `unresolved`.
/// Ascending. O(V + Σ degree²) to find the edges, then O(regions flipped); memory O(regions).
std::vector<uint64_t> plan_face_flips(const MeshView& mesh, uint64_t& unresolved,
                                      uint64_t max_region_faces = uint64_t(1) << 22);

/// Plans the cleaning of `mesh` (a store view) and adds its counts to `counts` (not `cleaned`).
/// With drop_unpaired (a later round, on a store cleaned once whose cuts left an edge with more
/// than two faces: an unpaired face or a second sheet still joined to the surface around both
/// ends) the faces a cut leaves without a partner are dropped instead, and on an edge with two
/// pairs or more those of every pair but its first (a hole of a face or two rather than a
/// non-manifold edge). Chunk range by chunk range, TBB-parallel; the plan depends on neither the thread
/// count nor the memory limit. O(V + F) time (fans of flagged vertices sorted); memory O(copies +
/// moved corners) besides per-thread fan scratch: nothing O(V) or O(F). Thread-safe (pure).
CleaningPlan plan_topology_cleaning(const MeshView& mesh, TopologyCleaning& counts, bool drop_unpaired = false,
                                    std::span<const uint32_t> seam = {});

/// The ends of the misoriented edges of the manifold store `mesh` (two faces running the edge
/// the same way), ascending, unique: the `seam` along which plan_topology_cleaning cuts a
/// surface that no flip orients. Their count in `edges`. O(V + Σ degree²), TBB-parallel.
std::vector<uint32_t> misoriented_edge_vertices(const MeshView& mesh, uint64_t& edges);

/// Streams the cleaned soup of `store` into `sink` as a reader would: the store's vertices and
/// attributes in store order, then the copies; then its faces in store order, dropped ones left
/// out, moved corners rewritten. O(V + F), blocks of 64 Ki elements; memory: one block.
void stream_cleaned_soup(const MeshStore& store, const CleaningPlan& plan, MeshSink& sink);

/// The record a cleaned store keeps (cleaning.txt in its directory): the input's figures as read
/// and the cleaning's counts of `r`, one "name value" line each. O(1).
std::string cleaning_record(const StoreBuildReport& r);
/// Reads such a record into r (input_topology, cleaning; topology_checked and cleaning.rebuilt
/// set). Throws InputError "line N: ..." for a line it cannot read.
void parse_cleaning_record(const std::string& text, StoreBuildReport& r);

/// The cleaning as MeshStore's builds run it on a store `built` as read: its figures into
/// report.input_topology (compute_topology_stats, bounded memory); a clean store is returned as
/// it is; otherwise the plan, the cleaned soup streamed into a new build (RAM or anonymous work
/// files as options decide, the limit less what `built` holds in RAM; original ids mapped back
/// to the file's), `built` released, the counts and the cleaned figures into report.cleaning.
/// Throws as the builder does.
MeshStore clean_store_topology(MeshStore&& built, const StoreBuildOptions& options, StoreBuildReport& report,
                               const std::function<void(const BuildProgress&)>& progress);

}  // namespace streamcvd
