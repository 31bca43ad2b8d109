// A small headless software rasteriser for pictures of meshes (benchmark renders, README figures):
// orthographic camera fitted to the bounding box, z-buffer, flat shading with a headlight, and an
// optional wireframe drawn from each pixel's screen-space distance to the edges of the visible
// triangle, so hidden edges never show through. Writes an RGB buffer; no file I/O (PNG encoding
// is streaming/io/png_writer.h).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

/// An 8-bit RGB image, rows top to bottom, 3 bytes per pixel.
struct RgbImage {
  uint32_t width = 0, height = 0;
  std::vector<uint8_t> pixels;  ///< 3·width·height bytes
  /// Pointer to pixel (x, y), x < width, y < height.
  const uint8_t* at(uint32_t x, uint32_t y) const { return pixels.data() + 3 * (size_t(y) * width + x); }
};

struct RenderOptions {
  uint32_t width = 800, height = 800;  ///< image size in pixels (each 1..16384)
  double azimuth_deg = 30;             ///< camera turned about +y (the usual "up" of scans)
  double elevation_deg = 20;           ///< camera raised above the xz plane
  bool wireframe = false;              ///< draw the visible edges as dark lines
  double edge_width_px = 1.0;          ///< wireframe line width in pixels
  double margin = 0.05;                ///< empty border, fraction of the smaller image side
  std::array<uint8_t, 3> background = {255, 255, 255};
  std::array<uint8_t, 3> surface = {170, 190, 215};  ///< base colour, scaled by the shading
  std::array<uint8_t, 3> edge = {30, 30, 40};
};

/// Renders `mesh` (referenced vertices fitted into the image) with flat, two-sided headlight
/// shading: intensity 0.2 + 0.8·|cos(normal, view)|. Zero-area faces are skipped. Throws
/// InputError for an image side outside 1..16384, a vertex index ≥ V or a non-finite referenced
/// coordinate. An empty mesh gives a background-only image. O(F + pixels covered), single-threaded,
/// deterministic; thread-safe (pure).
RgbImage render_mesh(const TriangleSoupView& mesh, const RenderOptions& options = {});

}  // namespace streamcvd
