// Last safety net against flat (zero-area) output triangles. A remeshed face can be flat when
// its three vertices are collinear in float32: typically a §VI-D boundary-strip triangle
// (p, p_next, b) whose cluster vertex b was projected onto the input boundary between the two
// strip points. Such a face is either dropped (its longest edge is on the boundary: the middle
// vertex joins the boundary) or its longest edge is flipped (the middle vertex splits the
// neighbouring triangle in two). Both keep the mesh manifold, oriented, and keep V and χ.
// Where neither is safe (the middle vertex is on the boundary already: a bowtie; an ear), the
// middle vertex moves off the line by the least distance that gives the face an area. Where two
// flat faces share an edge far shorter than their others (a debris piece a hundredth of an output
// edge wide: no move of a few ulps gives both an area), one end of that edge moves by up to half
// its mean edge length, to where its worst face is best.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

namespace streamcvd {

struct FlatFaceRepair {
  uint64_t faces_removed = 0;  ///< flat faces dropped along the boundary
  uint64_t flips = 0;          ///< flat faces removed by flipping their longest edge
  uint64_t nudges = 0;         ///< flat faces given area by moving a vertex (a few ulps, or on debris further)
  uint64_t remaining = 0;      ///< flat faces left (no safe edit found)
};

/// Area below which a face counts as flat: 1e-12 · (bounding-box diagonal of `positions`)², the
/// criterion of core/measure/mesh_stats.cpp. O(V).
double flat_face_area(std::span<const float> positions);

/// Removes, flips or nudges the flat faces of the manifold mesh (`triangles`, 3·F indices into
/// the 3·V `positions`; a nudge moves one vertex by a few float ulps) while keeping it manifold
/// and consistently oriented: no edit that would create a non-manifold vertex, a duplicate edge
/// or a fold is made. Faces with a repeated index are left as they are. O(F) per pass, a few
/// passes; single-threaded.
FlatFaceRepair repair_flat_faces(std::span<float> positions, std::vector<uint32_t>& triangles);

}  // namespace streamcvd
