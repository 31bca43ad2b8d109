// OpenMesh adapter for in-core users: remesh an OpenMesh triangle mesh into another one.
#pragma once

#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>

#include "streamcvd/streaming/remesh_pipeline.h"

namespace streamcvd {

using OpenMeshTriMesh = OpenMesh::TriMesh_ArrayKernelT<>;

/// Copies an OpenMesh triangle mesh into a soup (positions as float, faces in order; deleted
/// elements skipped). O(V + F).
MeshBuffers soup_from_openmesh(const OpenMeshTriMesh& mesh);

/// Builds an OpenMesh triangle mesh from a soup. Faces OpenMesh refuses (complex edges) are
/// counted in `rejected_faces` when given. O(V + F).
OpenMeshTriMesh openmesh_from_soup(const TriangleSoupView& soup, uint64_t* rejected_faces = nullptr);

/// Remeshes `input` to options.remesh.vertices vertices (subdividing when needed) and returns
/// the result as an OpenMesh mesh; `result` (optional) receives the full report.
OpenMeshTriMesh remesh_openmesh(const OpenMeshTriMesh& input, const PipelineOptions& options,
                                PipelineResult* result = nullptr);

}  // namespace streamcvd
