// Mesh file writers: PLY (ascii, binary LE), OBJ, OFF, STL (binary), each optionally
// zstd-compressed (".zst"). The readers (read_mesh, read_mesh_stream, format_from_path...)
// are declared in streaming/io/mesh_reader.h, included here so that one include serves both.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/mesh_buffers.h"
#include "streamcvd/core/mesh/mesh_view.h"
#include "streamcvd/streaming/io/mesh_reader.h"

namespace streamcvd {

struct WriteOptions {
  bool ascii = false;       ///< PLY only: ascii instead of binary_little_endian
  int zstd_level = 3;       ///< compression level when the path ends in ".zst"
  std::string comment;      ///< written as a header comment where the format has one
  /// Per-vertex attributes (borrowed; names.size() values per vertex). PLY: vertex properties
  /// after x y z with the same names and types, integer types rounded and clamped to their range.
  /// OBJ: red, green, blue (all three, else none) as "v x y z r g b" in [0, 1] (unsigned integer
  /// types divided by their maximum, floats as they are); other scalars are dropped, as every
  /// attribute is for OFF and STL.
  VertexAttributeRows attributes;
};

/// Which of `attributes` a file of `format` holds, in its column order: all of them for PLY,
/// red, green, blue for OBJ when all three are there, none for OFF and STL. O(attributes).
std::vector<size_t> attributes_written(MeshFormat format, std::span<const VertexAttribute> attributes);

/// Writes `mesh` to `path` in the format its extension names (".ply" binary LE by default,
/// ".obj", ".off", ".stl" binary; + ".zst" to compress). Atomic: writes a temporary file in the
/// destination folder and renames it on success; on any error no file is left behind and
/// OutputError is thrown.
void write_mesh(const std::string& path, const TriangleSoupView& mesh, const WriteOptions& options = {});

}  // namespace streamcvd
