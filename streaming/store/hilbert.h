// 3D Hilbert keys: 21 bits per axis packed into a 63-bit integer, so that sorting points by key
// lays them out along a Hilbert curve (consecutive keys are face-adjacent grid cells). The store
// renumbers vertices by this key (DESIGN.md §2): nearby vertices get nearby indices, chunks are
// compact, and a contiguous index range is a compact patch of surface.
// Encoding is Skilling's transpose algorithm ("Programming the Hilbert curve", AIP Conf. Proc.
// 707, 2004): O(bits) integer operations per point, no tables.
#pragma once

#include <array>
#include <cstdint>
#include <span>

namespace streamcvd {

/// Bits per axis of a Hilbert key; a key has 3·21 = 63 significant bits.
inline constexpr int kHilbertBits = 21;
/// Largest quantised coordinate (2^21 − 1).
inline constexpr uint32_t kHilbertMaxCoord = (uint32_t(1) << kHilbertBits) - 1;

/// Hilbert index of the grid cell (x, y, z), each coordinate < 2^21 (higher bits are ignored).
/// Keys of cells that are consecutive along the curve differ by 1. O(21) operations; pure.
uint64_t hilbert_encode(uint32_t x, uint32_t y, uint32_t z);
/// Inverse of hilbert_encode: the cell (x, y, z) of a key < 2^63. O(21) operations; pure.
std::array<uint32_t, 3> hilbert_decode(uint64_t key);

/// Maps positions into the 2^21-cell cube that holds a bounding box. One scale for all three axes
/// (the largest extent), so cells are cubes and the curve's locality is not skewed for flat
/// objects; a degenerate box (one point) maps everything to cell 0.
struct HilbertGrid {
  double origin[3] = {0, 0, 0};
  double scale = 0;  ///< cells per unit length
};

/// Grid covering [bbox_min, bbox_max]. Non-finite or inverted boxes give scale 0. Pure.
HilbertGrid make_hilbert_grid(const float bbox_min[3], const float bbox_max[3]);

/// Hilbert key of one position: quantised into the grid (clamped to the cube; a NaN coordinate
/// maps to 0), then encoded. O(21) operations; pure.
uint64_t hilbert_key(const HilbertGrid& grid, const float position[3]);

/// Keys of all positions (3·V floats) into `keys` (V entries). TBB-parallel, O(V);
/// deterministic; thread-safe for distinct outputs.
void hilbert_keys(std::span<const float> positions, const HilbertGrid& grid, std::span<uint64_t> keys);

}  // namespace streamcvd
