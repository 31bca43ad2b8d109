#include "streamcvd/core/clustering/cluster_energy.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <stdexcept>
#include <string>

#include "streamcvd/core/fields/metric_field.h"

namespace streamcvd {

namespace {

// Largest accepted ‖z − c‖ per √W (W = cluster area for ρ = 1; √(W/π) is its radius).
constexpr double kMaxOffsetPerRootWeight = 0.75;

// c = M⁻¹s for a symmetric positive definite M (xx, xy, xz, yy, yz, zz); false when singular.
bool solve_symmetric(const double* M, const double* s, double* c) {
  const double a = M[0], b = M[1], cc = M[2], d = M[3], e = M[4], f = M[5];
  const double A00 = d * f - e * e, A01 = cc * e - b * f, A02 = b * e - cc * d;
  const double A11 = a * f - cc * cc, A12 = b * cc - a * e, A22 = a * d - b * b;
  const double det = a * A00 + b * A01 + cc * A02;
  if (!(std::abs(det) > 0) || !std::isfinite(det)) return false;
  const double inv = 1.0 / det;
  c[0] = (A00 * s[0] + A01 * s[1] + A02 * s[2]) * inv;
  c[1] = (A01 * s[0] + A11 * s[1] + A12 * s[2]) * inv;
  c[2] = (A02 * s[0] + A12 * s[1] + A22 * s[2]) * inv;
  return std::isfinite(c[0]) && std::isfinite(c[1]) && std::isfinite(c[2]);
}

inline void update_iso_centroid(ClusterSums& s) {
  const double inv = s.weight > 0 ? 1.0 / s.weight : 0.0;
  for (int c = 0; c < 3; ++c) s.centroid[c] = s.sum[c] * inv;
}

// Anisotropic centroid; falls back to the isotropic one when ΣK is singular (empty cluster).
inline void update_aniso_centroid(AnisoSums& a, const ClusterSums& iso) {
  if (!solve_symmetric(a.tensor, a.sum, a.centroid))
    for (int c = 0; c < 3; ++c) a.centroid[c] = iso.centroid[c];
}

const double* centroid_of(const ClusterState& s, size_t c) {
  return is_anisotropic(s.metric) ? s.aniso[c].centroid : s.iso[c].centroid;
}

}  // namespace

const char* metric_name(Metric m) {
  switch (m) {
    case Metric::I: return "I";
    case Metric::IQ: return "IQ";
    case Metric::A: return "A";
    case Metric::AQ: return "AQ";
  }
  return "?";
}

bool parse_metric(std::string_view text, Metric& out) {
  std::string upper;
  for (char ch : text) upper.push_back(char(std::toupper(static_cast<unsigned char>(ch))));
  for (Metric m : {Metric::I, Metric::IQ, Metric::A, Metric::AQ})
    if (upper == metric_name(m)) {
      out = m;
      return true;
    }
  return false;
}

ClusterState make_cluster_state(const ItemData& items, std::span<const int32_t> labels, uint32_t cluster_count,
                                Metric metric, double qem_threshold) {
  ClusterState s;
  s.metric = metric;
  s.qem_threshold = qem_threshold;
  s.iso.assign(cluster_count, ClusterSums{});
  const bool aniso = is_anisotropic(metric), quadrics = uses_quadrics(metric);
  if (aniso && items.tensor.size() != 6 * items.weight.size())
    throw std::invalid_argument(std::string("make_cluster_state: metric ") + metric_name(metric) +
                                " needs a tensor per item (attach_tensors)");
  if (quadrics && items.quadric.size() != 10 * items.weight.size())
    throw std::invalid_argument(std::string("make_cluster_state: metric ") + metric_name(metric) +
                                " needs a quadric per item (ItemQuadrics::per_vertex)");
  if (aniso) s.aniso.assign(cluster_count, AnisoSums{});
  if (quadrics) {
    s.quadric.assign(cluster_count, QuadricSums{});
    s.offset.assign(3 * size_t(cluster_count), 0.0);
  }
  // Each cluster's sums run over its vertices in vertex order, whichever thread adds them: the
  // cluster ids are dealt out in blocks of 4096 to `parts` parts, and each part scans every
  // label and sums its own clusters. The sums are those of one serial pass for any part count;
  // a scan of the labels (4 bytes per vertex) per part is the price.
  const uint32_t parts = labels.size() < (size_t(1) << 16)
                             ? 1u
                             : uint32_t(std::clamp(tbb::this_task_arena::max_concurrency(), 1, 8));
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, parts, 1), [&](const tbb::blocked_range<uint32_t>& r) {
    for (uint32_t part = r.begin(); part != r.end(); ++part)
      for (size_t v = 0; v < labels.size(); ++v) {
        const int32_t l = labels[v];
        if (l < 0 || (uint32_t(l) >> 12) % parts != part) continue;
        const double m = items.weight[v];
        const float* g = &items.centroid[3 * v];
        ClusterSums& c = s.iso[l];
        c.weight += m;
        for (int k = 0; k < 3; ++k) c.sum[k] += m * g[k];
        ++c.count;
        if (aniso) {
          AnisoSums& a = s.aniso[l];
          const float* T = &items.tensor[6 * v];
          for (int k = 0; k < 6; ++k) a.tensor[k] += m * T[k];
          double gd[3] = {g[0], g[1], g[2]}, w[3];
          energy_detail::tensor_times(m, T, gd, w);
          for (int k = 0; k < 3; ++k) a.sum[k] += w[k];
        }
        if (quadrics) {
          const float* q = &items.quadric[10 * v];
          for (int k = 0; k < 10; ++k) s.quadric[l].q[k] += q[k];
        }
      }
  });
  for (uint32_t c = 0; c < cluster_count; ++c) {
    update_iso_centroid(s.iso[c]);
    if (aniso) update_aniso_centroid(s.aniso[c], s.iso[c]);
  }
  return s;
}

void update_site_offset(ClusterState& s, size_t c) {
  double* d = &s.offset[3 * c];
  const double* centre = centroid_of(s, c);
  if (s.iso[c].count == 0) {
    d[0] = d[1] = d[2] = 0;
    return;
  }
  // Truncate more of the quadric's spectrum while the QEM point lies outside its cluster: on
  // a noisy scan the small eigenvalues are noise and the full solve lands far off the surface,
  // while a true corner or crease point lies within the cluster (radius ~ √(W/π)).
  const double limit2 = kMaxOffsetPerRootWeight * kMaxOffsetPerRootWeight * s.iso[c].weight;
  for (double threshold : {s.qem_threshold, 5e-2, 0.25}) {
    double z[3];
    const int rank = qem_point(s.quadric[c].q, s.quadric[c].q + 6, centre, threshold, z);
    for (int k = 0; k < 3; ++k) d[k] = std::isfinite(z[k]) ? z[k] - centre[k] : 0.0;
    if (d[0] * d[0] + d[1] * d[1] + d[2] * d[2] <= limit2 || rank <= 1) break;
  }
  const double d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  if (d2 > limit2) {
    const double scale = std::sqrt(limit2 / d2);
    for (int k = 0; k < 3; ++k) d[k] *= scale;
  }
}

void update_site_offsets(ClusterState& s) {
  if (s.quadric.empty()) return;
  s.use_offsets = true;
  for (size_t c = 0; c < s.iso.size(); ++c) update_site_offset(s, c);
}

double state_energy(const ItemData& items, const ClusterState& s) {
  // Eq. 13/17: Σ_j γ_jᵀK_jγ_j − Σ_i c_iᵀ(ΣK)c_i + Σ_i d_iᵀ(ΣK)d_i (K_j = M_j·I for I/IQ).
  double e = 0;
  if (is_anisotropic(s.metric)) {
    e = items.sum_tensor_norm2;
    for (size_t c = 0; c < s.iso.size(); ++c) {
      const AnisoSums& a = s.aniso[c];
      if (s.iso[c].count == 0) continue;
      e -= a.centroid[0] * a.sum[0] + a.centroid[1] * a.sum[1] + a.centroid[2] * a.sum[2];
      if (s.use_offsets) {
        const double* d = &s.offset[3 * c];
        const double* K = a.tensor;
        e += K[0] * d[0] * d[0] + K[3] * d[1] * d[1] + K[5] * d[2] * d[2] +
             2.0 * (K[1] * d[0] * d[1] + K[2] * d[0] * d[2] + K[4] * d[1] * d[2]);
      }
    }
  } else {
    e = items.sum_weighted_norm2;
    for (size_t c = 0; c < s.iso.size(); ++c) {
      const ClusterSums& i = s.iso[c];
      if (i.weight <= 0) continue;
      e -= (i.sum[0] * i.sum[0] + i.sum[1] * i.sum[1] + i.sum[2] * i.sum[2]) / i.weight;
      if (s.use_offsets) {
        const double* d = &s.offset[3 * c];
        e += i.weight * (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      }
    }
  }
  return std::max(e, 0.0);
}

std::vector<double> cluster_sites(const ItemData& items, const ClusterState& s) {
  std::vector<double> z(3 * s.iso.size(), 0.0);
  for (size_t c = 0; c < s.iso.size(); ++c) {
    const double* centre = centroid_of(s, c);
    for (int k = 0; k < 3; ++k)
      z[3 * c + k] = items.origin[k] + centre[k] + (s.use_offsets ? s.offset[3 * c + k] : 0.0);
  }
  return z;
}

void apply_move(const ItemData& items, ClusterState& s, uint32_t item, int32_t from, int32_t to) {
  const double m = items.weight[item];
  const float* g = &items.centroid[3 * size_t(item)];
  ClusterSums& a = s.iso[from];
  ClusterSums& b = s.iso[to];
  a.weight -= m;
  b.weight += m;
  for (int c = 0; c < 3; ++c) {
    a.sum[c] -= m * g[c];
    b.sum[c] += m * g[c];
  }
  --a.count;
  ++b.count;
  update_iso_centroid(a);
  update_iso_centroid(b);
  if (!s.aniso.empty()) {
    const float* T = &items.tensor[6 * size_t(item)];
    double gd[3] = {g[0], g[1], g[2]}, w[3];
    energy_detail::tensor_times(m, T, gd, w);
    AnisoSums& x = s.aniso[from];
    AnisoSums& y = s.aniso[to];
    for (int k = 0; k < 6; ++k) {
      x.tensor[k] -= m * T[k];
      y.tensor[k] += m * T[k];
    }
    for (int k = 0; k < 3; ++k) {
      x.sum[k] -= w[k];
      y.sum[k] += w[k];
    }
    update_aniso_centroid(x, a);
    update_aniso_centroid(y, b);
  }
  if (!s.quadric.empty()) {
    const float* q = &items.quadric[10 * size_t(item)];
    for (int k = 0; k < 10; ++k) {
      s.quadric[from].q[k] -= q[k];
      s.quadric[to].q[k] += q[k];
    }
  }
}

}  // namespace streamcvd
