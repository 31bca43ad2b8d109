#include "streamcvd/core/mesh/bvh.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "streamcvd/core/mesh/errors.h"

namespace streamcvd {
namespace {

using Vec3 = std::array<double, 3>;

constexpr uint32_t kBins = 16;                 // SAH candidates (Wald 2007 uses 8-32)
constexpr uint64_t kMaxLeaf = 8;               // a node this small may stop if the SAH says so
constexpr uint64_t kAlwaysLeaf = 4;            // ... and one of ≤ 4 always stops
// SAH traversal cost, relative to one point-triangle test. 2 (with kAlwaysLeaf 4) gives ≈ 0.55
// nodes per face, so ≈ 58 B/face in all, at the same query speed as 1.15 nodes per face
// (cost 1, leaves of 2) measured on a 1.3M-face icosphere and the 871k-face dragon.
constexpr double kTraversalCost = 2.0;
constexpr uint32_t kMedianDepth = 64;          // past this depth, split at the object median
constexpr uint64_t kMedianLeaf = 4;
constexpr uint64_t kSubtreeTask = 1u << 14;    // ranges this small are built by one task
constexpr uint64_t kParallelGrain = 1u << 15;  // ranges this large bin in parallel

// Build-time primitive: the triangle's box and its face. Centroid = lo + hi (doubled centre;
// only compared against other doubled centres, so the factor 1/2 is never needed).
struct PrimRef {
  float lo[3];
  float hi[3];
  uint32_t face;
  float centre(int axis) const { return lo[axis] + hi[axis]; }
};

struct Box {
  float lo[3] = {INFINITY, INFINITY, INFINITY};
  float hi[3] = {-INFINITY, -INFINITY, -INFINITY};
  void grow(const float* plo, const float* phi) {
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], plo[k]);
      hi[k] = std::max(hi[k], phi[k]);
    }
  }
  void grow(const Box& b) { grow(b.lo, b.hi); }
  // Half surface area (the SAH only compares ratios); 0 for an empty box.
  double half_area() const {
    if (!(lo[0] <= hi[0])) return 0.0;
    double dx = double(hi[0]) - lo[0], dy = double(hi[1]) - lo[1], dz = double(hi[2]) - lo[2];
    return dx * dy + dy * dz + dz * dx;
  }
};

// Box of the primitives and box of their (doubled) centres over one range.
struct RangeBounds {
  Box bounds, centres;
  void add(const PrimRef& p) {
    bounds.grow(p.lo, p.hi);
    float c[3] = {p.centre(0), p.centre(1), p.centre(2)};
    centres.grow(c, c);
  }
  void join(const RangeBounds& o) {
    bounds.grow(o.bounds);
    centres.grow(o.centres);
  }
};

// Min/max are exact and order-free, so the parallel reduction equals the sequential one.
RangeBounds range_bounds(std::span<const PrimRef> prims) {
  auto body = [&](const tbb::blocked_range<size_t>& r, RangeBounds acc) {
    for (size_t i = r.begin(); i < r.end(); ++i) acc.add(prims[i]);
    return acc;
  };
  if (prims.size() < kParallelGrain) return body({0, prims.size()}, RangeBounds{});
  return tbb::parallel_reduce(tbb::blocked_range<size_t>(0, prims.size(), kParallelGrain / 4), RangeBounds{}, body,
                              [](RangeBounds a, const RangeBounds& b) {
                                a.join(b);
                                return a;
                              });
}

// Bin mapping of one axis; partitioning reuses it so the split matches the binning exactly.
struct BinMap {
  float origin = 0, scale = 0;
  uint32_t bin(float c) const {
    auto b = static_cast<int64_t>((c - origin) * scale);
    return static_cast<uint32_t>(std::clamp<int64_t>(b, 0, kBins - 1));
  }
};

// Per bin: the primitives' box and centre box, so both children's RangeBounds come out of the
// sweep and no level needs a separate bounds pass.
struct Bins {
  RangeBounds bin[kBins];
  uint64_t count[kBins] = {};
  void join(const Bins& o) {
    for (uint32_t i = 0; i < kBins; ++i) {
      bin[i].join(o.bin[i]);
      count[i] += o.count[i];
    }
  }
};

Bins bin_prims(std::span<const PrimRef> prims, const BinMap& map, int axis) {
  auto body = [&](const tbb::blocked_range<size_t>& r, Bins acc) {
    for (size_t i = r.begin(); i < r.end(); ++i) {
      const uint32_t b = map.bin(prims[i].centre(axis));
      acc.bin[b].add(prims[i]);
      ++acc.count[b];
    }
    return acc;
  };
  if (prims.size() < kParallelGrain) return body({0, prims.size()}, Bins{});
  return tbb::parallel_reduce(tbb::blocked_range<size_t>(0, prims.size(), kParallelGrain / 4), Bins{}, body,
                              [](Bins a, const Bins& b) {
                                a.join(b);
                                return a;
                              });
}

struct Split {
  uint32_t bin = 0;        // left side = bins [0, bin]
  double cost = INFINITY;  // Σ half_area(side) · count(side)
  RangeBounds left, right;
};

// Sweeps the bins from both ends (Wald 2007, §4); ties keep the lowest bin (deterministic).
Split best_split(const Bins& bins) {
  double right_cost[kBins];
  Box acc;
  uint64_t n = 0;
  for (uint32_t i = kBins - 1; i > 0; --i) {
    acc.grow(bins.bin[i].bounds);
    n += bins.count[i];
    right_cost[i] = acc.half_area() * double(n);
  }
  Split best;
  acc = Box{};
  n = 0;
  for (uint32_t i = 0; i + 1 < kBins; ++i) {
    acc.grow(bins.bin[i].bounds);
    n += bins.count[i];
    const double cost = acc.half_area() * double(n) + right_cost[i + 1];
    if (cost < best.cost) {
      best.bin = i;
      best.cost = cost;
    }
  }
  for (uint32_t i = 0; i < kBins; ++i) (i <= best.bin ? best.left : best.right).join(bins.bin[i]);
  return best;
}

struct SubtreeJob {
  uint32_t slot;
  uint64_t begin, end;
  uint32_t depth;
  RangeBounds rb;
};

// Chooses how to split prims[b, e) (bounds `rb`) and partitions them in place; returns the split
// position and fills the children's bounds, or returns `b` when the range should be a leaf.
uint64_t split_range(std::span<PrimRef> prims, uint64_t b, uint64_t e, const RangeBounds& rb, uint32_t depth,
                     RangeBounds& left, RangeBounds& right) {
  const uint64_t n = e - b;
  auto range = prims.subspan(b, n);
  int axis = 0;
  float extent[3];
  for (int k = 0; k < 3; ++k) {
    extent[k] = rb.centres.hi[k] - rb.centres.lo[k];
    if (extent[k] > extent[axis]) axis = k;
  }
  auto halve = [&](uint64_t mid) {
    left = range_bounds(prims.subspan(b, mid - b));
    right = range_bounds(prims.subspan(mid, e - mid));
    return mid;
  };
  if (depth >= kMedianDepth) {
    // Bounded depth whatever the input: object-median halving finishes in ≤ 31 more levels.
    if (n <= kMedianLeaf) return b;
    auto mid = range.begin() + n / 2;
    std::nth_element(range.begin(), mid, range.end(), [axis](const PrimRef& x, const PrimRef& y) {
      const float cx = x.centre(axis), cy = y.centre(axis);
      return cx < cy || (cx == cy && x.face < y.face);
    });
    return halve(b + n / 2);
  }
  if (!(extent[axis] > 0)) {
    // Identical centres (duplicate faces): SAH cannot separate them, halve the run instead.
    return n <= kMaxLeaf ? b : halve(b + n / 2);
  }
  // Binning along the widest centre extent only: a third of the work of trying all three axes,
  // for the same query time on a 1.3M-face icosphere (1M queries, 3.4 s CPU either way).
  const BinMap map{rb.centres.lo[axis], float(kBins) / extent[axis]};
  Split split = best_split(bin_prims(range, map, axis));
  const double area = rb.bounds.half_area();
  if (n <= kMaxLeaf && double(n) * area <= kTraversalCost * area + split.cost) return b;
  const uint32_t last = split.bin;
  auto mid = std::partition(range.begin(), range.end(), [&](const PrimRef& p) { return map.bin(p.centre(axis)) <= last; });
  const uint64_t n_left = uint64_t(mid - range.begin());
  // Only reachable when centre extents overflow float (|x| ~ 1e38): fall back to halving.
  if (n_left == 0 || n_left == n) return halve(b + n / 2);
  left = split.left;
  right = split.right;
  return b + n_left;
}

// Builds the subtree of prims[b, e) (bounds `rb`) rooted at nodes[slot]. With `jobs`, ranges of
// at most kSubtreeTask primitives are deferred to `jobs` instead (their slot is left unset).
void build_node(std::span<PrimRef> prims, std::vector<BvhNode>& nodes, uint32_t slot, uint64_t b, uint64_t e,
                const RangeBounds& rb, uint32_t depth, uint32_t& max_depth, std::vector<SubtreeJob>* jobs) {
  if (jobs && e - b <= kSubtreeTask) {
    jobs->push_back({slot, b, e, depth, rb});
    return;
  }
  max_depth = std::max(max_depth, depth);
  BvhNode node;
  std::copy_n(rb.bounds.lo, 3, node.lo);
  std::copy_n(rb.bounds.hi, 3, node.hi);
  RangeBounds left, right;
  const uint64_t mid = e - b <= kAlwaysLeaf ? b : split_range(prims, b, e, rb, depth, left, right);
  if (mid == b) {
    node.index = static_cast<uint32_t>(b);
    node.count = static_cast<uint32_t>(e - b);
    nodes[slot] = node;
    return;
  }
  node.index = static_cast<uint32_t>(nodes.size());
  node.count = 0;
  nodes[slot] = node;
  nodes.emplace_back();
  nodes.emplace_back();
  build_node(prims, nodes, node.index, b, mid, left, depth + 1, max_depth, jobs);
  build_node(prims, nodes, node.index + 1, mid, e, right, depth + 1, max_depth, jobs);
}

Vec3 sub(const Vec3& x, const Vec3& y) { return {x[0] - y[0], x[1] - y[1], x[2] - y[2]}; }
double dot(const Vec3& x, const Vec3& y) { return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]; }
Vec3 cross(const Vec3& x, const Vec3& y) {
  return {x[1] * y[2] - x[2] * y[1], x[2] * y[0] - x[0] * y[2], x[0] * y[1] - x[1] * y[0]};
}
Vec3 lerp(const Vec3& a, const Vec3& d, double t) { return {a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]}; }

Vec3 closest_on_segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  Vec3 ab = sub(b, a);
  double len2 = dot(ab, ab);
  double t = len2 > 0 ? std::clamp(dot(sub(p, a), ab) / len2, 0.0, 1.0) : 0.0;
  return lerp(a, ab, t);
}

double distance_squared(const Vec3& x, const Vec3& y) {
  Vec3 d = sub(x, y);
  return dot(d, d);
}

double box_distance_squared(const BvhNode& n, const Vec3& p) {
  double d2 = 0;
  for (int k = 0; k < 3; ++k) {
    double d = std::max({double(n.lo[k]) - p[k], 0.0, p[k] - double(n.hi[k])});
    d2 += d * d;
  }
  return d2;
}

}  // namespace

Vec3 closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = sub(b, a), ac = sub(c, a), ap = sub(p, a);
  const Vec3 n = cross(ab, ac);
  const double nn = dot(n, n);
  // sin²(angle at a) below 1e-16: the face-region projection would lose all precision, and
  // the triangle is within 1e-8 · edge of its edges, so take the closest of the three edges.
  if (!(nn > 1e-16 * dot(ab, ab) * dot(ac, ac))) {
    Vec3 best = closest_on_segment(p, a, b);
    for (const Vec3& q : {closest_on_segment(p, b, c), closest_on_segment(p, c, a)})
      if (distance_squared(p, q) < distance_squared(p, best)) best = q;
    return best;
  }
  // Ericson, Real-Time Collision Detection §5.1.5: classify p into a vertex, edge or face
  // Voronoi region with dot products only.
  const double d1 = dot(ab, ap), d2 = dot(ac, ap);
  if (d1 <= 0 && d2 <= 0) return a;
  const Vec3 bp = sub(p, b);
  const double d3 = dot(ab, bp), d4 = dot(ac, bp);
  if (d3 >= 0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return lerp(a, ab, d1 - d3 > 0 ? d1 / (d1 - d3) : 0.0);
  const Vec3 cp = sub(p, c);
  const double d5 = dot(ab, cp), d6 = dot(ac, cp);
  if (d6 >= 0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return lerp(a, ac, d2 - d6 > 0 ? d2 / (d2 - d6) : 0.0);
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    const double den = (d4 - d3) + (d5 - d6);
    return lerp(b, sub(c, b), den > 0 ? (d4 - d3) / den : 0.0);
  }
  // Face region. Ericson's barycentric form divides by va+vb+vc, which cancels badly for thin
  // triangles; projecting along the normal is exact up to the normal's rounding.
  return lerp(p, n, -dot(ap, n) / nn);
}

TriangleBvh build_triangle_bvh(const TriangleSoupView& mesh) {
  const uint64_t face_count = mesh.face_count();
  const uint32_t vertex_count = mesh.vertex_count();
  if (face_count >= (uint64_t(1) << 31))
    throw InputError("bvh: " + std::to_string(face_count) + " faces exceed the 2^31 limit");
  TriangleBvh bvh;
  if (face_count == 0) return bvh;

  std::vector<PrimRef> prims(face_count);
  for (uint64_t f = 0; f < face_count; ++f) {
    PrimRef& p = prims[f];
    p.face = static_cast<uint32_t>(f);
    std::fill_n(p.lo, 3, INFINITY);
    std::fill_n(p.hi, 3, -INFINITY);
    for (int j = 0; j < 3; ++j) {
      uint32_t v = mesh.triangles[3 * f + j];
      if (v >= vertex_count)
        throw InputError("bvh: face " + std::to_string(f) + " uses vertex " + std::to_string(v) + " of " +
                         std::to_string(vertex_count));
      for (int k = 0; k < 3; ++k) {
        float x = mesh.positions[3 * size_t(v) + k];
        if (!std::isfinite(x))
          throw InputError("bvh: vertex " + std::to_string(v) + " has a non-finite coordinate");
        p.lo[k] = std::min(p.lo[k], x);
        p.hi[k] = std::max(p.hi[k], x);
      }
    }
  }

  // Top of the tree sequentially (each big node bins in parallel), then independent subtrees
  // in parallel, each into its own array; splicing them in job order makes the node layout
  // independent of the thread count.
  uint32_t depth = 0;
  std::vector<SubtreeJob> jobs;
  bvh.nodes.emplace_back();
  build_node(prims, bvh.nodes, 0, 0, face_count, range_bounds(prims), 0, depth, &jobs);
  std::vector<std::vector<BvhNode>> subtrees(jobs.size());
  std::vector<uint32_t> subtree_depth(jobs.size(), 0);
  tbb::parallel_for(size_t(0), jobs.size(), [&](size_t j) {
    const SubtreeJob& job = jobs[j];
    std::vector<BvhNode>& local = subtrees[j];
    local.reserve(size_t((job.end - job.begin) * 3 / 4) + 1);
    local.emplace_back();
    build_node(prims, local, 0, job.begin, job.end, job.rb, job.depth, subtree_depth[j], nullptr);
  });
  uint64_t total = bvh.nodes.size();
  for (const auto& s : subtrees) total += s.size() - 1;
  bvh.nodes.reserve(total);
  for (size_t j = 0; j < jobs.size(); ++j) {
    // Local node i > 0 lands at global offset + i - 1; the local root fills the job's slot.
    const auto offset = static_cast<uint32_t>(bvh.nodes.size());
    auto relocate = [offset](BvhNode n) {
      if (n.count == 0) n.index = offset + n.index - 1;
      return n;
    };
    bvh.nodes[jobs[j].slot] = relocate(subtrees[j][0]);
    for (size_t i = 1; i < subtrees[j].size(); ++i) bvh.nodes.push_back(relocate(subtrees[j][i]));
    depth = std::max(depth, subtree_depth[j]);
    std::vector<BvhNode>().swap(subtrees[j]);
  }
  if (depth > kBvhMaxDepth) throw std::logic_error("bvh: depth bound violated");
  bvh.depth = depth;

  // Face order first, then drop the build records before the corners are copied, so the peak
  // stays near the final size instead of adding the 28 B/face of PrimRefs on top of it.
  bvh.faces.resize(face_count);
  for (uint64_t i = 0; i < face_count; ++i) bvh.faces[i] = prims[i].face;
  std::vector<PrimRef>().swap(prims);
  bvh.corners.resize(9 * face_count);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, face_count), [&](const tbb::blocked_range<uint64_t>& r) {
    for (uint64_t i = r.begin(); i < r.end(); ++i)
      for (int j = 0; j < 3; ++j) {
        const size_t v = mesh.triangles[3 * size_t(bvh.faces[i]) + j];
        std::copy_n(&mesh.positions[3 * v], 3, &bvh.corners[9 * i + 3 * j]);
      }
  });
  return bvh;
}

ClosestHit closest_point(const TriangleBvh& bvh, Vec3 p, double max_distance_squared) {
  ClosestHit hit;
  hit.distance_squared = max_distance_squared;
  if (bvh.nodes.empty()) return hit;
  struct Entry {
    uint32_t node;
    double d2;
  };
  Entry stack[kBvhMaxDepth + 2];
  int top = 0;
  stack[top++] = {0, box_distance_squared(bvh.nodes[0], p)};
  while (top > 0) {
    const Entry e = stack[--top];
    if (!(e.d2 < hit.distance_squared)) continue;
    const BvhNode* node = &bvh.nodes[e.node];
    // Descend towards the nearer child without touching the stack; the farther one waits.
    while (node->count == 0) {
      uint32_t near = node->index, far = node->index + 1;
      double dnear = box_distance_squared(bvh.nodes[near], p);
      double dfar = box_distance_squared(bvh.nodes[far], p);
      if (dfar < dnear) {
        std::swap(near, far);
        std::swap(dnear, dfar);
      }
      if (dfar < hit.distance_squared) stack[top++] = {far, dfar};
      if (!(dnear < hit.distance_squared)) {
        node = nullptr;
        break;
      }
      node = &bvh.nodes[near];
    }
    if (!node) continue;
    for (uint32_t i = node->index; i < node->index + node->count; ++i) {
      const float* t = &bvh.corners[9 * size_t(i)];
      const Vec3 q = closest_point_on_triangle(p, {t[0], t[1], t[2]}, {t[3], t[4], t[5]}, {t[6], t[7], t[8]});
      const double d2 = distance_squared(p, q);
      if (d2 < hit.distance_squared) {
        hit.distance_squared = d2;
        hit.point = q;
        hit.face = bvh.faces[i];
      }
    }
  }
  return hit;
}

}  // namespace streamcvd
