// Tests for core/fields/metric_field.h (suite MetricField): gradation density (eq. 20) with its clamp,
// anisotropic tensors (eqs. 21-22) with the isotropic blend on planes and cylinders, per-vertex
// quadrics and the truncated QEM solve on planes, creases and corners, degenerate input.
#include "streamcvd/core/fields/metric_field.h"
#include "streamcvd/core/clustering/item_data.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <random>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/store/store.h"

namespace streamcvd {
namespace {

std::vector<float> to_vector(const LargeArray<float>& a) { return {a.begin(), a.end()}; }

using V3 = std::array<double, 3>;

void append(MeshBuffers& a, const MeshBuffers& b, double dx, double dy, double dz) {
  const uint32_t offset = a.vertex_count();
  for (size_t i = 0; i < b.positions.size(); i += 3)
    a.positions.insert(a.positions.end(),
                       {float(b.positions[i] + dx), float(b.positions[i + 1] + dy), float(b.positions[i + 2] + dz)});
  for (uint32_t i : b.triangles) a.triangles.push_back(i + offset);
}

// Unit sphere (level 4) above a 4×4 plane at z = 0: the plane holds most of the area.
MeshBuffers sphere_and_plane() {
  MeshBuffers m = make_grid(41, 41, 4.0f, 4.0f);
  append(m, make_icosphere(4, 1.0f), 2, 2, 3);
  return m;
}

// Open cylinder of radius r around the z axis, alternate rings turned by half a segment.
MeshBuffers make_cylinder(int rows, int segments, double r, double dz) {
  MeshBuffers m;
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < segments; ++j) {
      const double a = 2 * M_PI * (j + 0.5 * (i % 2)) / segments;
      m.positions.insert(m.positions.end(), {float(r * std::cos(a)), float(r * std::sin(a)), float(i * dz)});
    }
  auto id = [&](int i, int j) { return uint32_t(i * segments + (j % segments)); };
  for (int i = 0; i + 1 < rows; ++i)
    for (int j = 0; j < segments; ++j) {
      if (i % 2 == 0) {
        m.triangles.insert(m.triangles.end(), {id(i, j), id(i, j + 1), id(i + 1, j)});
        m.triangles.insert(m.triangles.end(), {id(i + 1, j), id(i, j + 1), id(i + 1, j + 1)});
      } else {
        m.triangles.insert(m.triangles.end(), {id(i, j), id(i, j + 1), id(i + 1, j + 1)});
        m.triangles.insert(m.triangles.end(), {id(i, j), id(i + 1, j + 1), id(i + 1, j)});
      }
    }
  return m;
}

MeshBuffers cube(double side, double x0, double y0, double z0) {
  MeshBuffers m;
  for (int i = 0; i < 8; ++i)
    m.positions.insert(m.positions.end(), {float(x0 + side * (i & 1)), float(y0 + side * ((i >> 1) & 1)),
                                           float(z0 + side * ((i >> 2) & 1))});
  m.triangles = {0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4,
                 2, 6, 3, 3, 6, 7, 0, 4, 2, 2, 4, 6, 1, 3, 5, 3, 7, 5};
  return m;
}

MeshStore store_of(const MeshBuffers& m) {
  StoreBuildOptions o;
  o.hilbert_order = false;  // keep input ids so the tests can address vertices
  return MeshStore::build(m.view(), o);
}

// Exact curvature of a cylinder of radius r around z: k1 = 1/r around, k2 = 0 along the axis.
Curvature cylinder_curvature(const MeshView& view, double r) {
  Curvature c;
  const uint32_t V = view.vertex_count();
  c.k1.assign(V, float(1 / r));
  c.k2.assign(V, 0.0f);
  c.fallback.assign(V, 0);
  for (uint32_t v = 0; v < V; ++v) {
    const double x = view.positions[3 * v], y = view.positions[3 * v + 1], n = std::hypot(x, y);
    c.d1.insert(c.d1.end(), {float(-y / n), float(x / n), 0.0f});
    c.d2.insert(c.d2.end(), {0.0f, 0.0f, 1.0f});
  }
  return c;
}

Eigen::Matrix3d tensor(const std::vector<float>& t, uint32_t v) {
  const float* k = &t[6 * size_t(v)];
  Eigen::Matrix3d M;
  M << k[0], k[1], k[2], k[1], k[3], k[4], k[2], k[4], k[5];
  return M;
}

std::vector<double> areas(const MeshView& view) {
  std::vector<double> a(view.vertex_count(), 0);
  for (uint64_t f = 0; f < view.face_count(); ++f) {
    Eigen::Vector3d p[3];
    for (int k = 0; k < 3; ++k)
      for (int c = 0; c < 3; ++c) p[k][c] = view.positions[3 * size_t(view.triangles[3 * f + k]) + c];
    const double area = (p[1] - p[0]).cross(p[2] - p[0]).norm() / 2;
    for (int k = 0; k < 3; ++k) a[view.triangles[3 * f + k]] += area / 3;
  }
  return a;
}

double area_weighted_mean(const MeshView& view, const std::vector<float>& value) {
  const std::vector<double> a = areas(view);
  double sw = 0, s = 0;
  for (size_t v = 0; v < a.size(); ++v) {
    sw += a[v];
    s += a[v] * value[v];
  }
  return s / sw;
}

TEST(MetricField, GradationGammaZeroIsExactlyOnes) {
  const MeshStore store = store_of(sphere_and_plane());
  const Curvature k = compute_curvature(store.view());
  for (float d : gradation_density(store.view(), k, 0.0)) ASSERT_EQ(d, 1.0f);
}

TEST(MetricField, GradationIsHigherOnTheCurvedPart) {
  const MeshBuffers m = sphere_and_plane();
  const uint32_t plane_vertices = 41 * 41;
  const MeshStore store = store_of(m);
  const Curvature k = compute_curvature(store.view());
  const std::vector<float> d = gradation_density(store.view(), k, 1.5);
  double plane = 0, sphere = 0;
  for (uint32_t v = 0; v < d.size(); ++v) {
    ASSERT_TRUE(std::isfinite(d[v]) && d[v] > 0) << v;
    (v < plane_vertices ? plane : sphere) += d[v];
  }
  plane /= plane_vertices;
  sphere /= double(d.size() - plane_vertices);
  const CurvatureRange r = curvature_range(store.view(), k);
  std::printf("[ figures  ] sphere+plane γ=1.5: mean multiplier sphere %.3g, plane %.3g; s %.3g lo %.3g hi %.3g\n",
              sphere, plane, r.reference, r.low, r.high);
  EXPECT_GT(sphere, 5 * plane);
  EXPECT_NEAR(area_weighted_mean(store.view(), d), 1.0, 1e-4);
  const auto [lo, hi] = std::minmax_element(d.begin(), d.end());
  EXPECT_LE(*hi / *lo, std::pow(r.high / r.low, 1.5) * (1 + 1e-5));
  EXPECT_LE(*hi / *lo, std::pow(100.0, 1.5) * (1 + 1e-5));
  // Scale invariance: the same shape 1000× larger has the same multipliers.
  MeshBuffers big = m;
  for (float& x : big.positions) x *= 1000;
  const MeshStore big_store = store_of(big);
  const std::vector<float> db = gradation_density(big_store.view(), compute_curvature(big_store.view()), 1.5);
  for (uint32_t v = 0; v < d.size(); ++v) ASSERT_NEAR(db[v], d[v], 1e-3 * d[v]) << v;
}

TEST(MetricField, GradationSpikeIsClamped) {
  const MeshStore store = store_of(make_icosphere(4, 1.0f));
  const Curvature k = compute_curvature(store.view());
  const double gamma = 1.5;
  auto median_of = [](std::vector<float> d) {
    std::sort(d.begin(), d.end());
    return double(d[d.size() / 2]);
  };
  {  // One absurd estimate: the rest keep their weight (unclamped it would take ~all of the mean).
    Curvature spiked = k;
    spiked.k1[17] = 1e6f;
    const std::vector<float> d = gradation_density(store.view(), spiked, gamma);
    const double median = median_of(d);
    EXPECT_NEAR(median, 1.0, 0.05);
    EXPECT_GE(d[17], median * 0.999);
    EXPECT_LE(d[17], median * 1.1);  // cut to P98 ≈ the sphere's own curvature
  }
  // Spikes on 5% of the vertices (beyond P98): cut to max_ratio · s exactly.
  Curvature spiked = k;
  for (uint32_t v = 0; v < spiked.vertex_count(); v += 20) spiked.k1[v] = 1e6f;
  for (double max_ratio : {10.0, 2.0}) {
    MetricFieldOptions o;
    o.max_ratio = max_ratio;
    const std::vector<float> d = gradation_density(store.view(), spiked, gamma, o);
    const double median = median_of(d);
    for (uint32_t v = 0; v < spiked.vertex_count(); v += 20)
      ASSERT_NEAR(d[v] / median, std::pow(max_ratio, gamma), 0.02 * std::pow(max_ratio, gamma)) << v;
    // The unspiked 95% keep at least 1 / (0.95 + 0.05 · max_ratio^γ) of their weight.
    EXPECT_GT(median, 0.98 / (0.95 + 0.05 * std::pow(max_ratio, gamma)));
    const auto [lo, hi] = std::minmax_element(d.begin(), d.end());
    EXPECT_LE(*hi / *lo, std::pow(max_ratio / o.min_ratio, gamma));
  }
}

TEST(MetricField, GradationOnFlatOrUnknownCurvatureIsUniform) {
  const MeshStore store = store_of(make_grid(20, 20));
  const Curvature k = compute_curvature(store.view());
  for (float d : gradation_density(store.view(), k, 1.5)) ASSERT_EQ(d, 1.0f);
  // A tilted plane far from the origin: the fit sees float rounding only, still flat.
  MeshBuffers tilted = make_grid(30, 30);
  for (size_t i = 0; i < tilted.positions.size(); i += 3) {
    tilted.positions[i] = tilted.positions[i] * 0.8f + 100;
    tilted.positions[i + 2] = 0.6f * (tilted.positions[i] - 100) / 0.8f + 0.37f * tilted.positions[i + 1] + 30;
  }
  const MeshStore tilted_store = store_of(tilted);
  const Curvature tk = compute_curvature(tilted_store.view());
  double max_k = 0;
  for (float x : tk.k1) max_k = std::max(max_k, double(std::abs(x)));
  std::printf("[ figures  ] tilted plane: max |k1| %.3g\n", max_k);
  for (float d : gradation_density(tilted_store.view(), tk, 1.5)) ASSERT_EQ(d, 1.0f);
  Curvature unknown = compute_curvature(store_of(make_icosphere(2)).view());
  std::fill(unknown.fallback.begin(), unknown.fallback.end(), 1);
  for (float d : gradation_density(store_of(make_icosphere(2)).view(), unknown, 1.5)) ASSERT_EQ(d, 1.0f);
  EXPECT_THROW(gradation_density(store.view(), k, 20.0), InputError);
  EXPECT_THROW(gradation_density(store.view(), k, std::nan("")), InputError);
  Curvature short_k = k;
  short_k.k1.pop_back();
  EXPECT_THROW(gradation_density(store.view(), short_k, 1.0), InputError);
  MetricFieldOptions bad;
  bad.min_ratio = 0;
  EXPECT_THROW(gradation_density(store.view(), k, 1.0, bad), InputError);
}

TEST(MetricField, TensorsArePositiveDefiniteOnPlanes) {
  {  // all flat: the identity
    const MeshStore store = store_of(make_grid(20, 20));
    const AnisotropicField f = anisotropic_field(store.view(), compute_curvature(store.view()));
    for (uint32_t v = 0; v < store.view().vertex_count(); ++v)
      ASSERT_TRUE(tensor(f.tensors, v).isApprox(Eigen::Matrix3d::Identity(), 1e-6)) << v;
  }
  // A plane next to a sphere: isotropic κ0/N on the plane, positive definite everywhere.
  const MeshStore store = store_of(sphere_and_plane());
  const AnisotropicField f = anisotropic_field(store.view(), compute_curvature(store.view()));
  EXPECT_GT(f.kappa0, 0);
  const double l0 = f.kappa0 / f.scale;
  for (uint32_t v = 0; v < store.view().vertex_count(); ++v) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(tensor(f.tensors, v));
    ASSERT_GT(eig.eigenvalues()[0], 0.99 * l0) << v;
    ASSERT_LE(eig.eigenvalues()[2] / eig.eigenvalues()[0], f.max_ratio * 1.001) << v;
    if (v == 20 * 41 + 20) {  // plane centre
      EXPECT_NEAR(eig.eigenvalues()[0], l0, 1e-3 * l0);
      EXPECT_NEAR(eig.eigenvalues()[2], l0, 1e-3 * l0);
    }
  }
}

TEST(MetricField, CylinderTensorRatioFollowsTheBlend) {
  const double r = 0.5;
  const MeshStore store = store_of(make_cylinder(30, 48, r, 2 * M_PI * r / 48 * 0.866));
  const MeshView view = store.view();
  const Curvature k = cylinder_curvature(view, r);
  struct Case {
    double blend, max_anisotropy, ratio;
  };
  for (const Case c : {Case{0.25, 100, 9}, Case{0.5, 100, 5}, Case{0.25, 4, 4}}) {
    MetricFieldOptions o;
    o.isotropic_blend = c.blend;
    o.max_anisotropy = c.max_anisotropy;
    const AnisotropicField f = anisotropic_field(view, k, o);
    EXPECT_NEAR(f.max_ratio, c.ratio, 1e-9);
    std::vector<float> half_trace(view.vertex_count());
    for (uint32_t v = 0; v < view.vertex_count(); ++v) {
      const Eigen::Matrix3d K = tensor(f.tensors, v);
      const Eigen::Vector3d axis(0, 0, 1);
      const Eigen::Vector3d around(k.d1[3 * v], k.d1[3 * v + 1], k.d1[3 * v + 2]);
      const Eigen::Vector3d normal = around.cross(axis);
      const double l_around = around.dot(K * around), l_axis = axis.dot(K * axis), l_normal = normal.dot(K * normal);
      ASSERT_NEAR(l_around / l_axis, c.ratio, 1e-4 * c.ratio) << v;
      ASSERT_NEAR(l_normal, l_axis, 1e-5) << v;  // the normal gets the blend κ0 only
      ASSERT_NEAR(f.density[v], std::sqrt(l_around * l_axis), 1e-5) << v;
      half_trace[v] = float(0.5 * (l_around + l_axis));
    }
    EXPECT_NEAR(area_weighted_mean(view, half_trace), 1.0, 1e-5);  // the normalisation N
  }
}

TEST(MetricField, CylinderTensorFromMeasuredCurvature) {
  const double r = 0.5;
  const MeshStore store = store_of(make_cylinder(40, 64, r, 2 * M_PI * r / 64 * 0.866));
  const MeshView view = store.view();
  const AnisotropicField f = anisotropic_field(view, compute_curvature(view));
  int checked = 0;
  for (uint32_t v = 8 * 64; v < 32 * 64; ++v) {  // away from the open ends
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(tensor(f.tensors, v));
    const double ratio = eig.eigenvalues()[2] / eig.eigenvalues()[1];
    ASSERT_NEAR(ratio, 9.0, 0.9) << v;
    // The middle eigenvalue (tangential minimum) is along the axis, the largest around it.
    ASSERT_GT(std::abs(eig.eigenvectors().col(1).z()), 0.95) << v;
    ASSERT_LT(std::abs(eig.eigenvectors().col(2).z()), 0.2) << v;
    ++checked;
  }
  EXPECT_EQ(checked, 24 * 64);
}

// The per-vertex quadrics of the items (IQ/AQ), in the items' frame (the bounding box centre).
LargeArray<float> quadrics_of(const MeshView& view, const double expected_origin[3]) {
  ItemData items = compute_item_data(view, {}, ram_storage(), ItemQuadrics::per_vertex);
  for (int c = 0; c < 3; ++c) EXPECT_NEAR(items.origin[c], expected_origin[c], 1e-5) << c;
  return std::move(items.quadric);
}

TEST(MetricField, QuadricOfAFlatPatchProjectsTheCentroid) {
  MeshBuffers m = make_grid(11, 11, 2.0f, 2.0f);
  // Tilt the plane: z = 0.3 x + 0.2 y + 5, far from the origin to exercise the relative frame.
  for (size_t i = 0; i < m.positions.size(); i += 3) {
    m.positions[i] += 100;
    m.positions[i + 2] = float(0.3 * (m.positions[i] - 100) + 0.2 * m.positions[i + 1] + 5);
  }
  const MeshStore store = store_of(m);
  const double origin[3] = {101, 1, 5.5};  // the bounding box centre lies on the plane
  const LargeArray<float> q = quadrics_of(store.view(), origin);
  double sum[10] = {};
  for (uint32_t v = 0; v < store.view().vertex_count(); ++v)
    for (int k = 0; k < 10; ++k) sum[k] += q[10 * v + k];
  const Eigen::Vector3d n = Eigen::Vector3d(-0.3, -0.2, 1).normalized();
  EXPECT_NEAR(sum[0] + sum[3] + sum[5], 4.0 * std::sqrt(1 + 0.09 + 0.04), 1e-3);  // trace = area
  // A centroid off the plane and off the patch centre: moved along n only, onto the plane.
  const double c[3] = {0.4, -0.3, 0.25};
  double x[3];
  EXPECT_EQ(qem_point(sum, sum + 6, c, 1e-3, x), 1);
  const Eigen::Vector3d cv(c[0], c[1], c[2]), xv(x[0], x[1], x[2]);
  const Eigen::Vector3d expected = cv - n * n.dot(cv);
  EXPECT_LT((xv - expected).norm(), 1e-5);
  EXPECT_NEAR(quadric_value(sum, x), 0.0, 1e-6);
  EXPECT_GT(quadric_value(sum, c), 1e-3);
  // Nearly flat (1e-5 bumps): the tangential eigenvalues are ~1e-10 of λmax; inverting them
  // would throw the point far along the plane, truncating them keeps it at the projection.
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> bump(-1e-5f, 1e-5f);
  for (size_t i = 2; i < m.positions.size(); i += 3) m.positions[i] += bump(rng);
  const MeshStore bumpy = store_of(m);
  const LargeArray<float> qb = compute_item_data(bumpy.view(), {}, ram_storage(), ItemQuadrics::per_vertex).quadric;
  double sb[10] = {};
  for (uint32_t v = 0; v < bumpy.view().vertex_count(); ++v)
    for (int k = 0; k < 10; ++k) sb[k] += qb[10 * v + k];
  EXPECT_EQ(qem_point(sb, sb + 6, c, 1e-3, x), 1);
  EXPECT_LT((Eigen::Vector3d(x[0], x[1], x[2]) - expected).norm(), 1e-4);
}

TEST(MetricField, QuadricOfACubeCornerAndCrease) {
  const MeshStore store = store_of(cube(2.0, 1000, -500, 7));
  const double origin[3] = {1001, -499, 8};  // the cube centre
  const LargeArray<float> q = quadrics_of(store.view(), origin);
  // Corner 0 = (1000, -500, 7) → (-1, -1, -1) relative: three planes meet there.
  double Q[10];
  for (int k = 0; k < 10; ++k) Q[k] = q[k];
  const double c[3] = {-0.5, -0.7, -0.4};
  double x[3];
  EXPECT_EQ(qem_point(Q, Q + 6, c, 1e-3, x), 3);
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(x[i], -1.0, 1e-5);
  // Only the two faces x = -1 and y = -1 around corner 0: a crease along z, the solve keeps
  // the centroid's z and moves x, y onto the edge.
  double crease[10] = {};
  for (uint64_t f = 0; f < store.view().face_count(); ++f) {
    const uint32_t* t = &store.view().triangles[3 * f];
    Eigen::Vector3d p[3];
    for (int k = 0; k < 3; ++k)
      for (int j = 0; j < 3; ++j) p[k][j] = store.view().positions[3 * t[k] + j] - origin[j];
    const Eigen::Vector3d n = (p[1] - p[0]).cross(p[2] - p[0]).normalized();
    const bool face_x = std::abs(n.x()) > 0.5 && p[0].x() < 0, face_y = std::abs(n.y()) > 0.5 && p[0].y() < 0;
    if (!face_x && !face_y) continue;
    const double d = -n.dot(p[0]), w = (p[1] - p[0]).cross(p[2] - p[0]).norm() / 6;
    const double add[10] = {n.x() * n.x(), n.x() * n.y(), n.x() * n.z(), n.y() * n.y(), n.y() * n.z(),
                            n.z() * n.z(), d * n.x(), d * n.y(), d * n.z(), d * d};
    for (int k = 0; k < 10; ++k) crease[k] += w * add[k];
  }
  EXPECT_EQ(qem_point(crease, crease + 6, c, 1e-3, x), 2);
  EXPECT_NEAR(x[0], -1.0, 1e-9);
  EXPECT_NEAR(x[1], -1.0, 1e-9);
  EXPECT_NEAR(x[2], c[2], 1e-9);
}

TEST(MetricField, QemPointMatchesADenseSolve) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  for (int trial = 0; trial < 1000; ++trial) {
    Eigen::Matrix3d B;
    for (int i = 0; i < 9; ++i) B(i / 3, i % 3) = u(rng);
    const Eigen::Matrix3d M = B * B.transpose() + 0.1 * Eigen::Matrix3d::Identity();
    const double A[6] = {M(0, 0), M(0, 1), M(0, 2), M(1, 1), M(1, 2), M(2, 2)};
    const double b[3] = {u(rng), u(rng), u(rng)}, c[3] = {u(rng), u(rng), u(rng)};
    double x[3];
    ASSERT_EQ(qem_point(A, b, c, 1e-6, x), 3);
    const Eigen::Vector3d ref = M.ldlt().solve(-Eigen::Vector3d(b[0], b[1], b[2]));
    for (int i = 0; i < 3; ++i) ASSERT_NEAR(x[i], ref[i], 1e-8 * (1 + ref.norm())) << trial;
  }
}

TEST(MetricField, DegenerateInputStaysFinite) {
  MeshBuffers m = make_grid(10, 10);
  for (uint32_t v = 10; v < 20; ++v) m.positions[3 * v + 1] = m.positions[3 * (v - 10) + 1];  // collapsed row
  m.triangles.insert(m.triangles.end(), {0, 0, 1, 5, 6, 5});                                  // repeated indices
  m.positions.insert(m.positions.end(), {7, 7, 7, -3, 2, 1});                                 // two isolated vertices
  append(m, make_icosphere(2, 0.5f), 3, 0, 0);
  const MeshStore store = store_of(m);
  const MeshView view = store.view();
  const Curvature k = compute_curvature(view);
  for (double gamma : {-2.0, 1.5, 8.0})
    for (float d : gradation_density(view, k, gamma)) ASSERT_TRUE(std::isfinite(d) && d > 0) << gamma;
  const AnisotropicField f = anisotropic_field(view, k);
  for (uint32_t v = 0; v < view.vertex_count(); ++v) {
    const Eigen::Matrix3d K = tensor(f.tensors, v);
    ASSERT_TRUE(K.allFinite() && std::isfinite(f.density[v])) << v;
    ASSERT_GT(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(K).eigenvalues()[0], 0) << v;
  }
  Curvature broken = k;  // directions unusable: isotropic fallback tensor
  std::fill(broken.d1.begin(), broken.d1.end(), 0.0f);
  const AnisotropicField g = anisotropic_field(view, broken);
  for (uint32_t v = 0; v < view.vertex_count(); ++v) {
    const Eigen::Matrix3d K = tensor(g.tensors, v);
    ASSERT_TRUE(K.allFinite() && K.isDiagonal() && K(0, 0) > 0) << v;
  }
  const LargeArray<float> q = compute_item_data(view, {}, ram_storage(), ItemQuadrics::per_vertex).quadric;
  for (float x : q) ASSERT_TRUE(std::isfinite(x));
  for (uint32_t v : {100u, 101u}) {  // the isolated vertices
    for (int j = 0; j < 10; ++j) ASSERT_EQ(q[10 * v + j], 0.0f);
    double Q[10], x[3];
    const double c[3] = {7, 7, 7};
    for (int j = 0; j < 10; ++j) Q[j] = q[10 * v + j];
    ASSERT_EQ(qem_point(Q, Q + 6, c, 1e-3, x), 0);
    ASSERT_EQ(x[0], 7.0);
  }
  const double nan_A[6] = {std::nan(""), 0, 0, 1, 0, 1}, b[3] = {0, 0, 0}, c[3] = {1, 2, 3};
  double x[3];
  EXPECT_EQ(qem_point(nan_A, b, c, 1e-3, x), 0);
  EXPECT_EQ(x[1], 2.0);
  // Empty mesh.
  const MeshView empty;
  EXPECT_TRUE(gradation_density(empty, Curvature{}, 1.0).empty());
  EXPECT_TRUE(anisotropic_field(empty, Curvature{}).tensors.empty());
  EXPECT_TRUE(compute_item_data(empty, {}, ram_storage(), ItemQuadrics::per_vertex).quadric.empty());
}

TEST(MetricField, IndependentOfThreadCount) {
  const MeshStore store = store_of(sphere_and_plane());
  const Curvature k = compute_curvature(store.view());
  std::vector<float> d1, t1, q1, d4, t4, q4;
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
    d1 = gradation_density(store.view(), k, 1.5);
    t1 = anisotropic_tensors(store.view(), k);
    q1 = to_vector(compute_item_data(store.view(), {}, ram_storage(), ItemQuadrics::per_vertex).quadric);
  }
  {
    tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 4);
    d4 = gradation_density(store.view(), k, 1.5);
    t4 = anisotropic_tensors(store.view(), k);
    q4 = to_vector(compute_item_data(store.view(), {}, ram_storage(), ItemQuadrics::per_vertex).quadric);
  }
  EXPECT_EQ(d1, d4);
  EXPECT_EQ(t1, t4);
  EXPECT_EQ(q1, q4);
}

}  // namespace
}  // namespace streamcvd
