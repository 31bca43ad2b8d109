#include "streamcvd/streaming/openmesh_adapter.h"

#include <vector>

namespace streamcvd {

MeshBuffers soup_from_openmesh(const OpenMeshTriMesh& mesh) {
  MeshBuffers soup;
  std::vector<uint32_t> id(mesh.n_vertices(), UINT32_MAX);
  uint32_t next = 0;
  for (auto v : mesh.vertices()) {
    if (mesh.has_vertex_status() && mesh.status(v).deleted()) continue;
    id[v.idx()] = next++;
    const auto& p = mesh.point(v);
    soup.positions.insert(soup.positions.end(), {float(p[0]), float(p[1]), float(p[2])});
  }
  for (auto f : mesh.faces()) {
    if (mesh.has_face_status() && mesh.status(f).deleted()) continue;
    std::vector<uint32_t> corners;
    for (auto v : mesh.fv_range(f)) corners.push_back(id[v.idx()]);
    for (size_t k = 1; k + 1 < corners.size(); ++k)
      soup.triangles.insert(soup.triangles.end(), {corners[0], corners[k], corners[k + 1]});
  }
  return soup;
}

OpenMeshTriMesh openmesh_from_soup(const TriangleSoupView& soup, uint64_t* rejected_faces) {
  OpenMeshTriMesh mesh;
  std::vector<OpenMeshTriMesh::VertexHandle> handles;
  handles.reserve(soup.vertex_count());
  for (uint32_t v = 0; v < soup.vertex_count(); ++v)
    handles.push_back(mesh.add_vertex({soup.positions[3 * v], soup.positions[3 * v + 1], soup.positions[3 * v + 2]}));
  uint64_t rejected = 0;
  for (uint64_t f = 0; f < soup.face_count(); ++f) {
    auto h = mesh.add_face(handles[soup.triangles[3 * f]], handles[soup.triangles[3 * f + 1]],
                           handles[soup.triangles[3 * f + 2]]);
    rejected += !h.is_valid();
  }
  if (rejected_faces) *rejected_faces = rejected;
  return mesh;
}

OpenMeshTriMesh remesh_openmesh(const OpenMeshTriMesh& input, const PipelineOptions& options, PipelineResult* result) {
  MeshBuffers soup = soup_from_openmesh(input);
  MeshStore store = MeshStore::build(soup.view());
  PipelineResult run = remesh_store(store, options);
  OpenMeshTriMesh output = openmesh_from_soup(run.remesh.mesh.view());
  if (result) *result = std::move(run);
  return output;
}

}  // namespace streamcvd
