// Procedural test surfaces: closed spheres and tori, flat grids. Used by tests and benchmarks.
#pragma once

#include "core/mesh_buffers.h"

namespace streamcvd {

/// Closed icosphere, 10·4^level + 2 vertices, outward oriented. O(F log F).
MeshBuffers make_icosphere(int subdivision_level, float radius = 1.0f);
/// Closed torus (genus 1) of `rings` × `segments` vertices, radii major > minor, outward oriented.
MeshBuffers make_torus(int rings, int segments, float major_radius = 1.0f, float minor_radius = 0.35f);
/// Flat grid of nx × ny vertices on [0,sx]×[0,sy] at z = 0 (an open disc), normals +z.
MeshBuffers make_grid(int nx, int ny, float size_x = 1.0f, float size_y = 1.0f);

}  // namespace streamcvd
