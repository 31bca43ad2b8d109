// TEMPORARY (replaced by the streaming readers): read_mesh_stream over the whole-soup readers.
#include "streaming/mesh_io.h"
#include "streaming/store_build.h"

namespace streamcvd {
void read_mesh_stream(const std::string& path, MeshSink& sink, const ReadOptions& options) {
  MeshBuffers m = read_mesh(path);
  stream_soup(m.view(), sink, options.block);
}
}  // namespace streamcvd
