// Topology per connected component, for the output checks of a remesh: every input component
// that got clusters must come out as exactly one output component with no more handles and no
// more boundary loops than it had (a handle or a hole below the output resolution may close; a
// closed input's Euler characteristic is checked exactly elsewhere). The input side is read
// chunk by chunk from the store's arrays; the output side is small (a soup in RAM).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "streamcvd/core/dual/dual_mesh.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

/// Euler characteristic and boundary loops of one component.
struct ComponentShape {
  int64_t euler = 0;
  uint64_t boundary_loops = 0;
  uint64_t faces = 0;
  bool manifold = true;  ///< no non-manifold vertex or edge (then the genus is defined)
  /// (2 − χ − b) / 2 for an orientable manifold component.
  int64_t genus() const { return (2 - euler - int64_t(boundary_loops)) / 2; }
};

/// The shape of each input component (ids from component_of_vertex, kNone = UINT32_MAX for
/// isolated vertices): χ = V − E + F from the CSR offsets (degrees and corners), loops from `loops`,
/// manifold from the vertex flags. O(V + F); one pass in vertex order. Thread-safe (pure).
std::vector<ComponentShape> input_component_shapes(const MeshView& mesh, std::span<const uint32_t> component_of_vertex,
                                                   uint32_t component_count, const BoundaryLoops& loops);

/// What check_component_topology finds.
struct ComponentCheck {
  uint64_t input_components = 0;   ///< input components that got clusters
  uint64_t output_components = 0;  ///< connected components of the output
  uint64_t input_boundary_loops = 0;   ///< boundary loops of the input components with clusters
  int64_t input_euler_characteristic = 0;  ///< Σ χ of the input components with clusters
  uint64_t output_boundary_loops = 0;  ///< boundary loops of the output
  int64_t output_euler_characteristic = 0;  ///< V − E + F of the output, referenced vertices only
  std::vector<std::string> problems;  ///< one line each: "component 3 (1,234 vertices): split into 2 pieces"
  bool ok() const { return problems.empty(); }
};

/// Compares the output soup's components with the input's: each input component with clusters
/// (component_of_cluster[c] = its input component) must map to exactly one output component,
/// whose genus (manifold inputs) and boundary loops are not more than the input's. At
/// most `max_problems` lines are listed. O(F_out log F_out). Thread-safe (pure).
ComponentCheck check_component_topology(std::span<const ComponentShape> input, const TriangleSoupView& output,
                                        std::span<const int32_t> cluster_of_output_vertex,
                                        std::span<const uint32_t> component_of_cluster, size_t max_problems = 8);

}  // namespace streamcvd
