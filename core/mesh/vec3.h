// Small double-precision 3-vector helpers for the geometry passes (accumulation in double over
// float32 storage). Header-only, inline, no allocation.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <span>

namespace streamcvd::vec3 {

using Vec3 = std::array<double, 3>;

inline Vec3 sub(const Vec3& a, const Vec3& b) { return {a[0] - b[0], a[1] - b[1], a[2] - b[2]}; }
inline Vec3 add(const Vec3& a, const Vec3& b) { return {a[0] + b[0], a[1] + b[1], a[2] + b[2]}; }
inline Vec3 scale(const Vec3& a, double s) { return {a[0] * s, a[1] * s, a[2] * s}; }
inline double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
inline Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}
inline double norm(const Vec3& a) { return std::sqrt(dot(a, a)); }
/// a / |a|, or zero for a zero vector.
inline Vec3 unit(const Vec3& a) {
  const double n = norm(a);
  return n > 0 ? scale(a, 1.0 / n) : Vec3{0, 0, 0};
}
/// Vertex v of a flat xyz float array, in double.
inline Vec3 point(std::span<const float> xyz, uint32_t v) {
  return {xyz[3 * size_t(v)], xyz[3 * size_t(v) + 1], xyz[3 * size_t(v) + 2]};
}

}  // namespace streamcvd::vec3
