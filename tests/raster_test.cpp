// Tests for core/measure/raster.h and streaming/io/png_writer.h (suite Raster).
#include "streamcvd/core/measure/raster.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/io/png_writer.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

namespace fs = std::filesystem;

std::string slurp_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

bool is_background(const RgbImage& im, uint32_t x, uint32_t y, const RenderOptions& o) {
  const uint8_t* p = im.at(x, y);
  return p[0] == o.background[0] && p[1] == o.background[1] && p[2] == o.background[2];
}

uint64_t count_near(const RgbImage& im, std::array<uint8_t, 3> colour, int tolerance) {
  uint64_t n = 0;
  for (size_t i = 0; i < im.pixels.size(); i += 3)
    n += std::abs(im.pixels[i] - colour[0]) <= tolerance && std::abs(im.pixels[i + 1] - colour[1]) <= tolerance &&
         std::abs(im.pixels[i + 2] - colour[2]) <= tolerance;
  return n;
}

// A big triangle at z = 1 in front of a finely tessellated grid at z = 0, seen along −z.
MeshBuffers occluder_over_grid() {
  MeshBuffers m = make_grid(21, 21, 2.0f, 2.0f);  // [0,2]² at z = 0, 800 small triangles
  const uint32_t v = m.vertex_count();
  m.positions.insert(m.positions.end(), {-1.0f, -1.0f, 1.0f, 3.0f, -1.0f, 1.0f, 1.0f, 3.0f, 1.0f});
  m.triangles.insert(m.triangles.end(), {v, v + 1, v + 2});
  return m;
}

TEST(Raster, SphereFillsTheCentreAndFacesTheHeadlight) {
  RenderOptions o;
  o.width = 96;
  o.height = 64;
  const RgbImage im = render_mesh(make_icosphere(3).view(), o);
  ASSERT_EQ(im.width, 96u);
  ASSERT_EQ(im.height, 64u);
  ASSERT_EQ(im.pixels.size(), 3u * 96 * 64);
  EXPECT_FALSE(is_background(im, 48, 32, o));
  EXPECT_TRUE(is_background(im, 0, 0, o));
  EXPECT_TRUE(is_background(im, 95, 63, o));
  EXPECT_TRUE(is_background(im, 5, 32, o));  // the sphere is fitted to the height: left margin is empty
  // At the centre the surface faces the camera: shading ≈ 1, so the pixel ≈ the base colour; near
  // the silhouette it grazes, so it is darker.
  const uint8_t* centre = im.at(48, 32);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(centre[k], o.surface[k], 6);
  EXPECT_LT(im.at(48, 5)[2], centre[2] - 20);
}

TEST(Raster, WireframeDrawsEdgesOnlyWhenAsked) {
  RenderOptions o;
  o.width = o.height = 128;
  const MeshBuffers sphere = make_icosphere(2);
  const RgbImage plain = render_mesh(sphere.view(), o);
  o.wireframe = true;
  const RgbImage wire = render_mesh(sphere.view(), o);
  EXPECT_EQ(count_near(plain, o.edge, 8), 0u);
  EXPECT_GT(count_near(wire, o.edge, 8), 500u);
  // Same coverage: the wireframe only recolours pixels of the surface.
  uint64_t bg_plain = count_near(plain, o.background, 0), bg_wire = count_near(wire, o.background, 0);
  EXPECT_EQ(bg_plain, bg_wire);
}

TEST(Raster, HiddenEdgesDoNotShowThroughAnOccluder) {
  RenderOptions o;
  o.width = o.height = 200;
  o.azimuth_deg = 0;  // eye on +z, looking along −z
  o.elevation_deg = 0;
  o.wireframe = true;
  const MeshBuffers m = occluder_over_grid();
  const RgbImage im = render_mesh(m.view(), o);
  // The occluder spans x∈[−1,3]; the grid [0,2] sits behind its middle. Pixels well inside the
  // occluder (away from its three edges) must all be flat occluder colour: no grid edge.
  const uint8_t* ref = im.at(100, 110);
  int dark = 0;
  for (uint32_t y = 95; y < 125; ++y)
    for (uint32_t x = 85; x < 115; ++x) dark += im.at(x, y)[0] != ref[0];
  EXPECT_EQ(dark, 0);
  // Reversing the face order gives the same picture (the z-buffer decides, not the order).
  MeshBuffers reversed = m;
  const size_t F = m.face_count();
  for (size_t f = 0; f < F; ++f)
    for (int k = 0; k < 3; ++k) reversed.triangles[3 * f + k] = m.triangles[3 * (F - 1 - f) + k];
  const RgbImage im2 = render_mesh(reversed.view(), o);
  uint64_t differing = 0;
  for (size_t i = 0; i < im.pixels.size(); ++i) differing += im.pixels[i] != im2.pixels[i];
  EXPECT_LT(differing, im.pixels.size() / 200);  // only ties along shared edges may differ
}

TEST(Raster, EmptyMeshIsBackgroundAndBadInputThrows) {
  RenderOptions o;
  o.width = 10;
  o.height = 7;
  MeshBuffers empty;
  const RgbImage im = render_mesh(empty.view(), o);
  EXPECT_EQ(count_near(im, o.background, 0), 70u);

  MeshBuffers bad = make_icosphere(0);
  bad.triangles[4] = 999;
  EXPECT_THROW(render_mesh(bad.view(), o), InputError);
  MeshBuffers nan = make_icosphere(0);
  nan.positions[0] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(render_mesh(nan.view(), o), InputError);
  o.width = 0;
  EXPECT_THROW(render_mesh(make_icosphere(0).view(), o), InputError);
  o.width = 20000;
  EXPECT_THROW(render_mesh(make_icosphere(0).view(), o), InputError);
}

TEST(Raster, PngRoundTripIsExact) {
  const fs::path dir = test::temp_dir("png");
  RenderOptions o;
  o.width = 73;  // odd sizes: no row padding assumptions
  o.height = 41;
  o.wireframe = true;
  const RgbImage im = render_mesh(make_torus(24, 12).view(), o);
  const std::string path = (dir / "torus.png").string();
  write_png(path, im);
  std::ifstream f(path, std::ios::binary);
  char sig[8];
  f.read(sig, 8);
  EXPECT_EQ(std::string(sig + 1, 3), "PNG");
  const RgbImage back = read_png(path);
  EXPECT_EQ(back.width, 73u);
  EXPECT_EQ(back.height, 41u);
  EXPECT_EQ(back.pixels, im.pixels);
  fs::remove_all(dir);
}

TEST(Raster, PngErrorsAreReportedWithoutLeftovers) {
  const fs::path dir = test::temp_dir("png_err");
  RenderOptions o;
  o.width = o.height = 32;
  const RgbImage im = render_mesh(make_icosphere(1).view(), o);
  EXPECT_THROW(write_png((dir / "missing" / "x.png").string(), im), OutputError);
  RgbImage wrong = im;
  wrong.pixels.pop_back();
  EXPECT_THROW(write_png((dir / "wrong.png").string(), wrong), InputError);
  EXPECT_FALSE(fs::exists(dir / "wrong.png"));

  const std::string good = (dir / "good.png").string();
  write_png(good, im);
  const auto size = fs::file_size(good);
  // Truncated file, garbage file, missing file: InputError naming the file, never a crash.
  fs::copy_file(good, dir / "cut.png");
  fs::resize_file(dir / "cut.png", size / 2);
  try {
    read_png((dir / "cut.png").string());
    ADD_FAILURE() << "truncated PNG accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cut.png"), std::string::npos) << e.what();
  }
  std::ofstream((dir / "junk.png").string()) << "this is not a png at all";
  EXPECT_THROW(read_png((dir / "junk.png").string()), InputError);
  EXPECT_THROW(read_png((dir / "nope.png").string()), InputError);
  // Corrupt a byte of the image data: the CRC or zlib check must catch it.
  std::string bytes = slurp_file(good);
  bytes[bytes.size() / 2] ^= 0x5A;
  std::ofstream((dir / "flip.png").string(), std::ios::binary) << bytes;
  EXPECT_THROW(read_png((dir / "flip.png").string()), InputError);
  size_t entries = 0;
  for (const auto& e : fs::directory_iterator(dir)) entries += e.path().filename().string()[0] == '.';
  EXPECT_EQ(entries, 0u) << "temporary files left behind";
  fs::remove_all(dir);
}

}  // namespace
}  // namespace streamcvd
