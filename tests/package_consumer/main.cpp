// Remeshes a torus through the installed library and checks the vertex count and the checks.
#include <streamcvd/core/measure/shapes.h>
#include <streamcvd/streaming/remesh_pipeline.h>
#include <streamcvd/streaming/store/store.h>

#include <cstdio>

#include "all_headers.h"  // every installed header compiles from the install tree

int main() {
  const streamcvd::MeshBuffers torus = streamcvd::make_torus(60, 30);
  const streamcvd::MeshStore store = streamcvd::MeshStore::build(torus.view());
  streamcvd::PipelineOptions options;
  options.remesh.vertices = 500;
  options.remesh.clustering.loops.threads = 1;
  const streamcvd::PipelineResult r = streamcvd::remesh_store(store, options);
  std::printf("consumer: %u vertices, %llu faces\n", r.remesh.mesh.vertex_count(),
              static_cast<unsigned long long>(r.remesh.mesh.face_count()));
  return r.remesh.mesh.vertex_count() == 500 ? 0 : 1;
}
