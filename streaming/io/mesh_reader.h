// Streaming mesh readers: PLY (ascii, binary LE/BE; `face` lists or `tristrips`), OBJ, OFF, STL
// (ascii/binary), each optionally zstd-compressed (detected by content), from a file or from
// standard input ("-"). A reader never holds the whole mesh: it hands out blocks of vertices and
// of triangles to a MeshSink, in memory bounded by the block size (DESIGN.md §2). Consumers are
// the store builder (streaming/store/store_build.h, out of core) and read_mesh() (small meshes in RAM).
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/mesh_buffers.h"

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

/// The PLY name of a scalar type ("uchar", "float"...): how writers and the store's
/// attributes.txt spell it. O(1), thread-safe.
const char* scalar_type_name(ScalarType type);
/// Bytes of one value of the type in a binary file.
inline size_t scalar_type_bytes(ScalarType type) {
  constexpr size_t kSize[] = {1, 1, 2, 2, 4, 4, 4, 8};
  return kSize[static_cast<int>(type)];
}

/// Per-vertex attribute rows, borrowed: names.size() floats per vertex, row-major, in vertex
/// order (values as stored: uchar 200 → 200.0f). What writers and the subdivision take.
struct VertexAttributeRows {
  std::span<const VertexAttribute> names;
  std::span<const float> values;
  bool empty() const { return names.empty(); }
};

/// What a reader knows before the data arrives (DESIGN.md §2: headers first).
struct MeshHeaderInfo {
  static constexpr uint64_t kUnknown = ~uint64_t(0);
  MeshFormat format = MeshFormat::Ply;
  uint64_t vertices = kUnknown;  ///< vertex records the header announces (PLY, OFF); kUnknown for OBJ, STL
  /// Face records announced (PLY `face`, OFF, binary STL): a polygon record gives several
  /// triangles. kUnknown for OBJ, ascii STL and PLY `tristrips` (a strip holds any number).
  uint64_t faces = kUnknown;
  uint64_t input_bytes = 0;      ///< size of the file on disk, 0 for a pipe
  bool compressed = false;       ///< zstd input: input_bytes counts compressed bytes
  /// STL: every triangle t brings its three corners by value, as vertices 3t, 3t+1, 3t+2
  /// (−0 folded to +0 by the reader), and triangles() repeats (3t, 3t+1, 3t+2). Bitwise
  /// identical corners are one vertex, merged by the consumer (the store builder in its sort,
  /// read_mesh() with a hash table, in order of first appearance).
  bool corners_by_value = false;
  /// True when every vertex block comes before the first triangle block (PLY with the vertex
  /// element first, OFF). False for OBJ, STL and PLY files that put faces first: see
  /// MeshSink::triangles for what may then arrive early.
  bool vertices_before_triangles = false;
  std::vector<VertexAttribute> attributes;  ///< in the order of MeshSink::vertices' rows
  /// Binary PLY from a regular file: the reader measured the vertex element before streaming it
  /// (one sequential pass), so a consumer can order vertices as they arrive instead of keeping
  /// them first. The bounds are exactly those of the finite coordinates handed out later; the
  /// sample holds the positions of vertices 0, stride, 2·stride, ... (at most 2^17 of them).
  bool has_bounds = false;
  float bounds_lo[3] = {0, 0, 0}, bounds_hi[3] = {0, 0, 0};
  std::vector<float> position_sample;
  uint64_t sample_stride = 1;
};

/// Counts a reader reports at the end.
struct ReadStats {
  uint64_t vertices = 0;             ///< vertex records read (STL: 3 × triangles)
  uint64_t triangles = 0;            ///< triangles handed out
  uint64_t polygons_split = 0;       ///< input faces with more than 3 corners (fan-triangulated)
  uint64_t strip_triangles_dropped = 0;  ///< PLY tristrips: degenerate joining triangles dropped
  uint64_t bytes = 0;                ///< (decompressed) bytes consumed
};

/// Receives a mesh block by block, in file order: begin(), then vertices() and triangles()
/// blocks, then end(). Vertex ids are implicit (the i-th vertex handed out has id i);
/// triangles refer to them. A block holds 1 to ReadOptions::block elements (the last block of
/// an element, or vertices handed out early, may be shorter). Called from the reading thread.
class MeshSink {
 public:
  virtual ~MeshSink() = default;
  /// Once, before any data.
  virtual void begin(const MeshHeaderInfo& header) = 0;
  /// The next xyz.size()/3 vertices (finite coordinates, checked by the reader); `attributes`
  /// holds header.attributes.size() floats per vertex, row-major, each the value as stored
  /// (uchar 200 → 200.0f; not checked). Empty when there are no attributes.
  virtual void vertices(std::span<const float> xyz, std::span<const float> attributes) = 0;
  /// The next triangles, three vertex ids each. Every vertex read before a triangle block has
  /// been handed out before it. PLY and OFF ids are < header.vertices (checked when read), but
  /// may precede their vertices when the PLY face element comes first; OBJ ids may point
  /// forward (past the vertices read so far) and are checked once the file has ended, before
  /// end() is called.
  virtual void triangles(std::span<const uint32_t> corners) = 0;
  /// Once, after the last block; not called when the read fails.
  virtual void end(const ReadStats& stats) = 0;
};

struct ReadOptions {
  /// Elements per block handed to the sink (vertices or triangles); at least 1.
  uint32_t block = 1u << 16;
  /// Which vertex attributes to carry: all (default), none, or those named (in file order;
  /// names the file lacks are simply absent from header.attributes).
  enum class Attributes { All, None, Named } attributes = Attributes::All;
  std::vector<std::string> attribute_names;  ///< with Attributes::Named
  /// Called between blocks with the (raw) bytes consumed so far and header.input_bytes.
  std::function<void(uint64_t bytes, uint64_t total)> progress;
  /// read_mesh / read_mesh_with_attributes only: bytes the whole soup may take in RAM (0 = no
  /// limit); past it they throw InputError naming the limit instead of growing further.
  uint64_t memory_limit = 0;
};

/// Format from the file name (".ply", ".obj", ".off", ".stl", each optionally + ".zst",
/// case-insensitive). Throws InputError for an unknown extension.
MeshFormat format_from_path(const std::string& path);
/// True when `path` ends in ".zst" (case-insensitive).
bool has_zst_extension(const std::string& path);

/// Streams the mesh at `path` ("-" = standard input, named "stdin" in messages) into `sink`:
/// format from the extension, else from the content. Memory: O(block + header + 4 MiB of input
/// buffer), whatever the file size (a line of OBJ, OFF or ascii STL is held whole, up to its
/// 256 MiB limit; ascii PLY lines of any length stream). Throws InputError "<file>: line N|byte N: <problem>"
/// (truncation, bad values, indices out of range, a PLY with no element readable as faces, a
/// mesh without vertices or without triangles...); the sink's own exceptions pass through.
void read_mesh_stream(const std::string& path, MeshSink& sink, const ReadOptions& options = {});

/// Mesh with its vertex attributes, in RAM (what read_mesh_with_attributes collects).
struct MeshWithAttributes {
  MeshBuffers mesh;
  std::vector<VertexAttribute> attributes;
  std::vector<float> values;  ///< attributes.size() floats per vertex, row-major
};

/// Convenience for small meshes and tests: the whole soup in RAM, collected from
/// read_mesh_stream (STL corners merged here, in order of first appearance), then checked by
/// validate_soup. Same errors as read_mesh_stream.
MeshBuffers read_mesh(const std::string& path);
/// Same, with `options` (attributes are not kept).
MeshBuffers read_mesh(const std::string& path, const ReadOptions& options);
/// Same, keeping the vertex attributes selected by `options` (its block size changes only the
/// memory of the read, never the result).
MeshWithAttributes read_mesh_with_attributes(const std::string& path, const ReadOptions& options = {});

/// Checks a soup in RAM: V > 0, finite coordinates, indices < V. Throws InputError naming
/// `path` and the first offending vertex/face.
void validate_soup(const std::string& path, const MeshBuffers& mesh);

}  // namespace streamcvd
