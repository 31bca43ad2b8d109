// Per-cluster accumulators and the O(1) move test of Algorithm 1 for the four metrics of the
// paper: I (eq. 15, site = centroid), IQ (site = QEM point, §V-C), A (eqs. 16-18, site =
// anisotropic centroid) and AQ (anisotropic energy, QEM site). Shared by the serial and the
// parallel clustering loops, so both evaluate exactly the same energy.
//
// Q metrics: the site z_i = c_i + d_i, with c_i the (an)isotropic centroid and d_i the offset
// to the cluster's QEM point. d_i is frozen during a loop and recomputed for the clusters that
// changed at its end (cached per cluster: one 3×3 eigen-solve per changed cluster and loop, not
// one per tested edge as in the reference implementation). With d fixed, the energy of cluster i
// is W‖d‖² + Σ M_j‖γ_j − c_i‖² (iso), so a tested move costs O(1) like metric I.
#pragma once

#include <algorithm>
#include <cstdint>
#include <span>
#include <string_view>
#include <vector>

#include "streamcvd/core/clustering/item_data.h"

namespace streamcvd {

enum class Metric : uint8_t { I, IQ, A, AQ };

inline bool is_anisotropic(Metric m) { return m == Metric::A || m == Metric::AQ; }
inline bool uses_quadrics(Metric m) { return m == Metric::IQ || m == Metric::AQ; }
/// "I", "IQ", "A" or "AQ".
const char* metric_name(Metric m);
/// Parses "I", "IQ", "A", "AQ" (case-insensitive); false when the text is none of them.
bool parse_metric(std::string_view text, Metric& out);

/// Per-cluster accumulators of the isotropic energy: ΣM, ΣMγ (relative to ItemData::origin).
struct ClusterSums {
  double weight = 0;
  double sum[3] = {0, 0, 0};
  double centroid[3] = {0, 0, 0};  ///< sum / weight, kept up to date so a test costs no division
  uint32_t count = 0;
};

/// Anisotropic accumulators (eq. 18): ΣK_j (xx, xy, xz, yy, yz, zz), ΣK_jγ_j, and the
/// anisotropic centroid c = (ΣK_j)⁻¹ΣK_jγ_j, the minimiser of eq. 16 for the cluster.
struct AnisoSums {
  double tensor[6] = {0, 0, 0, 0, 0, 0};
  double sum[3] = {0, 0, 0};
  double centroid[3] = {0, 0, 0};
};

/// Σ of the items' quadrics (A: xx, xy, xz, yy, yz, zz; b: x, y, z; c), Q(x) = xᵀAx + 2bᵀx + c.
struct QuadricSums {
  double q[10] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
};

/// Everything the move test needs about the clusters under one metric.
struct ClusterState {
  Metric metric = Metric::I;
  bool use_offsets = false;         ///< Q metrics once the sites are QEM points (d_i below)
  /// Q metrics: quadric eigenvalues below this fraction of the largest are truncated (§V-C).
  /// Larger values (then 5e-2, 0.25) are tried in turn while the QEM point lies outside its
  /// cluster (‖z − c‖ > 0.75·√W): on a noisy scan the small eigenvalues are noise.
  double qem_threshold = 1e-2;
  std::vector<ClusterSums> iso;     ///< always (counts and weights are used by every metric)
  std::vector<AnisoSums> aniso;     ///< A, AQ
  std::vector<QuadricSums> quadric; ///< IQ, AQ
  std::vector<double> offset;       ///< 3 per cluster: d_i = z_i − c_i (Q metrics, else empty)
  uint32_t cluster_count() const { return uint32_t(iso.size()); }
};

/// Builds the accumulators of `metric` from the labels, each cluster's in vertex order (the same
/// sums for any thread count; TBB-parallel by blocks of cluster ids, each part scanning the
/// labels). Offsets start at zero (use_offsets false). Throws std::invalid_argument when the
/// items lack what the metric needs: a tensor per item for A/AQ (attach_tensors), a quadric per
/// item for IQ/AQ; the state's metric is always `metric`. O(V·parts + K), parts ≤ 8.
ClusterState make_cluster_state(const ItemData& items, std::span<const int32_t> labels, uint32_t cluster_count,
                                Metric metric, double qem_threshold = 1e-2);

/// Recomputes d_i = qem_point(Q_i around c_i) − c_i for every cluster and sets use_offsets (Q
/// metrics; nothing for I and A). O(K) 3×3 eigen-solves on this thread; solved_cluster_state
/// (core/clustering/clustering.h) spreads them over threads.
void update_site_offsets(ClusterState& state);

/// The offset d_c of one cluster (state must carry quadrics; use_offsets is the caller's).
/// O(1); thread-safe for distinct clusters (the parallel loop updates clusters concurrently).
void update_site_offset(ClusterState& state, size_t c);

/// The energy of eq. 12/16 minus its configuration-independent part Σ A_j: Σ_i Σ_j
/// M_j‖γ_j − z_i‖² (iso) or Σ_i Σ_j (γ_j − z_i)ᵀK_j(γ_j − z_i) (aniso), with the current sites.
/// O(K), fixed order.
double state_energy(const ItemData& items, const ClusterState& state);

/// Absolute site position z_i of every cluster (3 per cluster): centroid (I), anisotropic
/// centroid (A), plus the QEM offset when use_offsets. O(K).
std::vector<double> cluster_sites(const ItemData& items, const ClusterState& state);

// ---- The move test, inline for the loops ------------------------------------------------------

/// Energy change of moving one item out of cluster `from` into cluster `to`, as the two
/// positive parts; the move lowers the energy by decrease − increase.
struct MoveDelta {
  double increase = 0, decrease = 0;
};

namespace energy_detail {

inline double dist2(const float* g, const double* c) {
  double dx = g[0] - c[0], dy = g[1] - c[1], dz = g[2] - c[2];
  return dx * dx + dy * dy + dz * dz;
}

// wᵀM⁻¹w for a symmetric positive definite M (xx, xy, xz, yy, yz, zz), through the adjugate.
inline double inverse_quadratic_form(const double* M, const double* w) {
  const double a = M[0], b = M[1], c = M[2], d = M[3], e = M[4], f = M[5];
  const double A00 = d * f - e * e, A01 = c * e - b * f, A02 = b * e - c * d;
  const double A11 = a * f - c * c, A12 = b * c - a * e, A22 = a * d - b * b;
  const double det = a * A00 + b * A01 + c * A02;
  if (!(det > 0)) return 0.0;
  const double q = A00 * w[0] * w[0] + A11 * w[1] * w[1] + A22 * w[2] * w[2] +
                   2.0 * (A01 * w[0] * w[1] + A02 * w[0] * w[2] + A12 * w[1] * w[2]);
  return q / det;
}

// w = m·T·u for the item tensor T (6 floats).
inline void tensor_times(double m, const float* T, const double* u, double* w) {
  w[0] = m * (T[0] * u[0] + T[1] * u[1] + T[2] * u[2]);
  w[1] = m * (T[1] * u[0] + T[3] * u[1] + T[4] * u[2]);
  w[2] = m * (T[2] * u[0] + T[4] * u[1] + T[5] * u[2]);
}

}  // namespace energy_detail

/// Isotropic move (eq. 15, numerically stable form with z = centroid): removing (m, g) from a
/// cluster of mass W and centroid c lowers Σ M‖γ − c‖² by m·W/(W − m)·‖g − c‖²; adding it
/// raises it by m·W/(W + m)·‖g − c‖². Offsets d add m‖d‖² on each side (the site moves with c).
template <bool kOffsets>
inline MoveDelta iso_move_delta(const ItemData& items, const ClusterState& s, uint32_t item, int32_t from, int32_t to) {
  const double m = items.weight[item];
  const float* g = &items.centroid[3 * size_t(item)];
  const ClusterSums& a = s.iso[from];
  const ClusterSums& b = s.iso[to];
  MoveDelta d;
  if (a.weight > m) d.decrease = m * a.weight / (a.weight - m) * energy_detail::dist2(g, a.centroid);
  if (b.weight > 0) d.increase = m * b.weight / (b.weight + m) * energy_detail::dist2(g, b.centroid);
  if constexpr (kOffsets) {
    const double* da = &s.offset[3 * size_t(from)];
    const double* db = &s.offset[3 * size_t(to)];
    d.decrease += m * (da[0] * da[0] + da[1] * da[1] + da[2] * da[2]);
    d.increase += m * (db[0] * db[0] + db[1] * db[1] + db[2] * db[2]);
  }
  return d;
}

/// Anisotropic move (eqs. 16-18) with the site re-optimised on both sides: with u = g − c and
/// w = K_j u, removing the item lowers the cluster energy by uᵀw + wᵀ(K − K_j)⁻¹w, adding it
/// raises it by uᵀw − wᵀ(K + K_j)⁻¹w (K = ΣK of the cluster before the move). For K_j = mI
/// these reduce to the isotropic formulas. Offsets add dᵀK_j d on each side.
template <bool kOffsets>
inline MoveDelta aniso_move_delta(const ItemData& items, const ClusterState& s, uint32_t item, int32_t from, int32_t to) {
  using namespace energy_detail;
  const double m = items.weight[item];
  const float* g = &items.centroid[3 * size_t(item)];
  const float* T = &items.tensor[6 * size_t(item)];
  MoveDelta d;
  const AnisoSums& a = s.aniso[from];
  const AnisoSums& b = s.aniso[to];
  if (s.iso[from].count > 1) {
    double u[3] = {g[0] - a.centroid[0], g[1] - a.centroid[1], g[2] - a.centroid[2]}, w[3];
    tensor_times(m, T, u, w);
    double rest[6];
    for (int k = 0; k < 6; ++k) rest[k] = a.tensor[k] - m * T[k];
    d.decrease = u[0] * w[0] + u[1] * w[1] + u[2] * w[2] + inverse_quadratic_form(rest, w);
  }
  if (s.iso[to].count > 0) {
    double u[3] = {g[0] - b.centroid[0], g[1] - b.centroid[1], g[2] - b.centroid[2]}, w[3];
    tensor_times(m, T, u, w);
    double grown[6];
    for (int k = 0; k < 6; ++k) grown[k] = b.tensor[k] + m * T[k];
    d.increase = std::max(0.0, u[0] * w[0] + u[1] * w[1] + u[2] * w[2] - inverse_quadratic_form(grown, w));
  }
  if constexpr (kOffsets) {
    const double* da = &s.offset[3 * size_t(from)];
    const double* db = &s.offset[3 * size_t(to)];
    double w[3];
    tensor_times(m, T, da, w);
    d.decrease += da[0] * w[0] + da[1] * w[1] + da[2] * w[2];
    tensor_times(m, T, db, w);
    d.increase += db[0] * w[0] + db[1] * w[1] + db[2] * w[2];
  }
  return d;
}

/// Dispatch on the state's metric (the loops call the templates directly).
inline MoveDelta move_delta(const ItemData& items, const ClusterState& s, uint32_t item, int32_t from, int32_t to) {
  if (is_anisotropic(s.metric))
    return s.use_offsets ? aniso_move_delta<true>(items, s, item, from, to) : aniso_move_delta<false>(items, s, item, from, to);
  return s.use_offsets ? iso_move_delta<true>(items, s, item, from, to) : iso_move_delta<false>(items, s, item, from, to);
}

/// A move is taken only when it lowers the energy by more than a relative margin, so rounding
/// cannot make an item ping-pong between two clusters forever (DESIGN.md §3). Returns the gain
/// (> 0) or 0.
inline double move_gain(const MoveDelta& d) {
  constexpr double kRelativeMargin = 1e-10;
  double gain = d.decrease - d.increase;
  return gain > kRelativeMargin * (d.decrease + d.increase) ? gain : 0.0;
}

/// Moves `item` from cluster `from` to `to` in every accumulator of the state (labels are the
/// caller's). O(1); the anisotropic centroids are re-solved (3×3). Not thread-safe for the
/// two clusters involved.
void apply_move(const ItemData& items, ClusterState& s, uint32_t item, int32_t from, int32_t to);

}  // namespace streamcvd
