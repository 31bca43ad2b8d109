// The remeshing job from a file or store to an output mesh: load (or map) the input, subdivide
// when the budget asks for it (§VI-F), build the store in RAM, remesh, check the output.
#pragma once

#include <string>

#include "core/mesh_stats.h"
#include "core/remesh.h"
#include "streaming/store.h"

namespace streamcvd {

struct PipelineOptions {
  RemeshOptions remesh;
  int subdivide = -1;  ///< −1 auto (fewer than ~10 input vertices per cluster), 0 none, K levels
};

struct InputSummary {
  uint64_t vertices = 0, faces = 0;
  uint64_t components = 0;
  uint64_t boundary_vertices = 0;
  bool closed = false;             ///< no boundary vertex, no non-manifold vertex
  int64_t euler_characteristic = 0;
};

struct PipelineResult {
  RemeshResult remesh;
  InputSummary input;
  int subdivision_levels = 0;
  uint64_t remeshed_vertices = 0, remeshed_faces = 0;  ///< after subdivision
  double load_seconds = 0, subdivide_seconds = 0, store_seconds = 0;
  TopologyStats output_topology;
  QualityStats output_quality;
};

/// Summary figures of a store view in O(V) (Euler characteristic from CSR degrees).
InputSummary summarize_input(const MeshView& mesh, uint64_t components);

/// Remeshes an in-RAM or mapped store (subdividing first when asked or needed). Throws
/// InputError when the result has no triangle (all components dropped, or thinner than a cluster).
PipelineResult remesh_store(const MeshStore& store, const PipelineOptions& options);

/// Loads `input` (mesh file or store directory) and remeshes it. Throws InputError naming `input`.
PipelineResult remesh_path(const std::string& input, const PipelineOptions& options);

}  // namespace streamcvd
