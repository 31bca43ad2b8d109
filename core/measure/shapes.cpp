#include "streamcvd/core/measure/shapes.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>

namespace streamcvd {

MeshBuffers make_icosphere(int level, float radius) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<std::array<double, 3>> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                                           {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  std::vector<std::array<uint32_t, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                             {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                             {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                             {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  auto normalize = [](std::array<double, 3> p) {
    double n = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    return std::array<double, 3>{p[0] / n, p[1] / n, p[2] / n};
  };
  for (auto& p : v) p = normalize(p);
  for (int l = 0; l < level; ++l) {
    std::map<std::pair<uint32_t, uint32_t>, uint32_t> mid;
    auto midpoint = [&](uint32_t a, uint32_t b) {
      auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      auto p = normalize({(v[a][0] + v[b][0]) / 2, (v[a][1] + v[b][1]) / 2, (v[a][2] + v[b][2]) / 2});
      v.push_back(p);
      uint32_t id = uint32_t(v.size() - 1);
      mid[key] = id;
      return id;
    };
    std::vector<std::array<uint32_t, 3>> nf;
    for (auto& tri : f) {
      uint32_t a = midpoint(tri[0], tri[1]), b = midpoint(tri[1], tri[2]), c = midpoint(tri[2], tri[0]);
      nf.push_back({tri[0], a, c});
      nf.push_back({tri[1], b, a});
      nf.push_back({tri[2], c, b});
      nf.push_back({a, b, c});
    }
    f = std::move(nf);
  }
  MeshBuffers m;
  for (auto& p : v)
    for (double c : p) m.positions.push_back(float(c * radius));
  for (auto& tri : f)
    for (uint32_t i : tri) m.triangles.push_back(i);
  return m;
}

MeshBuffers make_torus(int rings, int segments, float R, float r) {
  MeshBuffers m;
  for (int i = 0; i < rings; ++i) {
    double u = 2 * M_PI * i / rings;
    for (int j = 0; j < segments; ++j) {
      double w = 2 * M_PI * j / segments;
      m.positions.push_back(float((R + r * std::cos(w)) * std::cos(u)));
      m.positions.push_back(float((R + r * std::cos(w)) * std::sin(u)));
      m.positions.push_back(float(r * std::sin(w)));
    }
  }
  auto id = [&](int i, int j) { return uint32_t((i % rings) * segments + (j % segments)); };
  for (int i = 0; i < rings; ++i)
    for (int j = 0; j < segments; ++j) {
      uint32_t a = id(i, j), b = id(i + 1, j), c = id(i + 1, j + 1), d = id(i, j + 1);
      m.triangles.insert(m.triangles.end(), {a, b, c, a, c, d});
    }
  return m;
}

MeshBuffers make_ellipsoid(int level, float ax, float ay, float az) {
  MeshBuffers m = make_icosphere(level, 1.0f);
  for (size_t i = 0; i < m.positions.size(); i += 3) {
    m.positions[i] *= ax;
    m.positions[i + 1] *= ay;
    m.positions[i + 2] *= az;
  }
  if (ax * ay * az < 0)  // a mirror flips the orientation
    for (size_t f = 0; f < m.triangles.size(); f += 3) std::swap(m.triangles[f + 1], m.triangles[f + 2]);
  return m;
}

MeshBuffers make_capsule(int segments, float radius, float length) {
  segments = std::max(segments, 3);
  const double r = radius, half = 0.5 * double(length), quarter = 0.5 * M_PI * r;
  const double profile = 2 * quarter + double(length);  // arc length from pole to pole
  // Ring spacing = the height of an equilateral triangle on the segment chord.
  const double chord = 2 * M_PI * r / segments;
  const int rows = std::max(1, int(std::lround(profile / (chord * std::sqrt(3.0) / 2))) - 1);
  MeshBuffers m;
  m.positions.insert(m.positions.end(), {0.0f, 0.0f, float(-half - r)});  // south pole: vertex 0
  for (int i = 1; i <= rows; ++i) {
    const double s = profile * i / (rows + 1);
    double rho = r, z = 0;
    if (s < quarter) {
      rho = r * std::sin(s / r);
      z = -half - r * std::cos(s / r);
    } else if (s > profile - quarter) {
      rho = r * std::sin((profile - s) / r);
      z = half + r * std::cos((profile - s) / r);
    } else {
      z = -half + (s - quarter);
    }
    for (int j = 0; j < segments; ++j) {
      const double a = 2 * M_PI * (j + 0.5 * (i % 2)) / segments;
      m.positions.insert(m.positions.end(), {float(rho * std::cos(a)), float(rho * std::sin(a)), float(z)});
    }
  }
  const uint32_t north = uint32_t(m.positions.size() / 3);
  m.positions.insert(m.positions.end(), {0.0f, 0.0f, float(half + r)});
  auto ring = [&](int i, int j) { return uint32_t(1 + (i - 1) * segments + ((j % segments) + segments) % segments); };
  // Orients each triangle away from the capsule's axis segment (the shape is convex).
  auto add = [&](uint32_t a, uint32_t b, uint32_t c) {
    const float* P = m.positions.data();
    double e1[3], e2[3], g[3];
    for (int k = 0; k < 3; ++k) {
      e1[k] = double(P[3 * b + k]) - P[3 * a + k];
      e2[k] = double(P[3 * c + k]) - P[3 * a + k];
      g[k] = (double(P[3 * a + k]) + P[3 * b + k] + P[3 * c + k]) / 3;
    }
    g[2] -= std::clamp(g[2], -half, half);
    const double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
    if (n[0] * g[0] + n[1] * g[1] + n[2] * g[2] < 0) std::swap(b, c);
    m.triangles.insert(m.triangles.end(), {a, b, c});
  };
  for (int j = 0; j < segments; ++j) {
    add(0, ring(1, j), ring(1, j + 1));
    add(north, ring(rows, j), ring(rows, j + 1));
  }
  // Ring i+1 is turned by +half a segment from ring i when i is even, −half when i is odd.
  for (int i = 1; i < rows; ++i)
    for (int j = 0; j < segments; ++j) {
      if (i % 2 == 0) {
        add(ring(i, j), ring(i, j + 1), ring(i + 1, j));
        add(ring(i + 1, j), ring(i, j + 1), ring(i + 1, j + 1));
      } else {
        add(ring(i, j), ring(i, j + 1), ring(i + 1, j + 1));
        add(ring(i, j), ring(i + 1, j + 1), ring(i + 1, j));
      }
    }
  return m;
}

MeshBuffers make_grid(int nx, int ny, float sx, float sy) {
  MeshBuffers m;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      m.positions.push_back(sx * float(i) / float(nx - 1));
      m.positions.push_back(sy * float(j) / float(ny - 1));
      m.positions.push_back(0.0f);
    }
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      uint32_t a = uint32_t(j * nx + i), b = a + 1, c = a + uint32_t(nx) + 1, d = a + uint32_t(nx);
      m.triangles.insert(m.triangles.end(), {a, b, c, a, c, d});
    }
  return m;
}

}  // namespace streamcvd
