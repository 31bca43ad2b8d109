// Jet-fitting curvature (Cazals & Pouget 2005, paper ref [30]). Cazals-Pouget fit the jet in a
// PCA frame and then re-orient it along the fitted normal; here the first frame comes from the
// area-weighted face normals (their orientation gives the sign of the curvatures), one fit
// corrects the normal from its linear terms, and a second fit in the corrected frame gives the
// curvatures. Coordinates are divided by the ring radius so the normal matrix stays well
// conditioned whatever the mesh units.
#include "streamcvd/core/fields/curvature.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <bit>
#include <cmath>
#include <span>
#include <string>

#include "streamcvd/core/mesh/errors.h"

namespace streamcvd {
namespace {

using Vec3 = Eigen::Vector3d;

// Open-addressing set of vertex ids. Slots are "empty" unless their stamp equals the current
// generation, so starting a new vertex costs O(1) instead of clearing the table.
class VisitedSet {
 public:
  void clear() {
    if (keys_.empty()) resize(64);
    size_ = 0;
    if (++generation_ == 0) {  // stamps wrapped: forget every old entry for real
      std::fill(stamps_.begin(), stamps_.end(), 0u);
      generation_ = 1;
    }
  }
  // True when `key` was not in the set (and is now).
  bool insert(uint32_t key) {
    if (2 * (size_ + 1) > keys_.size()) grow();
    for (uint32_t slot = hash(key);; slot = (slot + 1) & mask_) {
      if (stamps_[slot] != generation_) {
        stamps_[slot] = generation_;
        keys_[slot] = key;
        ++size_;
        return true;
      }
      if (keys_[slot] == key) return false;
    }
  }

 private:
  // Fibonacci hashing: the top bits of key·2^32/φ spread neighbouring ids over the table.
  uint32_t hash(uint32_t key) const { return uint32_t((key * 2654435769u) >> shift_); }
  void resize(size_t capacity) {
    keys_.assign(capacity, 0);
    stamps_.assign(capacity, 0);
    mask_ = uint32_t(capacity - 1);
    shift_ = 32 - std::countr_zero(capacity);
    generation_ = 1;
  }
  void grow() {
    std::vector<uint32_t> old_keys = std::move(keys_), old_stamps = std::move(stamps_);
    const uint32_t old_generation = generation_;
    resize(old_keys.size() * 2);
    size_ = 0;
    for (size_t i = 0; i < old_keys.size(); ++i)
      if (old_stamps[i] == old_generation) insert(old_keys[i]);
  }
  std::vector<uint32_t> keys_, stamps_;
  uint32_t generation_ = 0, mask_ = 0, size_ = 0;
  int shift_ = 32;
};

struct Scratch {
  VisitedSet visited;
  std::vector<uint32_t> ring;  // BFS order, ring[0] = the vertex itself
};

// CSR row of v, or an empty row when the offsets are inconsistent (a hand-made view must not
// make us read out of bounds).
std::span<const uint32_t> csr_row(std::span<const uint64_t> offsets, std::span<const uint32_t> data, uint32_t v) {
  const uint64_t b = offsets[v], e = offsets[size_t(v) + 1];
  if (b > e || e > data.size()) return {};
  return data.subspan(b, e - b);
}

Vec3 position(const MeshView& m, uint32_t v) {
  return {m.positions[3 * size_t(v)], m.positions[3 * size_t(v) + 1], m.positions[3 * size_t(v) + 2]};
}

// Vertices within `rings` edges of v, then further rings (up to max_rings) while fewer than
// `need` neighbours were found; stops after a ring that reaches max_neighbours.
void gather_ring(const MeshView& m, uint32_t v, const CurvatureOptions& opt, size_t need, Scratch& s) {
  const uint32_t vertices = m.vertex_count();
  s.ring.clear();
  s.visited.clear();
  s.visited.insert(v);
  s.ring.push_back(v);
  size_t level_begin = 0, level_end = 1;
  for (int r = 1; r <= opt.max_rings; ++r) {
    if (r > opt.rings && s.ring.size() - 1 >= need) break;
    if (s.ring.size() >= opt.max_neighbours || level_begin == level_end) break;
    for (size_t i = level_begin; i < level_end; ++i)
      for (uint32_t w : csr_row(m.vertex_vertex_offsets, m.vertex_vertex, s.ring[i]))
        if (w < vertices && s.visited.insert(w)) s.ring.push_back(w);
    level_begin = level_end;
    level_end = s.ring.size();
  }
}

// Σ over the faces of v of (p1 - p0) × (p2 - p0): twice the area-weighted face normal. Also
// returns Σ |cross| so the caller can tell cancellation (folded fans) from a real normal.
Vec3 area_normal(const MeshView& m, uint32_t v, double& magnitude_sum) {
  const uint32_t vertices = m.vertex_count();
  const uint64_t faces = m.face_count();
  Vec3 sum = Vec3::Zero();
  for (uint32_t f : csr_row(m.vertex_face_offsets, m.vertex_face, v)) {
    if (f >= faces) continue;
    const uint32_t a = m.triangles[3 * size_t(f)], b = m.triangles[3 * size_t(f) + 1], c = m.triangles[3 * size_t(f) + 2];
    if (a >= vertices || b >= vertices || c >= vertices) continue;
    const Vec3 p = position(m, a);
    const Vec3 n = (position(m, b) - p).cross(position(m, c) - p);
    sum += n;
    magnitude_sum += n.norm();
  }
  return sum;
}

// Normal of the ring's best-fit plane (PCA), oriented like the face normals around the ring.
// Used when the vertex's own face normals cancel out. Zero when even that is undefined.
Vec3 pca_normal(const MeshView& m, const Scratch& s) {
  Vec3 centroid = Vec3::Zero();
  for (uint32_t w : s.ring) centroid += position(m, w);
  centroid /= double(s.ring.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  Vec3 orientation = Vec3::Zero();
  for (uint32_t w : s.ring) {
    const Vec3 d = position(m, w) - centroid;
    cov += d * d.transpose();
    double unused = 0;
    orientation += area_normal(m, w, unused);
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(cov);
  if (eig.info() != Eigen::Success) return Vec3::Zero();
  Vec3 n = eig.eigenvectors().col(0);  // smallest eigenvalue: across the surface
  if (n.dot(orientation) < 0) n = -n;
  return n;
}

// Right-handed orthonormal frame (u, v, n) from a unit n, continuous except at n.z = 0
// (Duff et al. 2017, "Building an orthonormal basis, revisited").
struct Frame {
  Vec3 u, v, n;
};
Frame make_frame(const Vec3& n) {
  const double sign = std::copysign(1.0, n.z());
  const double a = -1.0 / (sign + n.z()), b = n.x() * n.y() * a;
  return {Vec3(1 + sign * n.x() * n.x() * a, sign * b, -sign * n.x()), Vec3(b, sign + n.y() * n.y() * a, -n.y()), n};
}

// Least-squares fit of Z = A X² + B XY + C Y² + D X + E Y (+ F) to the ring in `frame`, with
// coordinates relative to p0 and divided by h. N = 5 or 6 unknowns. False when the normal
// equations are singular or too ill-conditioned to trust.
template <int N>
bool fit_jet(const MeshView& m, const Scratch& s, const Vec3& p0, const Frame& frame, double inv_h,
             const CurvatureOptions& opt, double coeff[6]) {
  double M[N][N] = {}, rhs[N] = {};
  for (uint32_t w : s.ring) {
    const Vec3 d = (position(m, w) - p0) * inv_h;
    const double x = d.dot(frame.u), y = d.dot(frame.v), z = d.dot(frame.n);
    const double weight = opt.gaussian_weights ? std::exp(-d.squaredNorm()) : 1.0;
    const double phi[6] = {x * x, x * y, y * y, x, y, 1.0};
    for (int i = 0; i < N; ++i) {
      const double wi = weight * phi[i];
      rhs[i] += wi * z;
      for (int j = i; j < N; ++j) M[i][j] += wi * phi[j];
    }
  }
  Eigen::Matrix<double, N, N> A;
  Eigen::Matrix<double, N, 1> b;
  for (int i = 0; i < N; ++i) {
    b(i) = rhs[i];
    for (int j = i; j < N; ++j) A(i, j) = A(j, i) = M[i][j];
  }
  // Eigen's LDLT solves around zero pivots (as a pseudo-inverse would), so rcond() alone can
  // miss an exactly rank-deficient system (collinear points): check the pivots too.
  const Eigen::LDLT<Eigen::Matrix<double, N, N>> ldlt(A);
  if (ldlt.info() != Eigen::Success) return false;
  const auto pivots = ldlt.vectorD();
  if (!(pivots.minCoeff() >= opt.min_rcond * pivots.maxCoeff()) || !(ldlt.rcond() >= opt.min_rcond)) return false;
  const Eigen::Matrix<double, N, 1> x = ldlt.solve(b);
  for (int i = 0; i < 6; ++i) coeff[i] = i < N ? x(i) : 0.0;
  for (int i = 0; i < N; ++i)
    if (!std::isfinite(coeff[i])) return false;
  return true;
}

bool fit(const MeshView& m, const Scratch& s, const Vec3& p0, const Frame& frame, double inv_h,
         const CurvatureOptions& opt, double coeff[6]) {
  return opt.fit_constant ? fit_jet<6>(m, s, p0, frame, inv_h, opt, coeff)
                          : fit_jet<5>(m, s, p0, frame, inv_h, opt, coeff);
}

struct VertexResult {
  double k1 = 0, k2 = 0;
  Vec3 d1{1, 0, 0}, d2{0, 1, 0};
  bool fallback = true;
};

// Principal curvatures of the graph z(x, y) at the origin, from its derivatives there: first
// fundamental form I = [[1+fx², fx·fy], [fx·fy, 1+fy²]], second II = [[fxx, fxy], [fxy, fyy]] / w
// with w = √(1+fx²+fy²) and normal (-fx, -fy, 1)/w; the shape operator I⁻¹·II is diagonalised
// in an I-orthonormal basis P (so PᵀIP = Id and PᵀIIP is symmetric). Curvatures are negated so
// that a surface bending away from its normal (a convex surface, outward normals) is positive.
VertexResult shape_operator(const Frame& f, double fx, double fy, double fxx, double fxy, double fyy) {
  const double w = std::sqrt(1 + fx * fx + fy * fy);
  Eigen::Matrix2d I, II, P;
  I << 1 + fx * fx, fx * fy, fx * fy, 1 + fy * fy;
  II << fxx, fxy, fxy, fyy;
  II /= w;
  const Eigen::Vector2d q(-fx * fy / (1 + fx * fx), 1.0);  // r_y minus its component along r_x
  P << 1 / std::sqrt(1 + fx * fx), q.x() / std::sqrt(q.dot(I * q)), 0, q.y() / std::sqrt(q.dot(I * q));
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2d> eig(P.transpose() * II * P);
  VertexResult r;
  if (eig.info() != Eigen::Success) return r;
  const Eigen::Vector2d a = P * eig.eigenvectors().col(0);  // smallest eigenvalue → largest k
  const Vec3 normal = ((f.n - fx * f.u - fy * f.v) / w).normalized();
  r.k1 = -eig.eigenvalues()(0);
  r.k2 = -eig.eigenvalues()(1);
  r.d1 = (a.x() * (f.u + fx * f.n) + a.y() * (f.v + fy * f.n)).normalized();
  r.d2 = normal.cross(r.d1).normalized();
  r.fallback = false;
  return r;
}

VertexResult vertex_curvature(const MeshView& m, uint32_t v, const CurvatureOptions& opt, Scratch& s) {
  VertexResult fallback;
  const size_t unknowns = opt.fit_constant ? 6 : 5;
  const size_t need = std::max(size_t(std::max(opt.min_neighbours, 0)), unknowns);
  gather_ring(m, v, opt, need, s);

  // Normal first: even a fallback vertex gets d1, d2 in its tangent plane when it has faces.
  double magnitude = 0;
  Vec3 n = area_normal(m, v, magnitude);
  if (!(n.norm() > 1e-9 * magnitude)) n = s.ring.size() >= 3 ? pca_normal(m, s) : Vec3::Zero();
  const double n_norm = n.norm();
  if (!(n_norm > 0) || !std::isfinite(n_norm)) return fallback;
  Frame frame = make_frame(n / n_norm);
  fallback.d1 = frame.u;
  fallback.d2 = frame.v;
  if (s.ring.size() - 1 < need) return fallback;

  const Vec3 p0 = position(m, v);
  double h = 0;
  for (uint32_t w : s.ring) h = std::max(h, (position(m, w) - p0).norm());
  if (!(h > 0) || !std::isfinite(h)) return fallback;
  const double inv_h = 1 / h;

  // Pass 1: the linear terms tilt the normal; re-frame along the fitted normal (-D, -E, 1).
  double c[6];
  if (!fit(m, s, p0, frame, inv_h, opt, c)) return fallback;
  const Vec3 fitted = frame.n - c[3] * frame.u - c[4] * frame.v;
  frame = make_frame(fitted.normalized());
  // Pass 2, then back to unscaled derivatives: z = h·Z(x/h, y/h), so fxx = 2A/h, fxy = B/h.
  if (!fit(m, s, p0, frame, inv_h, opt, c)) return fallback;
  VertexResult r = shape_operator(frame, c[3], c[4], 2 * c[0] * inv_h, c[1] * inv_h, 2 * c[2] * inv_h);
  const bool finite = std::isfinite(float(r.k1)) && std::isfinite(float(r.k2)) && r.d1.allFinite() &&
                      r.d2.allFinite() && std::abs(r.d1.norm() - 1) < 1e-6 && std::abs(r.d2.norm() - 1) < 1e-6;
  return finite ? r : fallback;
}

void check_view(const MeshView& m, const CurvatureOptions& opt) {
  const size_t vertices = m.vertex_count();
  auto fail = [](const std::string& problem) { throw InputError("curvature: " + problem); };
  if (opt.rings < 1) fail("rings must be at least 1, got " + std::to_string(opt.rings));
  if (m.positions.size() % 3 != 0 || m.triangles.size() % 3 != 0)
    fail("positions and triangles must hold 3 values per element");
  if (vertices == 0) return;
  if (m.vertex_vertex_offsets.size() != vertices + 1 || m.vertex_face_offsets.size() != vertices + 1)
    fail("adjacency offsets must hold V + 1 = " + std::to_string(vertices + 1) + " entries");
  if (m.chunks.empty()) return;
  uint64_t next = 0;
  for (const Chunk& c : m.chunks) {
    if (c.vertex_begin != next || c.vertex_end < c.vertex_begin) fail("chunks do not tile the vertex range");
    next = c.vertex_end;
  }
  if (next != vertices) fail("chunks do not tile the vertex range");
}

}  // namespace

Curvature compute_curvature(const MeshView& mesh, const CurvatureOptions& options) {
  check_view(mesh, options);
  CurvatureOptions opt = options;
  opt.max_rings = std::max(opt.max_rings, opt.rings);
  const uint32_t vertices = mesh.vertex_count();
  Curvature out;
  out.k1.assign(vertices, 0.0f);
  out.k2.assign(vertices, 0.0f);
  out.d1.assign(3 * size_t(vertices), 0.0f);
  out.d2.assign(3 * size_t(vertices), 0.0f);
  out.fallback.assign(vertices, 1);
  if (vertices == 0) return out;

  // A view without chunks is one chunk.
  std::vector<Chunk> whole;
  std::span<const Chunk> chunks = mesh.chunks;
  if (chunks.empty()) {
    whole.resize(1);
    whole[0].vertex_end = vertices;
    chunks = whole;
  }
  tbb::enumerable_thread_specific<Scratch> scratch;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, chunks.size(), 1), [&](const tbb::blocked_range<size_t>& cr) {
    for (size_t ci = cr.begin(); ci != cr.end(); ++ci) {
      const Chunk& chunk = chunks[ci];
      tbb::parallel_for(tbb::blocked_range<uint32_t>(chunk.vertex_begin, chunk.vertex_end, 256),
                        [&](const tbb::blocked_range<uint32_t>& vr) {
                          Scratch& s = scratch.local();  // no TBB call below: never shared mid-use
                          for (uint32_t v = vr.begin(); v != vr.end(); ++v) {
                            const VertexResult r = vertex_curvature(mesh, v, opt, s);
                            out.k1[v] = float(r.k1);
                            out.k2[v] = float(r.k2);
                            for (int j = 0; j < 3; ++j) {
                              out.d1[3 * size_t(v) + j] = float(r.d1[j]);
                              out.d2[3 * size_t(v) + j] = float(r.d2[j]);
                            }
                            out.fallback[v] = r.fallback ? 1 : 0;
                          }
                        });
    }
  });
  out.fallback_count = uint64_t(std::count(out.fallback.begin(), out.fallback.end(), uint8_t(1)));
  return out;
}

}  // namespace streamcvd
