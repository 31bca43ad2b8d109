// Mesh file readers and writers: PLY (ascii, binary LE/BE), OBJ, OFF, STL (ascii/binary),
// each optionally zstd-compressed (".zst", detected by content when reading).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/mesh_buffers.h"
#include "core/mesh_view.h"
#include "streaming/mesh_reader.h"

namespace streamcvd {

class InputStream;

/// Per-format readers over an open stream; same contract as read_mesh.
/// PLY: ascii, binary_little_endian and binary_big_endian; any extra element/property; any
/// list count/index types; polygons fan-triangulated.
MeshBuffers read_ply(InputStream& in);
/// OBJ: `v` and `f` (v, v/vt, v/vt/vn, v//vn, negative indices, polygons); other records ignored.
MeshBuffers read_obj(InputStream& in);
/// OFF, COFF, NOFF, CNOFF, STOFF...: '#' comments, optional counts line after the keyword.
MeshBuffers read_off(InputStream& in);
/// STL ascii or binary (binary told apart by size and content); exactly identical
/// coordinates are merged into one vertex, in order of first appearance.
MeshBuffers read_stl(InputStream& in);

/// Checks a freshly read soup: V > 0, finite coordinates, indices < V. Throws InputError
/// naming `path` and the first offending vertex/face.
void validate_soup(const std::string& path, const MeshBuffers& mesh);

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
