// Mesh file writers: PLY (ascii, binary LE), OBJ, OFF, STL (binary), each optionally
// zstd-compressed (".zst"). The readers (read_mesh, read_mesh_stream, format_from_path...)
// are declared in streaming/mesh_reader.h, included here so that one include serves both.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/mesh_buffers.h"
#include "core/mesh_view.h"
#include "streaming/mesh_reader.h"

namespace streamcvd {

struct WriteOptions {
  bool ascii = false;       ///< PLY only: ascii instead of binary_little_endian
  int zstd_level = 3;       ///< compression level when the path ends in ".zst"
  std::string comment;      ///< written as a header comment where the format has one
};

/// Writes `mesh` to `path` in the format its extension names (".ply" binary LE by default,
/// ".obj", ".off", ".stl" binary; + ".zst" to compress). Atomic: writes a temporary file in the
/// destination folder and renames it on success; on any error no file is left behind and
/// OutputError is thrown.
void write_mesh(const std::string& path, const TriangleSoupView& mesh, const WriteOptions& options = {});

}  // namespace streamcvd
