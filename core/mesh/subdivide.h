// How many levels of linear 1→4 subdivision a remesh asks for (paper §VI-F: remeshing by
// over-sampling, so that N can approach or exceed the input vertex count). The subdivision itself
// streams from a store into the store builder: streaming/store/subdivision_stream.h.
#pragma once

#include <cstdint>

#include "streamcvd/core/mesh/mesh_buffers.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

/// Levels of subdivision for `input_vertices` → `clusters`: `requested` ≥ 0 is used as is;
/// −1 (auto) subdivides until there are at least `min_vertices_per_cluster` input vertices per
/// cluster (each level multiplies V by about 4), at most 6 levels.
int subdivision_levels(uint64_t input_vertices, uint64_t clusters, int requested, double min_vertices_per_cluster = 10.0);

}  // namespace streamcvd
