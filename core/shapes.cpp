#include "core/shapes.h"

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
