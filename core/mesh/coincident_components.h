// Components that touch another component at a coincident vertex. The topology cleaning cuts a
// non-manifold junction by giving each fan its own copy of the vertex (streaming/store/
// store_clean.h): a fin or a doubled wall becomes a sheet of its own that still touches the
// surface it was cut from, vertex on vertex. The component budget drops such sheets when they
// are below the output resolution (paper §VI-G budget; issue 16).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

/// Per component (size `components`): 1 when one of its vertices sits at exactly the position of
/// a vertex of another component. Needs store order (Hilbert keys): coincident vertices have the
/// same key, so each vertex is compared with the next few in index order only. Vertices without
/// a component (kNoComponent) are skipped. O(V) reads of positions and labels, TBB-parallel over
/// vertex blocks, memory O(components + touching pairs).
std::vector<uint8_t> components_touching_others(const MeshView& mesh, std::span<const uint32_t> component_of_vertex,
                                                uint32_t components);

}  // namespace streamcvd
