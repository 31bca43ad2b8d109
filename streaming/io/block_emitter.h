// Internal to the mesh readers: the block buffers between a format reader and a MeshSink
// (streaming/io/mesh_reader.h). A reader writes vertices and triangles into fixed blocks of
// ReadOptions::block elements, allocated once; a full block goes to the sink and is reused, so
// memory stays O(block) whatever the file size. Also the per-format entry points.
#pragma once

#include <cstdint>
#include <string_view>
#include <vector>

#include "streamcvd/streaming/io/input_stream.h"
#include "streamcvd/streaming/io/mesh_reader.h"

namespace streamcvd {

/// True when `options` asks for the vertex attribute `name` (All, or Named and listed).
bool attribute_selected(const ReadOptions& options, std::string_view name);

/// One read's block buffers and its sink. The hot paths (reserve, write, commit) are inline and
/// allocation-free; a full block is handed out from a cold call. Triangle blocks are always
/// preceded by the vertices buffered so far (MeshSink::triangles' guarantee).
class BlockEmitter {
 public:
  /// Allocates the blocks for `options.block` elements; throws InputError when it is 0.
  BlockEmitter(InputStream& in, MeshSink& sink, const ReadOptions& options);

  /// The header handed to sink.begin(); readers fill it in before begin().
  MeshHeaderInfo& header() { return header_; }
  /// Sizes the attribute rows for header().attributes and calls sink.begin(). Idempotent; a
  /// flush calls it if the reader has not (OBJ: faces before the first vertex).
  void begin();
  /// Whether begin() has run: the header can no longer change.
  bool begun() const { return begun_; }
  /// Counts the readers keep (polygons split, strip triangles dropped); the rest is filled in
  /// by the emitter.
  ReadStats& stats() { return stats_; }
  /// The read's options (attribute selection for the header).
  const ReadOptions& options() const { return options_; }

  /// Id of the next vertex: vertices handed out plus those waiting in the block.
  uint64_t vertex_count() const { return vertices_sent_ + pending_vertices_; }
  /// Floats per vertex in the attribute rows (header().attributes.size() once begun).
  size_t attribute_count() const { return attributes_; }

  /// Room for min(want, space left) more vertices, flushing a full block first; want ≥ 1, the
  /// result is ≥ 1. Only after begin() (the attribute rows are sized there). Write them at vertex_xyz() (3 floats each) and vertex_attributes()
  /// (attribute_count() each), then commit_vertices(how many were written).
  size_t reserve_vertices(uint64_t want) {
    if (pending_vertices_ == block_) [[unlikely]] flush_vertices();
    return want < block_ - pending_vertices_ ? size_t(want) : block_ - pending_vertices_;
  }
  float* vertex_xyz() { return xyz_.data() + 3 * pending_vertices_; }
  float* vertex_attributes() { return attribute_values_.data() + attributes_ * pending_vertices_; }
  void commit_vertices(size_t k) { pending_vertices_ += k; }
  /// One vertex without attributes (or with attributes written afterwards at the returned row).
  float* add_vertex(float x, float y, float z) {
    reserve_vertices(1);
    float* p = vertex_xyz();
    p[0] = x, p[1] = y, p[2] = z;
    float* row = vertex_attributes();
    ++pending_vertices_;
    return row;
  }

  /// As reserve_vertices, for triangles (3 ids each at triangle_corners()).
  size_t reserve_triangles(uint64_t want) {
    if (pending_triangles_ == block_) [[unlikely]] flush_triangles();
    return want < block_ - pending_triangles_ ? size_t(want) : block_ - pending_triangles_;
  }
  uint32_t* triangle_corners() { return corners_.data() + 3 * pending_triangles_; }
  void commit_triangles(size_t k) { pending_triangles_ += k; }
  void add_triangle(uint32_t a, uint32_t b, uint32_t c) {
    reserve_triangles(1);
    uint32_t* t = triangle_corners();
    t[0] = a, t[1] = b, t[2] = c;
    ++pending_triangles_;
  }

  /// Hands out both partial blocks (the end of an element).
  void flush();
  /// The read's last step: flush, check that the mesh has vertices and triangles, fill in the
  /// byte count and call sink.end().
  void finish();

 private:
  void flush_vertices();
  void flush_triangles();
  void report_progress();

  InputStream& in_;
  MeshSink& sink_;
  const ReadOptions& options_;
  MeshHeaderInfo header_;
  ReadStats stats_;
  bool begun_ = false;
  size_t block_;
  size_t attributes_ = 0;
  std::vector<float> xyz_, attribute_values_;
  std::vector<uint32_t> corners_;
  // size_t, not uint32_t: a uint32_t counter may alias the uint32_t ids written through
  // triangle_corners(), which would force a reload and store of it after every triangle.
  size_t pending_vertices_ = 0, pending_triangles_ = 0;
  uint64_t vertices_sent_ = 0;
};

/// Fan triangulation (v0, v[j-1], v[j]) of a polygon whose corners arrive one by one.
class PolygonFan {
 public:
  explicit PolygonFan(BlockEmitter& out) : out_(out) {}
  void add(uint32_t v) {
    if (corners_ == 0) first_ = v;
    else if (corners_ >= 2) out_.add_triangle(first_, prev_, v);
    prev_ = v;
    ++corners_;
  }
  /// Ends the polygon (counting it as split when it had more than 3 corners).
  void end() {
    if (corners_ > 3) ++out_.stats().polygons_split;
    corners_ = 0;
  }

 private:
  BlockEmitter& out_;
  uint32_t first_ = 0, prev_ = 0;
  uint64_t corners_ = 0;
};

/// The per-format producers behind read_mesh_stream: each fills in the emitter's header, calls
/// begin(), streams the data and flushes; the caller calls finish().
void stream_ply(InputStream& in, BlockEmitter& out);
void stream_obj(InputStream& in, BlockEmitter& out);
void stream_off(InputStream& in, BlockEmitter& out);
void stream_stl(InputStream& in, BlockEmitter& out);

}  // namespace streamcvd
