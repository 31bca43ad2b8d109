// Metric fields of paper §VI-H (eqs. 20-22) and the QEM solve of §V-C (Garland & Heckbert
// 1997). Statistics use fixed-order sums and a total-order sort so every result is
// bit-identical for any thread count.
#include "streamcvd/core/fields/metric_field.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "streamcvd/core/mesh/errors.h"

namespace streamcvd {
namespace {

constexpr uint32_t kGrain = 4096;

void check_options(const MetricFieldOptions& o) {
  auto bad = [](const std::string& what) { throw InputError("metric field: " + what); };
  if (!(o.percentile_low >= 0 && o.percentile_low <= o.percentile_high && o.percentile_high <= 1))
    bad("percentiles must satisfy 0 <= low <= high <= 1");
  if (!(o.min_ratio > 0 && o.min_ratio <= 1)) bad("min_ratio must be in (0, 1]");
  if (!(o.max_ratio >= 1 && std::isfinite(o.max_ratio))) bad("max_ratio must be finite and >= 1");
  if (!(o.isotropic_blend > 0 && std::isfinite(o.isotropic_blend))) bad("isotropic_blend must be finite and > 0");
  if (!(o.max_anisotropy >= 1 && std::isfinite(o.max_anisotropy))) bad("max_anisotropy must be finite and >= 1");
  if (!(o.flat_threshold >= 0 && std::isfinite(o.flat_threshold))) bad("flat_threshold must be finite and >= 0");
}

void check_sizes(const MeshView& mesh, const Curvature& k, bool need_directions) {
  const size_t V = mesh.vertex_count();
  if (k.k1.size() != V || k.k2.size() != V || (!k.fallback.empty() && k.fallback.size() != V))
    throw InputError("metric field: curvature has " + std::to_string(k.k1.size()) + " vertices, mesh has " +
                     std::to_string(V));
  if (need_directions && (k.d1.size() != 3 * V || k.d2.size() != 3 * V))
    throw InputError("metric field: curvature directions are not 3 floats per vertex");
  if (V > 0 && mesh.vertex_face_offsets.size() != V + 1)
    throw InputError("metric field: mesh has no vertex-face adjacency");
}

bool is_fallback(const Curvature& k, uint32_t v) {
  return (!k.fallback.empty() && k.fallback[v]) || !std::isfinite(k.k1[v]) || !std::isfinite(k.k2[v]);
}

// |P_j|: a third of the areas of the faces around each vertex (0 for isolated vertices).
std::vector<double> vertex_areas(const MeshView& mesh) {
  const uint32_t V = mesh.vertex_count();
  std::vector<double> area(V, 0.0);
  const float* P = mesh.positions.data();
  const uint32_t* T = mesh.triangles.data();
  const uint64_t F = mesh.face_count();
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, V, kGrain), [&](const tbb::blocked_range<uint32_t>& r) {
    for (uint32_t v = r.begin(); v != r.end(); ++v) {
      double sum = 0;
      for (uint32_t f : mesh.faces_of(v)) {
        if (f >= F) continue;
        const uint32_t i[3] = {T[3 * size_t(f)], T[3 * size_t(f) + 1], T[3 * size_t(f) + 2]};
        if (i[0] >= V || i[1] >= V || i[2] >= V) continue;
        double e1[3], e2[3];
        for (int c = 0; c < 3; ++c) {
          e1[c] = double(P[3 * size_t(i[1]) + c]) - P[3 * size_t(i[0]) + c];
          e2[c] = double(P[3 * size_t(i[2]) + c]) - P[3 * size_t(i[0]) + c];
        }
        const double x = e1[1] * e2[2] - e1[2] * e2[1], y = e1[2] * e2[0] - e1[0] * e2[2],
                     z = e1[0] * e2[1] - e1[1] * e2[0];
        const double a = std::sqrt(x * x + y * y + z * z) / 6.0;
        if (std::isfinite(a)) sum += a;
      }
      area[v] = sum;
    }
  });
  return area;
}

// Value below which a fraction p of the total weight lies, in a list sorted by value.
double weighted_percentile(const std::vector<std::pair<double, double>>& sorted, double total, double p) {
  const double target = p * total;
  double cum = 0;
  for (const auto& [value, weight] : sorted) {
    cum += weight;
    if (cum >= target) return value;
  }
  return sorted.back().first;
}

// Everything the two fields need from the curvature statistics.
struct Stats {
  std::vector<double> area;  // |P_j|, or 1 for all vertices when the mesh has no area at all
  CurvatureRange range;
};

Stats curvature_stats(const MeshView& mesh, const Curvature& k, const MetricFieldOptions& o) {
  Stats st;
  st.area = vertex_areas(mesh);
  const uint32_t V = mesh.vertex_count();
  double total_area = 0;
  for (double a : st.area) total_area += a;
  if (!(total_area > 0)) std::fill(st.area.begin(), st.area.end(), 1.0);  // degenerate: count vertices

  std::vector<std::pair<double, double>> samples;  // (c, |P|) of the fitted vertices
  samples.reserve(V);
  for (uint32_t v = 0; v < V; ++v)
    if (!is_fallback(k, v) && st.area[v] > 0) samples.emplace_back(std::hypot(double(k.k1[v]), double(k.k2[v])), st.area[v]);
  if (samples.empty()) return st;
  tbb::parallel_sort(samples.begin(), samples.end());  // total order on pairs: deterministic
  double total = 0, weighted_sum = 0;
  for (const auto& [c, a] : samples) {
    total += a;
    weighted_sum += a * c;
  }
  double s = weighted_percentile(samples, total, 0.5);
  if (!(s > 0)) s = weighted_sum / total;  // more than half the area is flat
  if (!(s * std::sqrt(total) >= o.flat_threshold) || !std::isfinite(s)) return st;  // flat, or no area
  CurvatureRange& r = st.range;
  r.reference = s;
  r.low = std::max(weighted_percentile(samples, total, o.percentile_low), o.min_ratio * s);
  r.high = std::max(r.low, std::min(weighted_percentile(samples, total, o.percentile_high), o.max_ratio * s));
  return st;
}

// Area-weighted mean in a fixed order (deterministic).
double weighted_mean(const std::vector<double>& area, const std::vector<double>& value) {
  double sw = 0, swv = 0;
  for (size_t i = 0; i < area.size(); ++i) {
    sw += area[i];
    swv += area[i] * value[i];
  }
  return sw > 0 ? swv / sw : 0.0;
}

bool normalise(double v[3]) {
  const double n = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
  if (!(n > 1e-12) || !std::isfinite(n)) return false;
  for (int c = 0; c < 3; ++c) v[c] /= n;
  return true;
}

}  // namespace

CurvatureRange curvature_range(const MeshView& mesh, const Curvature& curvature, const MetricFieldOptions& options) {
  check_options(options);
  check_sizes(mesh, curvature, false);
  return curvature_stats(mesh, curvature, options).range;
}

std::vector<float> gradation_density(const MeshView& mesh, const Curvature& curvature, double gamma,
                                     const MetricFieldOptions& options) {
  check_options(options);
  check_sizes(mesh, curvature, false);
  if (!(std::abs(gamma) <= 8)) throw InputError("metric field: gradation gamma must be in [-8, 8]");
  const uint32_t V = mesh.vertex_count();
  std::vector<float> density(V, 1.0f);
  if (gamma == 0 || V == 0) return density;
  const Stats st = curvature_stats(mesh, curvature, options);
  const CurvatureRange& r = st.range;
  if (!(r.reference > 0)) return density;
  // Eq. 20 relative to the reference, in log space: (c/s)^γ stays within 10^±32 for |γ| ≤ 8.
  std::vector<double> m(V);
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, V, kGrain), [&](const tbb::blocked_range<uint32_t>& br) {
    for (uint32_t v = br.begin(); v != br.end(); ++v) {
      const double c = is_fallback(curvature, v) ? r.reference : std::hypot(double(curvature.k1[v]), double(curvature.k2[v]));
      m[v] = std::exp(gamma * std::log(std::clamp(c, r.low, r.high) / r.reference));
    }
  });
  const double mean = weighted_mean(st.area, m);
  for (uint32_t v = 0; v < V; ++v) density[v] = float(m[v] / mean);
  return density;
}

AnisotropicField anisotropic_field(const MeshView& mesh, const Curvature& curvature, const MetricFieldOptions& options) {
  check_options(options);
  check_sizes(mesh, curvature, true);
  const uint32_t V = mesh.vertex_count();
  AnisotropicField out;
  out.tensors.assign(6 * size_t(V), 0.0f);
  out.density.assign(V, 1.0f);
  for (uint32_t v = 0; v < V; ++v) out.tensors[6 * size_t(v)] = out.tensors[6 * size_t(v) + 3] = out.tensors[6 * size_t(v) + 5] = 1.0f;
  out.kappa0 = 1;
  if (V == 0) return out;
  const Stats st = curvature_stats(mesh, curvature, options);
  const CurvatureRange& r = st.range;
  if (!(r.reference > 0)) return out;  // flat everywhere: K = I

  // a1, a2: |k1|, |k2| scaled so that their magnitude is at most hi (the ratio k1:k2 is kept).
  std::vector<double> a1(V), a2(V), half(V);
  for (uint32_t v = 0; v < V; ++v) {
    if (is_fallback(curvature, v)) {
      a1[v] = a2[v] = r.reference / std::sqrt(2.0);  // umbilic of typical magnitude
    } else {
      const double k1 = std::abs(double(curvature.k1[v])), k2 = std::abs(double(curvature.k2[v]));
      const double c = std::hypot(k1, k2), scale = c > r.high ? r.high / c : 1.0;
      a1[v] = k1 * scale;
      a2[v] = k2 * scale;
    }
    half[v] = 0.5 * (a1[v] + a2[v]);
  }
  const double kappa0 = options.isotropic_blend * weighted_mean(st.area, half);
  if (!(kappa0 > 0)) return out;
  const double cap = (options.max_anisotropy - 1) * kappa0;
  for (uint32_t v = 0; v < V; ++v) {
    a1[v] = std::min(a1[v], cap) + kappa0;
    a2[v] = std::min(a2[v], cap) + kappa0;
    half[v] = 0.5 * (a1[v] + a2[v]);
  }
  const double N = weighted_mean(st.area, half);
  out.kappa0 = kappa0;
  out.scale = N;
  out.max_ratio = std::min(options.max_anisotropy, 1 + r.high / kappa0);

  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, V, kGrain), [&](const tbb::blocked_range<uint32_t>& br) {
    for (uint32_t v = br.begin(); v != br.end(); ++v) {
      float* K = &out.tensors[6 * size_t(v)];
      const double l1 = a1[v] / N, l2 = a2[v] / N, l0 = kappa0 / N;
      out.density[v] = float(std::sqrt(l1 * l2));
      // Orthonormal frame from D1, D2 (Gram-Schmidt), n = D1 × D2 (eq. 22 plus the blend row).
      double u1[3] = {curvature.d1[3 * size_t(v)], curvature.d1[3 * size_t(v) + 1], curvature.d1[3 * size_t(v) + 2]};
      double u2[3] = {curvature.d2[3 * size_t(v)], curvature.d2[3 * size_t(v) + 1], curvature.d2[3 * size_t(v) + 2]};
      bool ok = normalise(u1);
      if (ok) {
        const double d = u1[0] * u2[0] + u1[1] * u2[1] + u1[2] * u2[2];
        for (int c = 0; c < 3; ++c) u2[c] -= d * u1[c];
        ok = normalise(u2);
      }
      if (!ok) {
        const double iso = 0.5 * (l1 + l2);
        K[0] = K[3] = K[5] = float(iso);
        K[1] = K[2] = K[4] = 0.0f;
        continue;
      }
      const double n[3] = {u1[1] * u2[2] - u1[2] * u2[1], u1[2] * u2[0] - u1[0] * u2[2], u1[0] * u2[1] - u1[1] * u2[0]};
      auto entry = [&](int i, int j) { return l1 * u1[i] * u1[j] + l2 * u2[i] * u2[j] + l0 * n[i] * n[j]; };
      K[0] = float(entry(0, 0));
      K[1] = float(entry(0, 1));
      K[2] = float(entry(0, 2));
      K[3] = float(entry(1, 1));
      K[4] = float(entry(1, 2));
      K[5] = float(entry(2, 2));
    }
  });
  return out;
}

std::vector<float> anisotropic_tensors(const MeshView& mesh, const Curvature& curvature, const MetricFieldOptions& options) {
  return anisotropic_field(mesh, curvature, options).tensors;
}

int qem_point(const double A[6], const double b[3], const double centroid[3], double relative_threshold,
              double out[3]) {
  out[0] = centroid[0];
  out[1] = centroid[1];
  out[2] = centroid[2];
  Eigen::Matrix3d M;
  M << A[0], A[1], A[2], A[1], A[3], A[4], A[2], A[4], A[5];
  if (!M.allFinite() || !std::isfinite(b[0] + b[1] + b[2]) || !std::isfinite(centroid[0] + centroid[1] + centroid[2]))
    return 0;
  // computeDirect: closed form for 3×3, ~10× faster than the iterative solver; its accuracy on
  // the small eigenvalues (~1e-9 of λmax in double) is far below any useful threshold.
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  eig.computeDirect(M);
  const Eigen::Vector3d& lambda = eig.eigenvalues();  // ascending
  const double lmax = lambda[2];
  if (!(lmax > 0) || !std::isfinite(lmax)) return 0;
  const double floor = std::max(relative_threshold, 0.0) * lmax;
  const Eigen::Vector3d c(centroid[0], centroid[1], centroid[2]);
  const Eigen::Vector3d residual = -Eigen::Vector3d(b[0], b[1], b[2]) - M * c;
  Eigen::Vector3d x = c;
  int rank = 0;
  for (int k = 2; k >= 0; --k) {
    if (!(lambda[k] > floor)) break;
    const Eigen::Vector3d u = eig.eigenvectors().col(k);
    x += u * (u.dot(residual) / lambda[k]);
    ++rank;
  }
  if (!x.allFinite()) return 0;
  out[0] = x[0];
  out[1] = x[1];
  out[2] = x[2];
  return rank;
}

double quadric_value(const double q[10], const double x[3]) {
  const double Ax[3] = {q[0] * x[0] + q[1] * x[1] + q[2] * x[2], q[1] * x[0] + q[3] * x[1] + q[4] * x[2],
                        q[2] * x[0] + q[4] * x[1] + q[5] * x[2]};
  return x[0] * Ax[0] + x[1] * Ax[1] + x[2] * Ax[2] + 2 * (q[6] * x[0] + q[7] * x[1] + q[8] * x[2]) + q[9];
}

}  // namespace streamcvd
