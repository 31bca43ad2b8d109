// Triangle quality Q = 6/√3 · area / (half-perimeter · longest edge) (DESIGN.md §9): 1 for an
// equilateral triangle, towards 0 for needles and caps; unitless. The one formula every Q of the
// library uses, in double. Header-only, inline: O(1), no allocation, pure (thread-safe).
#pragma once

#include <algorithm>
#include <cmath>

#include "streamcvd/core/mesh/vec3.h"

namespace streamcvd {

/// Below this Q a triangle is a sliver: its normal says nothing about the surface (the quality
/// passes, core/dual/mesh_optimize.cpp and core/dual/strip_shape.cpp, do not trust it).
constexpr double kSliverQuality = 0.2;

/// Q's denominator from the three edge lengths (any unit): half-perimeter · longest edge.
inline double quality_denominator(double l0, double l1, double l2) {
  return 0.5 * (l0 + l1 + l2) * std::max({l0, l1, l2});
}

/// Q from the area (in the square of the lengths' unit) and quality_denominator. No guard: a
/// point-like triangle gives 0/0 (NaN); rule it out first or use triangle_quality.
inline double quality_from(double area, double denominator) { return 6.0 / std::sqrt(3.0) * area / denominator; }

/// Q of the triangle (a, b, c): edges b − a, c − b, a − c, area ½·|(b − a) × (c − a)|; 0 for a
/// point-like triangle (all edges 0) or a NaN corner.
inline double triangle_quality(const vec3::Vec3& a, const vec3::Vec3& b, const vec3::Vec3& c) {
  using namespace vec3;
  const double l0 = norm(sub(b, a)), l1 = norm(sub(c, b)), l2 = norm(sub(a, c));
  const double area = 0.5 * norm(cross(sub(b, a), sub(c, a)));
  const double denominator = quality_denominator(l0, l1, l2);
  return denominator > 0 ? quality_from(area, denominator) : 0.0;
}

}  // namespace streamcvd
