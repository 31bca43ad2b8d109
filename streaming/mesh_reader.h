// Streaming mesh readers: PLY (ascii, binary LE/BE; `face` lists or `tristrips`), OBJ, OFF, STL
// (ascii/binary), each optionally zstd-compressed (detected by content), from a file or from
// standard input ("-"). A reader never holds the whole mesh: it hands out blocks of vertices and
// of triangles to a MeshSink, in memory bounded by the block size (DESIGN.md §2). Consumers are
// the store builder (streaming/store_build.h, out of core) and read_mesh() (small meshes in RAM).
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "core/mesh_buffers.h"

namespace streamcvd {

enum class MeshFormat { Ply, Obj, Off, Stl };

/// Storage type of a PLY property (kept so that an attribute is written back as it was read).
enum class ScalarType : uint8_t { I8, U8, I16, U16, I32, U32, F32, F64 };

/// A per-vertex property carried besides x, y, z: colour (red, green, blue, alpha) or any other
/// scalar (confidence, intensity, quality...). Normals (nx, ny, nz) are not attributes: they are
/// recomputed from an output, never averaged.
struct VertexAttribute {
  std::string name;                   ///< property name as in the file
  ScalarType type = ScalarType::F32;  ///< its type in the file
};

/// What a reader knows before the data arrives (DESIGN.md §2: headers first).
struct MeshHeaderInfo {
  static constexpr uint64_t kUnknown = ~uint64_t(0);
  MeshFormat format = MeshFormat::Ply;
  uint64_t vertices = kUnknown;  ///< vertex records the header announces (PLY, OFF); kUnknown for OBJ, STL
  uint64_t faces = kUnknown;     ///< face records announced (PLY face or strip lists, OFF, binary STL)
  uint64_t input_bytes = 0;      ///< size of the file on disk, 0 for a pipe
  bool compressed = false;       ///< zstd input: input_bytes counts compressed bytes
  /// STL: every triangle brings its three corners by value, as vertices 3t, 3t+1, 3t+2; corners
  /// with bitwise identical coordinates (−0 folded to +0 by the reader) are one vertex, merged by
  /// the consumer (the store builder merges them in its sort, read_mesh() with a hash table).
  bool corners_by_value = false;
  std::vector<VertexAttribute> attributes;  ///< in the order of MeshSink::vertices' rows
};

/// Counts a reader reports at the end.
struct ReadStats {
  uint64_t vertices = 0;             ///< vertex records read (STL: 3 × triangles)
  uint64_t triangles = 0;            ///< triangles handed out
  uint64_t polygons_split = 0;       ///< input faces with more than 3 corners (fan-triangulated)
  uint64_t strip_triangles_dropped = 0;  ///< PLY tristrips: degenerate joining triangles dropped
  uint64_t bytes = 0;                ///< (decompressed) bytes consumed
};

/// Receives a mesh block by block, in file order. Vertex ids are implicit (the i-th vertex
/// handed out has id i); triangles refer to them. Called from the reading thread only.
class MeshSink {
 public:
  virtual ~MeshSink() = default;
  /// Once, before any data.
  virtual void begin(const MeshHeaderInfo& header) = 0;
  /// The next xyz.size()/3 vertices (finite coordinates, checked by the reader); `attributes`
  /// holds header.attributes.size() floats per vertex, row-major (empty when there are none).
  virtual void vertices(std::span<const float> xyz, std::span<const float> attributes) = 0;
  /// The next triangles, three vertex ids each. PLY and OFF ids are < the announced vertex count
  /// (checked by the reader when read); OBJ ids may point forward and are checked once the file
  /// has ended, before end() is called.
  virtual void triangles(std::span<const uint32_t> corners) = 0;
  /// Once, after the last block; not called when the read fails.
  virtual void end(const ReadStats& stats) = 0;
};

struct ReadOptions {
  /// Elements per block handed to the sink (vertices or triangles).
  uint32_t block = 1u << 16;
  /// Which vertex attributes to carry: all (default), none, or those named.
  enum class Attributes { All, None, Named } attributes = Attributes::All;
  std::vector<std::string> attribute_names;  ///< with Attributes::Named
  /// Called between blocks with the (raw) bytes consumed so far and header.input_bytes.
  std::function<void(uint64_t bytes, uint64_t total)> progress;
};

/// Format from the file name (".ply", ".obj", ".off", ".stl", each optionally + ".zst",
/// case-insensitive). Throws InputError for an unknown extension.
MeshFormat format_from_path(const std::string& path);
/// True when `path` ends in ".zst" (case-insensitive).
bool has_zst_extension(const std::string& path);

/// Streams the mesh at `path` ("-" = standard input) into `sink`: format from the extension,
/// else from the content. Memory: O(block + header), whatever the file size. Throws InputError
/// "<file>: line N|byte N: <problem>" (truncation, bad values, indices out of range, a PLY with
/// no element readable as faces...); the sink's own exceptions pass through.
void read_mesh_stream(const std::string& path, MeshSink& sink, const ReadOptions& options = {});

/// Mesh with its vertex attributes, in RAM (what read_mesh_with_attributes collects).
struct MeshWithAttributes {
  MeshBuffers mesh;
  std::vector<VertexAttribute> attributes;
  std::vector<float> values;  ///< attributes.size() floats per vertex, row-major
};

/// Convenience for small meshes and tests: the whole soup in RAM, collected from
/// read_mesh_stream (STL corners merged here, in order of first appearance). Validates V > 0.
MeshBuffers read_mesh(const std::string& path);
/// Same, keeping the vertex attributes selected by `options`.
MeshWithAttributes read_mesh_with_attributes(const std::string& path, const ReadOptions& options = {});

}  // namespace streamcvd
