// Procedural test surfaces: closed spheres, ellipsoids, capsules and tori, flat grids. Used by tests and benchmarks.
#pragma once

#include "streamcvd/core/mesh/mesh_buffers.h"

namespace streamcvd {

/// Closed icosphere, 10·4^level + 2 vertices, outward oriented. O(F log F).
MeshBuffers make_icosphere(int subdivision_level, float radius = 1.0f);
/// Closed torus (genus 1) of `rings` × `segments` vertices, radii major > minor, outward oriented.
MeshBuffers make_torus(int rings, int segments, float major_radius = 1.0f, float minor_radius = 0.35f);
/// Closed ellipsoid with semi-axes (ax, ay, az): an icosphere of `subdivision_level` scaled per
/// axis (triangles stretched by the axis ratios), 10·4^level + 2 vertices, outward oriented.
MeshBuffers make_ellipsoid(int subdivision_level, float ax, float ay, float az);
/// Closed capsule around the z axis: a cylinder of `radius` and `length` (z in [−length/2,
/// length/2]) with hemispherical caps. Rings of `segments` vertices at uniform arc length along
/// the profile, every other ring turned by half a segment (near-equilateral triangles on the
/// cylinder), one vertex per pole; outward oriented. segments ≥ 3. O(V).
MeshBuffers make_capsule(int segments, float radius = 1.0f, float length = 4.0f);
/// Flat grid of nx × ny vertices on [0,sx]×[0,sy] at z = 0 (an open disc), normals +z.
MeshBuffers make_grid(int nx, int ny, float size_x = 1.0f, float size_y = 1.0f);

}  // namespace streamcvd
