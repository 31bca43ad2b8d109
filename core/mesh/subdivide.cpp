#include "streamcvd/core/mesh/subdivide.h"


namespace streamcvd {

int subdivision_levels(uint64_t input_vertices, uint64_t clusters, int requested, double min_vertices_per_cluster) {
  if (requested >= 0) return requested;
  int levels = 0;
  double v = double(input_vertices);
  while (levels < 6 && clusters > 0 && v < min_vertices_per_cluster * double(clusters)) {
    v *= 4.0;
    ++levels;
  }
  return levels;
}

}  // namespace streamcvd
