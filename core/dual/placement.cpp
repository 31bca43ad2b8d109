// Output vertex placement and per-cluster tables (core/dual/placement.h): each a TBB pass over
// the input vertices or faces with K-sized atomic minima, the same result on any thread count.
#include "streamcvd/core/dual/placement.h"

#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>

#include "streamcvd/core/mesh/bvh.h"

namespace streamcvd {

namespace {

constexpr uint64_t kNoCandidate = std::numeric_limits<uint64_t>::max();
constexpr uint32_t kGrain = 1u << 14;

// Key ordering candidates by (non-negative float32 value, id): the bits of a non-negative float
// order as the float does, so one 64-bit minimum picks the least value, ties by the least id.
uint64_t candidate_key(double value, uint32_t id) {
  const float f = float(value);
  uint32_t bits;
  std::memcpy(&bits, &f, 4);
  return uint64_t(bits) << 32 | id;
}

// slot = min(slot, key), from any thread (a plain load first: most candidates lose).
void atomic_min(uint64_t& slot, uint64_t key) {
  std::atomic_ref<uint64_t> a(slot);
  uint64_t seen = a.load(std::memory_order_relaxed);
  while (key < seen && !a.compare_exchange_weak(seen, key, std::memory_order_relaxed)) {
  }
}

// Runs body(v) for every input vertex, in parallel over index ranges (each a visit of `mesh`'s
// range reading `arrays` when the pass reads the mesh).
template <typename Body>
void for_each_vertex(uint32_t V, const MeshView* mesh, uint8_t arrays, const Body& body) {
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, V, kGrain), [&](const tbb::blocked_range<uint32_t>& r) {
    if (mesh) {
      const RangeVisit visit(*mesh, "placement", {r.begin(), r.end()}, arrays);
      for (uint32_t v = r.begin(); v != r.end(); ++v) body(v);
    } else {
      for (uint32_t v = r.begin(); v != r.end(); ++v) body(v);
    }
  });
}

// Writes one byte that other threads may write the same value to.
void mark(uint8_t& flag) { std::atomic_ref<uint8_t>(flag).store(1, std::memory_order_relaxed); }

std::array<double, 3> corner(const float* P, uint32_t i) {
  return {P[3 * size_t(i)], P[3 * size_t(i) + 1], P[3 * size_t(i) + 2]};
}

double distance2(const std::array<double, 3>& a, const std::array<double, 3>& b) {
  return (a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) + (a[2] - b[2]) * (a[2] - b[2]);
}

uint32_t cluster_count_of(std::span<const int32_t> cluster_of_output_vertex) {
  int32_t K = 0;
  for (int32_t c : cluster_of_output_vertex) K = std::max(K, c + 1);
  return uint32_t(K);
}

}  // namespace

void project_onto_clusters(const MeshView& mesh, std::span<const int32_t> labels, std::span<double> z,
                           std::span<const uint8_t> selected) {
  const size_t K = z.size() / 3;
  std::vector<uint64_t> best(K, kNoCandidate);  // (distance, face) of the closest triangle
  const float* P = mesh.positions.data();
  const uint32_t* T = mesh.triangles.data();
  auto site = [&](size_t c) { return std::array<double, 3>{z[3 * c], z[3 * c + 1], z[3 * c + 2]}; };
  auto closest = [&](size_t c, uint64_t f) {
    return closest_point_on_triangle(site(c), corner(P, T[3 * f]), corner(P, T[3 * f + 1]), corner(P, T[3 * f + 2]));
  };
  // Face by face (in store order: by owner), each tested against the site of every cluster
  // among its corners.
  const uint64_t F = mesh.face_count();
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, F, 1u << 15), [&](const tbb::blocked_range<uint64_t>& r) {
    const RangeVisit visit(mesh, "placement", {face_owner(mesh.triangles, r.begin()), face_owner(mesh.triangles, r.end() - 1) + 1},
                           kReadsPositions | kReadsTriangles);
    for (uint64_t f = r.begin(); f != r.end(); ++f) {
      const std::array<std::array<double, 3>, 3> p = {corner(P, T[3 * f]), corner(P, T[3 * f + 1]), corner(P, T[3 * f + 2])};
      const int32_t l[3] = {labels[T[3 * f]], labels[T[3 * f + 1]], labels[T[3 * f + 2]]};
      // Every point of the face lies within its longest edge of a corner.
      const double edge = std::sqrt(std::max({distance2(p[0], p[1]), distance2(p[1], p[2]), distance2(p[2], p[0])}));
      for (int k = 0; k < 3; ++k) {
        const int32_t c = l[k];
        if (c < 0 || (k > 0 && c == l[0]) || (k > 1 && c == l[1])) continue;  // each cluster once
        if (!selected.empty() && !selected[size_t(c)]) continue;
        const std::array<double, 3> z_c = site(size_t(c));
        // A face farther than the best found so far cannot be the closest: skip the exact test
        // (strictly farther, with a margin for rounding, so the minimum found is the same).
        const uint64_t seen = std::atomic_ref<uint64_t>(best[size_t(c)]).load(std::memory_order_relaxed);
        if (seen != kNoCandidate) {
          const double bound =
              std::sqrt(std::min({distance2(z_c, p[0]), distance2(z_c, p[1]), distance2(z_c, p[2])})) - edge;
          float seen_d2;
          const uint32_t bits = uint32_t(seen >> 32);
          std::memcpy(&seen_d2, &bits, 4);
          if (bound > 0 && bound * bound > 1.0001 * double(seen_d2) + 1e-30) continue;
        }
        atomic_min(best[size_t(c)], candidate_key(distance2(closest(size_t(c), f), z_c), uint32_t(f)));
      }
    }
  });
  tbb::parallel_for(tbb::blocked_range<size_t>(0, K, kGrain), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t c = r.begin(); c != r.end(); ++c) {
      if (best[c] == kNoCandidate) continue;
      const std::array<double, 3> q = closest(c, uint32_t(best[c]));
      for (int k = 0; k < 3; ++k) z[3 * c + k] = q[k];
    }
  });
}

std::vector<uint32_t> cluster_anchor_faces(const MeshView& surface, std::span<const int32_t> labels,
                                           std::span<const int32_t> cluster_of_output_vertex,
                                           std::span<const float> output_positions) {
  const size_t V_out = cluster_of_output_vertex.size();
  const uint32_t K = cluster_count_of(cluster_of_output_vertex);
  std::vector<uint32_t> output_of_cluster(K, UINT32_MAX);
  for (size_t o = 0; o < V_out; ++o)
    if (cluster_of_output_vertex[o] >= 0) output_of_cluster[size_t(cluster_of_output_vertex[o])] = uint32_t(o);
  std::vector<uint64_t> nearest(V_out, kNoCandidate);  // (squared distance, input vertex)
  const uint32_t V = uint32_t(std::min<size_t>(surface.vertex_count(), labels.size()));
  // Positions and flags only (13 of the store's 84 bytes per vertex): out of core this pass
  // read the whole store ahead, 3.6 GB at 105M faces.
  for_each_vertex(V, &surface, kReadsPositions | kReadsFlags, [&](uint32_t v) {
    const int32_t c = labels[v];
    if (c < 0 || uint32_t(c) >= K || surface.is_isolated(v)) return;
    const uint32_t o = output_of_cluster[size_t(c)];
    if (o == UINT32_MAX) return;
    const std::array<double, 3> p = corner(surface.positions.data(), v), q = corner(output_positions.data(), o);
    atomic_min(nearest[o], candidate_key(distance2(p, q), v));
  });
  // The nearest vertices' first faces, looked up in vertex order: the face lists are read in
  // store order, not at random.
  std::vector<uint32_t> by_vertex;
  for (size_t o = 0; o < V_out; ++o)
    if (nearest[o] != kNoCandidate) by_vertex.push_back(uint32_t(o));
  std::sort(by_vertex.begin(), by_vertex.end(),
            [&](uint32_t a, uint32_t b) { return uint32_t(nearest[a]) < uint32_t(nearest[b]); });
  std::vector<uint32_t> anchor(V_out, UINT32_MAX);
  for (uint32_t o : by_vertex) anchor[o] = surface.faces_of(uint32_t(nearest[o]))[0];
  return anchor;
}

std::vector<uint8_t> remesh_movable_vertices(std::span<const int32_t> labels, const ComponentBudget& budget,
                                             std::span<const int32_t> cluster_of_output_vertex) {
  const uint32_t K = cluster_count_of(cluster_of_output_vertex);
  std::vector<uint8_t> verbatim(K, 0);
  const uint32_t V = uint32_t(std::min<size_t>(labels.size(), budget.component_of_vertex.size()));
  for_each_vertex(V, nullptr, 0, [&](uint32_t v) {
    const uint32_t comp = budget.component_of_vertex[v];
    if (labels[v] < 0 || uint32_t(labels[v]) >= K || comp >= budget.clusters_per_component.size()) return;
    if (budget.clusters_per_component[comp] >= budget.vertices_per_component[comp]) mark(verbatim[size_t(labels[v])]);
  });
  std::vector<uint8_t> movable(cluster_of_output_vertex.size(), 0);
  for (size_t o = 0; o < movable.size(); ++o) {
    const int32_t c = cluster_of_output_vertex[o];
    movable[o] = c >= 0 && !verbatim[size_t(c)];
  }
  return movable;
}

std::vector<uint8_t> clusters_in_large_components(std::span<const int32_t> labels, const ComponentBudget& budget,
                                                  uint32_t cluster_count, uint32_t min_clusters) {
  std::vector<uint8_t> large(cluster_count, 0);
  for_each_vertex(uint32_t(labels.size()), nullptr, 0, [&](uint32_t v) {
    const uint32_t comp = budget.component_of_vertex[v];
    if (labels[v] >= 0 && comp != UINT32_MAX && budget.clusters_per_component[comp] >= min_clusters)
      mark(large[size_t(labels[v])]);
  });
  return large;
}

std::vector<uint32_t> component_of_each_cluster(std::span<const int32_t> labels, const ComponentBudget& budget,
                                                uint32_t cluster_count) {
  std::vector<uint32_t> component(cluster_count, UINT32_MAX);
  // A cluster lies in one component: every writer of a slot writes the same value.
  for_each_vertex(uint32_t(labels.size()), nullptr, 0, [&](uint32_t v) {
    if (labels[v] >= 0)
      std::atomic_ref<uint32_t>(component[size_t(labels[v])])
          .store(budget.component_of_vertex[v], std::memory_order_relaxed);
  });
  return component;
}

InputClosure input_closure(const MeshView& mesh) {
  struct Partial {
    bool closed = true;
    uint64_t referenced = 0, boundary = 0;
  };
  tbb::combinable<Partial> partials;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, mesh.vertex_count(), kGrain), [&](const tbb::blocked_range<uint32_t>& r) {
    Partial& p = partials.local();
    for (uint32_t v = r.begin(); v != r.end(); ++v) {
      p.closed &= (mesh.vertex_flags[v] & (kVertexBoundary | kVertexNonManifold)) == 0;
      p.referenced += (mesh.vertex_flags[v] & kVertexIsolated) == 0;
      p.boundary += (mesh.vertex_flags[v] & kVertexBoundary) != 0;
    }
  });
  InputClosure closure;
  partials.combine_each([&](const Partial& p) {
    closure.closed &= p.closed;
    closure.referenced += p.referenced;
    closure.boundary_vertices += p.boundary;
  });
  closure.euler_characteristic =
      int64_t(closure.referenced) - int64_t(mesh.vertex_vertex.size() / 2) + int64_t(mesh.face_count());
  return closure;
}

}  // namespace streamcvd
