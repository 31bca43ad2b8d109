#include "streamcvd/streaming/io/png_writer.h"

#include <png.h>

#include <algorithm>
#include <csetjmp>
#include <cstdio>
#include <exception>
#include <memory>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/input_stream.h"
#include "streamcvd/streaming/io/output_file.h"

namespace streamcvd {
namespace {

constexpr uint32_t kMaxSide = 16384;

// libpng reports errors by longjmp. Nothing with a destructor may live in a frame the jump
// crosses, so the callbacks catch C++ exceptions, park them here, and only then call
// png_error(); the caller rethrows after the jump lands.
struct PngState {
  AtomicOutputFile* out = nullptr;
  InputStream* in = nullptr;
  std::exception_ptr exception;
  char message[256] = {0};
};

PngState* state_of(png_structp png) { return static_cast<PngState*>(png_get_error_ptr(png)); }

void on_error(png_structp png, png_const_charp msg) {
  PngState* s = state_of(png);
  snprintf(s->message, sizeof s->message, "%s", msg ? msg : "unknown libpng error");
  png_longjmp(png, 1);
}

void on_warning(png_structp, png_const_charp) {}  // benign (e.g. unknown ancillary chunks)

void on_write(png_structp png, png_bytep data, size_t n) {
  PngState* s = static_cast<PngState*>(png_get_io_ptr(png));
  bool failed = false;
  try {
    s->out->write(data, n);
  } catch (...) {
    s->exception = std::current_exception();
    failed = true;
  }
  if (failed) png_error(png, "write failed");
}

void on_flush(png_structp) {}

void on_read(png_structp png, png_bytep data, size_t n) {
  PngState* s = static_cast<PngState*>(png_get_io_ptr(png));
  bool short_read = false, failed = false;
  try {
    short_read = s->in->read(data, n) != n;
  } catch (...) {
    s->exception = std::current_exception();
    failed = true;
  }
  if (failed) png_error(png, "read failed");
  if (short_read) png_error(png, "unexpected end of file");
}

// All libpng calls of a write, inside one setjmp frame without destructors. Returns false
// after a libpng error (message in the state).
bool encode(png_structp png, png_infop info, const RgbImage* image, int level) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_compression_level(png, level);
  png_set_IHDR(png, info, image->width, image->height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  png_write_info(png, info);
  for (uint32_t y = 0; y < image->height; ++y)
    png_write_row(png, const_cast<png_bytep>(image->pixels.data() + 3 * size_t(y) * image->width));
  png_write_end(png, info);
  return true;
}

// Reads the header and sets the transformations to 8-bit RGB. Returns false after an error.
bool decode_header(png_structp png, png_infop info, png_uint_32* width, png_uint_32* height) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_set_user_limits(png, kMaxSide, kMaxSide);
  png_read_info(png, info);
  int bit_depth = 0, color_type = 0;
  png_get_IHDR(png, info, width, height, &bit_depth, &color_type, nullptr, nullptr, nullptr);
  png_set_expand(png);       // palette → RGB, gray < 8 bit → 8 bit, tRNS → alpha
  png_set_strip_16(png);
  png_set_strip_alpha(png);
  png_set_gray_to_rgb(png);
  png_set_interlace_handling(png);
  png_read_update_info(png, info);
  return png_get_rowbytes(png, info) == 3 * size_t(*width);
}

bool decode_rows(png_structp png, png_infop info, png_bytepp rows) {
  if (setjmp(png_jmpbuf(png))) return false;
  png_read_image(png, rows);
  png_read_end(png, info);
  return true;
}

}  // namespace

void write_png(const std::string& path, const RgbImage& image, int compression_level) {
  if (image.width == 0 || image.height == 0 || image.width > kMaxSide || image.height > kMaxSide ||
      image.pixels.size() != 3 * size_t(image.width) * image.height)
    throw InputError(error_at(path, "png: invalid image " + std::to_string(image.width) + "x" +
                                        std::to_string(image.height) + " with " +
                                        std::to_string(image.pixels.size()) + " bytes"));
  AtomicOutputFile out(path);
  PngState state;
  state.out = &out;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &state, on_error, on_warning);
  if (!png) throw std::bad_alloc();
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_write_struct(&png, nullptr);
    throw std::bad_alloc();
  }
  png_set_write_fn(png, &state, on_write, on_flush);
  const bool ok = encode(png, info, &image, std::clamp(compression_level, 0, 9));
  png_destroy_write_struct(&png, &info);
  if (state.exception) std::rethrow_exception(state.exception);
  if (!ok) throw OutputError(error_at(path, std::string("png: ") + state.message));
  out.commit();
}

RgbImage read_png(const std::string& path) {
  InputStream in(path);
  unsigned char signature[8] = {0};
  if (in.read(signature, 8) != 8 || png_sig_cmp(signature, 0, 8) != 0)
    throw InputError(error_at(path, "png: not a PNG file (bad signature)"));
  PngState state;
  state.in = &in;
  png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &state, on_error, on_warning);
  if (!png) throw std::bad_alloc();
  png_infop info = png_create_info_struct(png);
  if (!info) {
    png_destroy_read_struct(&png, nullptr, nullptr);
    throw std::bad_alloc();
  }
  png_set_read_fn(png, &state, on_read);
  png_set_sig_bytes(png, 8);
  png_uint_32 width = 0, height = 0;
  RgbImage image;
  bool ok = decode_header(png, info, &width, &height);
  std::vector<png_bytep> rows;
  if (ok) {
    image.width = width;
    image.height = height;
    image.pixels.resize(3 * size_t(width) * height);
    rows.resize(height);
    for (uint32_t y = 0; y < height; ++y) rows[y] = image.pixels.data() + 3 * size_t(y) * width;
    ok = decode_rows(png, info, rows.data());
  } else if (!state.message[0]) {
    snprintf(state.message, sizeof state.message, "unsupported pixel layout");
  }
  png_destroy_read_struct(&png, &info, nullptr);
  if (state.exception) std::rethrow_exception(state.exception);
  if (!ok) throw InputError(error_at(path, std::string("png: ") + state.message));
  return image;
}

}  // namespace streamcvd
