// A triangle soup held in RAM: what readers and generators produce.
#pragma once

#include <cstdint>
#include <vector>

#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

struct MeshBuffers {
  std::vector<float> positions;     ///< 3·V, xyz
  std::vector<uint32_t> triangles;  ///< 3·F, polygons fan-triangulated
  uint64_t polygons_split = 0;      ///< input faces with > 3 corners (fan-triangulated)

  uint32_t vertex_count() const { return static_cast<uint32_t>(positions.size() / 3); }
  uint64_t face_count() const { return triangles.size() / 3; }
  TriangleSoupView view() const { return {positions, triangles}; }
};

}  // namespace streamcvd
