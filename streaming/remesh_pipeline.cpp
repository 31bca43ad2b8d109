#include "streaming/remesh_pipeline.h"

#include <chrono>

#include "core/errors.h"
#include "core/subdivide.h"
#include "streaming/mesh_io.h"

namespace streamcvd {

namespace {
double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}
}  // namespace

InputSummary summarize_input(const MeshView& mesh, uint64_t components) {
  InputSummary s;
  s.vertices = mesh.vertex_count();
  s.faces = mesh.face_count();
  s.components = components;
  uint64_t referenced = 0;
  bool nonmanifold = false;
  for (uint32_t v = 0; v < mesh.vertex_count(); ++v) {
    uint8_t f = mesh.vertex_flags[v];
    s.boundary_vertices += (f & kVertexBoundary) != 0;
    nonmanifold |= (f & kVertexNonManifold) != 0;
    referenced += (f & kVertexIsolated) == 0;
  }
  s.closed = s.boundary_vertices == 0 && !nonmanifold;
  s.euler_characteristic = int64_t(referenced) - int64_t(mesh.vertex_vertex.size() / 2) + int64_t(s.faces);
  return s;
}

PipelineResult remesh_store(const MeshStore& store, const PipelineOptions& options) {
  PipelineResult result;
  MeshView view = store.view();
  result.subdivision_levels = subdivision_levels(view.vertex_count(), options.remesh.vertices, options.subdivide);
  MeshStore subdivided;
  if (result.subdivision_levels > 0) {
    auto t = std::chrono::steady_clock::now();
    MeshBuffers soup;
    soup.positions.assign(view.positions.begin(), view.positions.end());
    soup.triangles.assign(view.triangles.begin(), view.triangles.end());
    for (int level = 0; level < result.subdivision_levels; ++level) soup = subdivide_linear(soup.view());
    result.subdivide_seconds = seconds_since(t);
    t = std::chrono::steady_clock::now();
    subdivided = MeshStore::build(std::move(soup));
    result.store_seconds += seconds_since(t);
    view = subdivided.view();
  }
  result.remeshed_vertices = view.vertex_count();
  result.remeshed_faces = view.face_count();
  RemeshOptions remesh_options = options.remesh;
  if (!remesh_options.density.empty() && result.subdivision_levels > 0) remesh_options.density.clear();
  result.remesh = remesh(view, remesh_options);
  if (result.remesh.mesh.face_count() == 0)
    // An empty file is no answer: every component was dropped, or is thinner than a cluster
    // everywhere (a needle), or has no area.
    throw InputError("remeshing left no triangle (" + std::to_string(result.remesh.clusters) +
                     " clusters; components too small or too thin for the budget of " +
                     std::to_string(options.remesh.vertices) + " vertices)");
  result.input = summarize_input(store.view(), result.remesh.budget.clusters_per_component.size());
  result.output_topology = compute_topology_stats(result.remesh.mesh.view());
  result.output_quality = compute_quality(result.remesh.mesh.view());
  return result;
}

PipelineResult remesh_path(const std::string& input, const PipelineOptions& options) {
  auto t = std::chrono::steady_clock::now();
  MeshStore store;
  double load_seconds = 0, store_seconds = 0;
  if (is_store_directory(input)) {
    store = MeshStore::open(input);
    store.validate_all();
    load_seconds = seconds_since(t);
  } else {
    MeshBuffers soup = read_mesh(input);
    load_seconds = seconds_since(t);
    t = std::chrono::steady_clock::now();
    store = MeshStore::build(std::move(soup));
    store_seconds = seconds_since(t);
  }
  PipelineResult result;
  try {
    result = remesh_store(store, options);
  } catch (const InputError& e) {
    throw InputError(error_at(input, e.what()));  // name the file, as every CLI error does
  }
  result.load_seconds = load_seconds;
  result.store_seconds += store_seconds;
  return result;
}

}  // namespace streamcvd
