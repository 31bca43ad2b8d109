// PNG files of RGB images (renders from core/measure/raster.h) through libpng. Writing is atomic
// (streaming/io/output_file.h): a failed or interrupted write leaves no partial file.
#pragma once

#include <string>

#include "streamcvd/core/measure/raster.h"

namespace streamcvd {

/// Writes `image` (8-bit RGB, non-interlaced) to `path`, zlib level `compression_level` (0-9;
/// 9 keeps wireframe renders small). Throws OutputError "<path>: <problem>" when the file cannot
/// be written, InputError when the image is empty or its pixel buffer has the wrong size.
/// O(pixels); thread-safe for distinct paths.
void write_png(const std::string& path, const RgbImage& image, int compression_level = 9);

/// Reads a PNG file of any colour type / bit depth as 8-bit RGB (alpha dropped, gray expanded,
/// 16-bit stripped); images larger than 16384 pixels a side are refused. For tests and tools.
/// Throws InputError "<path>: png: <problem>" on a missing, malformed or truncated file.
/// O(file size + pixels); thread-safe.
RgbImage read_png(const std::string& path);

}  // namespace streamcvd
