// Holes below the output resolution (core/dual/hole_closing.h).
#include "streamcvd/core/dual/hole_closing.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <unordered_set>

#include "streamcvd/core/mesh/vec3.h"

namespace streamcvd::dual {

bool diameter_below(std::span<const float> xyz, std::span<const uint32_t> loop, double d) {
  vec3::Vec3 lo = {INFINITY, INFINITY, INFINITY}, hi = {-INFINITY, -INFINITY, -INFINITY};
  for (uint32_t v : loop) {
    const vec3::Vec3 p = vec3::point(xyz, v);
    for (int c = 0; c < 3; ++c) lo[c] = std::min(lo[c], p[c]), hi[c] = std::max(hi[c], p[c]);
  }
  // The box's diagonal bounds the diameter from above, its longest side from below.
  const vec3::Vec3 box = vec3::sub(hi, lo);
  if (vec3::dot(box, box) < d * d) return true;
  if (std::max({box[0], box[1], box[2]}) >= d || loop.size() > 4096) return false;
  for (size_t i = 0; i < loop.size(); ++i)
    for (size_t j = i + 1; j < loop.size(); ++j) {
      const vec3::Vec3 e = vec3::sub(vec3::point(xyz, loop[i]), vec3::point(xyz, loop[j]));
      if (vec3::dot(e, e) >= d * d) return false;
    }
  return true;
}

double loop_width(std::span<const float> xyz, std::span<const uint32_t> loop) {
  if (loop.empty()) return 0;
  auto at = [&](uint32_t v) {
    const vec3::Vec3 p = vec3::point(xyz, v);
    return Eigen::Vector3d(p[0], p[1], p[2]);
  };
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (uint32_t v : loop) mean += at(v);
  mean /= double(loop.size());
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (uint32_t v : loop) covariance += (at(v) - mean) * (at(v) - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(covariance);
  const Eigen::Vector3d across = eigen.eigenvectors().col(1);  // eigenvalues ascending: the middle one
  double lo = INFINITY, hi = -INFINITY;
  for (uint32_t v : loop) lo = std::min(lo, across.dot(at(v))), hi = std::max(hi, across.dot(at(v)));
  return hi - lo;
}

namespace {

constexpr size_t kMaxRing = 64;

// Pairs of ring clusters that share an input edge (adjacent[i·m + j]), by a flood over the
// vertices labelled with ring clusters from the loop. False when the flood meets no cluster off
// the ring: the loop then bounds all of a piece rather than a hole in it.
bool ring_neighbours(const MeshView& mesh, std::span<const uint32_t> loop, std::span<const int32_t> ring,
                     std::span<const int32_t> labels, std::vector<uint8_t>& adjacent) {
  const size_t m = ring.size();
  std::vector<std::pair<int32_t, uint32_t>> index(m);  // (cluster, ring position), sorted
  for (uint32_t i = 0; i < m; ++i) index[i] = {ring[i], i};
  std::sort(index.begin(), index.end());
  auto position = [&](int32_t c) -> int64_t {
    const auto it = std::lower_bound(index.begin(), index.end(), std::pair<int32_t, uint32_t>{c, 0});
    return it != index.end() && it->first == c ? int64_t(it->second) : -1;
  };
  adjacent.assign(m * m, 0);
  std::vector<uint32_t> queue(loop.begin(), loop.end());
  std::unordered_set<uint32_t> seen(loop.begin(), loop.end());
  bool outside = false;
  for (size_t head = 0; head < queue.size(); ++head) {
    const uint32_t v = queue[head];
    const int64_t i = position(labels[v]);
    for (uint32_t u : mesh.neighbours(v)) {
      if (labels[u] < 0) continue;
      const int64_t j = position(labels[u]);
      if (j < 0) {
        outside = true;
        continue;
      }
      if (j != i) adjacent[size_t(i) * m + size_t(j)] = adjacent[size_t(j) * m + size_t(i)] = 1;
      if (seen.insert(u).second) queue.push_back(u);
    }
  }
  return outside;
}

}  // namespace

std::vector<std::array<uint32_t, 3>> triangulate_hole_ring(const MeshView& mesh, std::span<const uint32_t> loop,
                                                           std::span<const uint32_t> changes,
                                                           std::span<const int32_t> ring,
                                                           std::span<const int32_t> labels,
                                                           std::span<const uint64_t> taken) {
  const size_t m = ring.size(), n = loop.size();
  if (m < 3 || m > kMaxRing) return {};
  std::vector<uint8_t> adjacent;
  if (!ring_neighbours(mesh, loop, ring, labels, adjacent)) return {};
  if (!taken.empty())
    for (size_t i = 0; i < m; ++i)
      for (size_t k = i + 1; k < m; ++k)
        if (std::binary_search(taken.begin(), taken.end(), cluster_pair_key(uint32_t(ring[i]), uint32_t(ring[k]))))
          adjacent[i * m + k] = adjacent[k * m + i] = 1;
  // Each ring cluster at the mean of the loop vertices it holds.
  std::vector<vec3::Vec3> at(m, {0, 0, 0});
  for (size_t t = 0; t < m; ++t) {
    const size_t begin = (changes[t] + 1) % n, length = (changes[(t + 1) % m] + n - begin) % n + 1;
    for (size_t k = 0; k < length; ++k) at[t] = vec3::add(at[t], vec3::point(mesh.positions, loop[(begin + k) % n]));
    at[t] = vec3::scale(at[t], 1.0 / double(length));
  }
  auto distance = [&](size_t i, size_t j) { return vec3::norm(vec3::sub(at[i], at[j])); };
  // cost[i·m + k]: least total diagonal length of a triangulation of the polygon i … k (i < k).
  constexpr double kNo = std::numeric_limits<double>::infinity();
  std::vector<double> cost(m * m, 0.0);
  std::vector<uint32_t> split(m * m, 0);
  for (size_t span = 2; span < m; ++span)
    for (size_t i = 0; i + span < m; ++i) {
      const size_t k = i + span;
      const bool ring_edge = i == 0 && k == m - 1;
      double best = kNo;
      if (ring_edge || !adjacent[i * m + k])
        for (size_t j = i + 1; j < k; ++j) {
          const double c = cost[i * m + j] + cost[j * m + k];
          if (c < best) best = c, split[i * m + k] = uint32_t(j);
        }
      cost[i * m + k] = best + (ring_edge || best == kNo ? 0.0 : distance(i, k));
    }
  if (cost[m - 1] == kNo) return {};
  std::vector<std::array<uint32_t, 3>> triangles;
  std::vector<std::pair<size_t, size_t>> todo = {{0, m - 1}};
  while (!todo.empty()) {
    const auto [i, k] = todo.back();
    todo.pop_back();
    if (k - i < 2) continue;
    const size_t j = split[i * m + k];
    triangles.push_back({uint32_t(ring[i]), uint32_t(ring[k]), uint32_t(ring[j])});  // against the ring
    todo.push_back({i, j});
    todo.push_back({j, k});
  }
  return triangles;
}

}  // namespace streamcvd::dual
