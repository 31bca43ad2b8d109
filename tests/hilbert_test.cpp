#include "streamcvd/streaming/store/hilbert.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <set>
#include <vector>

namespace streamcvd {
namespace {

int manhattan(const std::array<uint32_t, 3>& a, const std::array<uint32_t, 3>& b) {
  int d = 0;
  for (int k = 0; k < 3; ++k) d += std::abs(int64_t(a[k]) - int64_t(b[k]));
  return d;
}

TEST(Hilbert, EncodeDecodeRoundTrip) {
  std::mt19937 rng(7);
  std::uniform_int_distribution<uint32_t> coord(0, kHilbertMaxCoord);
  for (int i = 0; i < 100000; ++i) {
    const uint32_t x = coord(rng), y = coord(rng), z = coord(rng);
    const uint64_t key = hilbert_encode(x, y, z);
    ASSERT_LT(key, uint64_t(1) << 63);
    const auto p = hilbert_decode(key);
    ASSERT_EQ(p[0], x);
    ASSERT_EQ(p[1], y);
    ASSERT_EQ(p[2], z);
  }
}

TEST(Hilbert, CurveStartsAtOriginAndEndsOnACorner) {
  EXPECT_EQ(hilbert_encode(0, 0, 0), 0u);
  const auto last = hilbert_decode((uint64_t(1) << 63) - 1);
  for (uint32_t c : last) EXPECT_TRUE(c == 0 || c == kHilbertMaxCoord);
}

TEST(Hilbert, ConsecutiveKeysAreFaceNeighbours) {
  // At the start of the curve and around random keys: every step moves to an adjacent cell.
  std::mt19937_64 rng(11);
  std::vector<uint64_t> starts = {0};
  for (int i = 0; i < 64; ++i) starts.push_back(rng() >> 1 & ((uint64_t(1) << 63) - 5000));
  for (uint64_t s : starts) {
    const uint64_t n = s == 0 ? (1u << 15) : 4096;
    auto prev = hilbert_decode(s);
    for (uint64_t k = s + 1; k < s + n; ++k) {
      auto p = hilbert_decode(k);
      ASSERT_EQ(manhattan(prev, p), 1) << "key " << k;
      prev = p;
    }
  }
}

TEST(Hilbert, PrefixFillsAnAlignedSubcube) {
  // The first 8^3 keys are exactly the 8×8×8 cube at the origin (the curve is self-similar).
  std::set<std::array<uint32_t, 3>> cells;
  for (uint64_t k = 0; k < 512; ++k) {
    auto p = hilbert_decode(k);
    for (uint32_t c : p) ASSERT_LT(c, 8u);
    cells.insert(p);
  }
  EXPECT_EQ(cells.size(), 512u);
}

TEST(Hilbert, QuantisationClampsAndIgnoresNaN) {
  const float lo[3] = {-1, -1, -1}, hi[3] = {1, 3, 1};  // largest extent 4 sets the scale
  HilbertGrid g = make_hilbert_grid(lo, hi);
  EXPECT_DOUBLE_EQ(g.scale, double(1u << 21) / 4.0);
  const float origin[3] = {-1, -1, -1}, below[3] = {-5, -7, -9}, corner[3] = {1, 3, 1}, beyond[3] = {9, 9, 9};
  EXPECT_EQ(hilbert_key(g, origin), 0u);
  EXPECT_EQ(hilbert_key(g, below), 0u);
  const float nan = std::nanf("");
  const float with_nan[3] = {nan, nan, nan};
  EXPECT_EQ(hilbert_key(g, with_nan), 0u);
  auto c = hilbert_decode(hilbert_key(g, corner));
  EXPECT_EQ(c[1], kHilbertMaxCoord);  // the far face lands in the last cell, not past it
  EXPECT_EQ(c[0], (1u << 20));        // x spans half of the cube
  auto b = hilbert_decode(hilbert_key(g, beyond));
  for (uint32_t v : b) EXPECT_EQ(v, kHilbertMaxCoord);
  // A one-point box maps everything to cell 0.
  HilbertGrid point = make_hilbert_grid(lo, lo);
  EXPECT_EQ(point.scale, 0.0);
  EXPECT_EQ(hilbert_key(point, corner), 0u);
}

TEST(Hilbert, BatchMatchesSingleKeys) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-2, 5);
  std::vector<float> pos(3 * 50000);
  for (float& x : pos) x = u(rng);
  const float lo[3] = {-2, -2, -2}, hi[3] = {5, 5, 5};
  HilbertGrid g = make_hilbert_grid(lo, hi);
  std::vector<uint64_t> keys(50000);
  hilbert_keys(pos, g, keys);
  for (size_t v = 0; v < keys.size(); ++v) ASSERT_EQ(keys[v], hilbert_key(g, &pos[3 * v]));
}

}  // namespace
}  // namespace streamcvd
