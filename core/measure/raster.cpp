#include "streamcvd/core/measure/raster.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "streamcvd/core/mesh/errors.h"

namespace streamcvd {
namespace {

using Vec3 = std::array<double, 3>;

constexpr uint32_t kMaxSide = 16384;

double dot(const Vec3& a, const Vec3& b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

// Orthonormal camera frame: `view` points from the surface towards the eye (the headlight
// direction), `right` and `up` span the image plane, `up` leaning towards +y.
struct Camera {
  Vec3 view, right, up;
};

Camera make_camera(double azimuth_deg, double elevation_deg) {
  const double az = azimuth_deg * M_PI / 180.0, el = elevation_deg * M_PI / 180.0;
  Camera c;
  c.view = {std::cos(el) * std::sin(az), std::sin(el), std::cos(el) * std::cos(az)};
  c.right = {std::cos(az), 0.0, -std::sin(az)};  // ⟂ view for every elevation
  c.up = cross(c.view, c.right);
  return c;
}

// Screen position (pixels, x right, y down) and depth (larger = nearer) of each vertex.
struct Projected {
  std::vector<double> x, y, z;
  std::vector<uint8_t> used;
};

Projected project(const TriangleSoupView& mesh, const Camera& cam, const RenderOptions& opt) {
  const uint32_t V = mesh.vertex_count();
  Projected p;
  p.used.assign(V, 0);
  for (uint64_t i = 0; i < 3 * mesh.face_count(); ++i) {
    const uint32_t v = mesh.triangles[i];
    if (v >= V)
      throw InputError("render: face " + std::to_string(i / 3) + " uses vertex " + std::to_string(v) + " of " +
                       std::to_string(V));
    p.used[v] = 1;
  }
  p.x.assign(V, 0);
  p.y.assign(V, 0);
  p.z.assign(V, 0);
  double lo[2] = {INFINITY, INFINITY}, hi[2] = {-INFINITY, -INFINITY};
  for (uint32_t v = 0; v < V; ++v) {
    if (!p.used[v]) continue;
    const Vec3 q = {mesh.positions[3 * size_t(v)], mesh.positions[3 * size_t(v) + 1], mesh.positions[3 * size_t(v) + 2]};
    if (!std::isfinite(q[0]) || !std::isfinite(q[1]) || !std::isfinite(q[2]))
      throw InputError("render: vertex " + std::to_string(v) + " has a non-finite coordinate");
    p.x[v] = dot(q, cam.right);
    p.y[v] = dot(q, cam.up);
    p.z[v] = dot(q, cam.view);
    lo[0] = std::min(lo[0], p.x[v]);
    hi[0] = std::max(hi[0], p.x[v]);
    lo[1] = std::min(lo[1], p.y[v]);
    hi[1] = std::max(hi[1], p.y[v]);
  }
  if (!(lo[0] <= hi[0])) return p;  // no referenced vertex
  // Fit the projected extent into the image minus the margin, keeping the aspect ratio.
  const double border = opt.margin * std::min(opt.width, opt.height);
  const double avail_w = std::max(1.0, opt.width - 2 * border), avail_h = std::max(1.0, opt.height - 2 * border);
  const double extent_w = std::max(hi[0] - lo[0], 1e-30), extent_h = std::max(hi[1] - lo[1], 1e-30);
  const double scale = std::min(avail_w / extent_w, avail_h / extent_h);
  const double cx = 0.5 * (lo[0] + hi[0]), cy = 0.5 * (lo[1] + hi[1]);
  for (uint32_t v = 0; v < V; ++v) {
    if (!p.used[v]) continue;
    p.x[v] = 0.5 * opt.width + (p.x[v] - cx) * scale;
    p.y[v] = 0.5 * opt.height - (p.y[v] - cy) * scale;
  }
  return p;
}

}  // namespace

RgbImage render_mesh(const TriangleSoupView& mesh, const RenderOptions& opt) {
  if (opt.width < 1 || opt.width > kMaxSide || opt.height < 1 || opt.height > kMaxSide)
    throw InputError("render: image size " + std::to_string(opt.width) + "x" + std::to_string(opt.height) +
                     " outside 1..16384");
  RgbImage image;
  image.width = opt.width;
  image.height = opt.height;
  image.pixels.resize(3 * size_t(opt.width) * opt.height);
  for (size_t i = 0; i < image.pixels.size(); i += 3)
    for (int k = 0; k < 3; ++k) image.pixels[i + k] = opt.background[k];

  const Camera cam = make_camera(opt.azimuth_deg, opt.elevation_deg);
  const Projected p = project(mesh, cam, opt);
  std::vector<float> depth(size_t(opt.width) * opt.height, -std::numeric_limits<float>::infinity());
  const double half_line = 0.5 * opt.edge_width_px;

  for (uint64_t f = 0; f < mesh.face_count(); ++f) {
    const uint32_t i0 = mesh.triangles[3 * f], i1 = mesh.triangles[3 * f + 1], i2 = mesh.triangles[3 * f + 2];
    const double x0 = p.x[i0], y0 = p.y[i0], x1 = p.x[i1], y1 = p.y[i1], x2 = p.x[i2], y2 = p.y[i2];
    const double area2 = (x1 - x0) * (y2 - y0) - (x2 - x0) * (y1 - y0);  // twice the signed screen area
    if (std::abs(area2) < 1e-12) continue;
    // Flat two-sided headlight shading from the 3D face normal.
    const auto corner = [&](uint32_t v) {
      return Vec3{mesh.positions[3 * size_t(v)], mesh.positions[3 * size_t(v) + 1], mesh.positions[3 * size_t(v) + 2]};
    };
    const Vec3 a = corner(i0), b = corner(i1), c = corner(i2);
    const Vec3 n = cross({b[0] - a[0], b[1] - a[1], b[2] - a[2]}, {c[0] - a[0], c[1] - a[1], c[2] - a[2]});
    const double n_len = std::sqrt(dot(n, n));
    if (!(n_len > 0)) continue;
    const double shade = 0.2 + 0.8 * std::abs(dot(n, cam.view)) / n_len;
    uint8_t face_rgb[3];
    for (int k = 0; k < 3; ++k) face_rgb[k] = uint8_t(std::lround(opt.surface[k] * shade));
    // Pixel distance to edge k (opposite corner k) = λ_k · |2·area| / |edge k|.
    const double inv_len[3] = {1.0 / std::hypot(x2 - x1, y2 - y1), 1.0 / std::hypot(x0 - x2, y0 - y2),
                               1.0 / std::hypot(x1 - x0, y1 - y0)};

    const int px_lo = std::max(0, int(std::floor(std::min({x0, x1, x2}))));
    const int px_hi = std::min(int(opt.width) - 1, int(std::ceil(std::max({x0, x1, x2}))));
    const int py_lo = std::max(0, int(std::floor(std::min({y0, y1, y2}))));
    const int py_hi = std::min(int(opt.height) - 1, int(std::ceil(std::max({y0, y1, y2}))));
    const double inv_area2 = 1.0 / area2;
    for (int py = py_lo; py <= py_hi; ++py) {
      const double sy = py + 0.5;
      for (int px = px_lo; px <= px_hi; ++px) {
        const double sx = px + 0.5;
        const double l0 = ((x1 - sx) * (y2 - sy) - (x2 - sx) * (y1 - sy)) * inv_area2;
        const double l1 = ((x2 - sx) * (y0 - sy) - (x0 - sx) * (y2 - sy)) * inv_area2;
        const double l2 = 1.0 - l0 - l1;
        constexpr double kTol = -1e-9;  // pixel centres exactly on a shared edge belong to both faces
        if (l0 < kTol || l1 < kTol || l2 < kTol) continue;
        const float z = float(l0 * p.z[i0] + l1 * p.z[i1] + l2 * p.z[i2]);
        float& zb = depth[size_t(py) * opt.width + px];
        if (!(z > zb)) continue;
        zb = z;
        uint8_t* out = image.pixels.data() + 3 * (size_t(py) * opt.width + px);
        double alpha = 0;
        if (opt.wireframe) {
          const double d = std::abs(area2) * std::min({l0 * inv_len[0], l1 * inv_len[1], l2 * inv_len[2]});
          alpha = std::clamp(half_line + 0.5 - d, 0.0, 1.0);  // ~1 px of linear falloff: cheap anti-aliasing
        }
        for (int k = 0; k < 3; ++k) out[k] = uint8_t(std::lround(face_rgb[k] * (1 - alpha) + opt.edge[k] * alpha));
      }
    }
  }
  return image;
}

}  // namespace streamcvd
