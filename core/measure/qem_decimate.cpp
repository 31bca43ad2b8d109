#include "streamcvd/core/measure/qem_decimate.h"

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Tools/Decimater/DecimaterT.hh>
#include <OpenMesh/Tools/Decimater/ModNormalFlippingT.hh>
#include <OpenMesh/Tools/Decimater/ModQuadricT.hh>

#include <chrono>
#include <limits>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/mesh/timer.h"

namespace streamcvd {
namespace {

using OmMesh = OpenMesh::TriMesh_ArrayKernelT<>;

// Re-enables OpenMesh's error stream however the build ends: add_face() prints one line per
// refused face ("complex edge"), which on a scan with defects would flood stderr.
struct SilencedOmErr {
  SilencedOmErr() { ::omerr().disable(); }
  ~SilencedOmErr() { ::omerr().enable(); }
};

// Copies the referenced vertices and the faces OpenMesh accepts; returns the number refused.
uint64_t build_openmesh(const TriangleSoupView& soup, OmMesh& mesh, uint64_t& referenced) {
  const uint32_t V = soup.vertex_count();
  constexpr uint32_t kUnused = std::numeric_limits<uint32_t>::max();
  std::vector<uint32_t> handle(V, kUnused);
  for (uint64_t i = 0; i < 3 * soup.face_count(); ++i) {
    const uint32_t v = soup.triangles[i];
    if (v >= V)
      throw InputError("qem decimate: face " + std::to_string(i / 3) + " uses vertex " + std::to_string(v) + " of " +
                       std::to_string(V));
    handle[v] = 0;
  }
  referenced = 0;
  mesh.reserve(V, 3 * soup.face_count() / 2, soup.face_count());
  for (uint32_t v = 0; v < V; ++v) {
    if (handle[v] == kUnused) continue;
    const float* p = &soup.positions[3 * size_t(v)];
    handle[v] = uint32_t(mesh.add_vertex(OmMesh::Point(p[0], p[1], p[2])).idx());
    ++referenced;
  }
  uint64_t skipped = 0;
  SilencedOmErr silence;
  for (uint64_t f = 0; f < soup.face_count(); ++f) {
    const uint32_t a = handle[soup.triangles[3 * f]], b = handle[soup.triangles[3 * f + 1]],
                   c = handle[soup.triangles[3 * f + 2]];
    if (a == b || b == c || a == c) {
      ++skipped;
      continue;
    }
    const auto fh = mesh.add_face(OmMesh::VertexHandle(int(a)), OmMesh::VertexHandle(int(b)),
                                  OmMesh::VertexHandle(int(c)));
    skipped += !fh.is_valid();
  }
  return skipped;
}

}  // namespace

MeshBuffers decimate_quadric(const TriangleSoupView& soup, uint32_t target_vertices, QemReport* report,
                             bool prevent_flips) {
  QemReport r;
  auto t0 = std::chrono::steady_clock::now();
  OmMesh mesh;
  mesh.request_vertex_status();
  mesh.request_edge_status();
  mesh.request_face_status();
  mesh.request_face_normals();  // for the normal-flipping guard
  r.faces_skipped = build_openmesh(soup, mesh, r.input_vertices);
  // Vertices used only by refused faces would count towards the target yet never collapse.
  mesh.delete_isolated_vertices();
  mesh.garbage_collection();
  mesh.update_face_normals();
  r.build_seconds = seconds_since(t0);

  t0 = std::chrono::steady_clock::now();
  {
    OpenMesh::Decimater::DecimaterT<OmMesh> decimater(mesh);
    OpenMesh::Decimater::ModQuadricT<OmMesh>::Handle quadric;
    decimater.add(quadric);
    decimater.module(quadric).unset_max_err();
    // The usual OpenMesh pairing: a binary guard refusing collapses that flip a face normal by
    // more than 90° (without it, fold-overs add flaps several % of the diagonal off the surface).
    OpenMesh::Decimater::ModNormalFlippingT<OmMesh>::Handle no_flip;
    if (prevent_flips) decimater.add(no_flip);
    decimater.initialize();
    r.collapses = decimater.decimate_to(target_vertices);
  }
  mesh.garbage_collection();
  r.decimate_seconds = seconds_since(t0);

  MeshBuffers out;
  out.positions.reserve(3 * mesh.n_vertices());
  for (const auto vh : mesh.vertices()) {
    const auto& p = mesh.point(vh);
    out.positions.insert(out.positions.end(), {p[0], p[1], p[2]});
  }
  out.triangles.reserve(3 * mesh.n_faces());
  for (const auto fh : mesh.faces())
    for (const auto vh : mesh.fv_range(fh)) out.triangles.push_back(uint32_t(vh.idx()));
  if (report) *report = r;
  return out;
}

}  // namespace streamcvd
