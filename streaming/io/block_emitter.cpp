#include "streamcvd/streaming/io/block_emitter.h"

#include <algorithm>

#include "streamcvd/core/mesh/errors.h"

namespace streamcvd {

bool attribute_selected(const ReadOptions& options, std::string_view name) {
  switch (options.attributes) {
    case ReadOptions::Attributes::All: return true;
    case ReadOptions::Attributes::None: return false;
    case ReadOptions::Attributes::Named: break;
  }
  return std::find(options.attribute_names.begin(), options.attribute_names.end(), name) != options.attribute_names.end();
}

BlockEmitter::BlockEmitter(InputStream& in, MeshSink& sink, const ReadOptions& options)
    : in_(in), sink_(sink), options_(options), block_(options.block) {
  if (block_ == 0) throw InputError("read_mesh_stream: ReadOptions::block must be at least 1");
  header_.input_bytes = in.file_size();
  header_.compressed = in.compressed();
  // Allocated once: the whole read reuses these blocks (the attribute rows, sized in begin(),
  // too). Triangles may arrive before begin() (OBJ faces before the first vertex).
  xyz_.resize(3 * block_);
  corners_.resize(3 * block_);
}

void BlockEmitter::begin() {
  if (begun_) return;
  begun_ = true;
  attributes_ = header_.attributes.size();
  attribute_values_.resize(attributes_ * block_);
  sink_.begin(header_);
}

void BlockEmitter::flush_vertices() {
  begin();
  if (pending_vertices_ == 0) return;
  sink_.vertices({xyz_.data(), 3 * pending_vertices_},
                 {attribute_values_.data(), attributes_ * pending_vertices_});
  vertices_sent_ += pending_vertices_;
  pending_vertices_ = 0;
  report_progress();
}

void BlockEmitter::flush_triangles() {
  // Vertices first: a triangle block never precedes a vertex the file gave before it.
  flush_vertices();
  if (pending_triangles_ == 0) return;
  sink_.triangles({corners_.data(), 3 * pending_triangles_});
  stats_.triangles += pending_triangles_;
  pending_triangles_ = 0;
  report_progress();
}

void BlockEmitter::report_progress() {
  if (options_.progress) options_.progress(in_.raw_offset(), header_.input_bytes);
}

void BlockEmitter::flush() {
  flush_vertices();
  flush_triangles();
}

void BlockEmitter::finish() {
  flush();
  stats_.vertices = vertices_sent_;
  stats_.bytes = in_.offset();
  // Every command needs triangles: a point set (or a file whose faces were all degenerate
  // strip joins) is rejected here rather than failing later with a less clear message.
  if (stats_.vertices == 0) throw InputError(error_at(in_.path(), "no vertices"));
  if (stats_.triangles == 0) {
    std::string why = "no faces (" + std::to_string(stats_.vertices) + " vertices and no triangle";
    if (stats_.strip_triangles_dropped > 0)
      why += "; " + std::to_string(stats_.strip_triangles_dropped) + " degenerate strip triangles dropped";
    throw InputError(error_at(in_.path(), why + ")"));
  }
  sink_.end(stats_);
}

}  // namespace streamcvd
