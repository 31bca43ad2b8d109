#include "streamcvd/streaming/store/hilbert.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cassert>
#include <cmath>
#include <stdexcept>
#include <vector>

namespace streamcvd {
namespace {

// Spreads the low 21 bits of x so that bit i lands on bit 3i ("magic bits" interleave).
uint64_t spread_bits(uint64_t x) {
  x &= 0x1fffff;
  x = (x | x << 32) & 0x1f00000000ffffULL;
  x = (x | x << 16) & 0x1f0000ff0000ffULL;
  x = (x | x << 8) & 0x100f00f00f00f00fULL;
  x = (x | x << 4) & 0x10c30c30c30c30c3ULL;
  x = (x | x << 2) & 0x1249249249249249ULL;
  return x;
}

// Inverse of spread_bits: gathers bits 0, 3, 6, ... into the low 21 bits.
uint32_t compact_bits(uint64_t x) {
  x &= 0x1249249249249249ULL;
  x = (x ^ (x >> 2)) & 0x10c30c30c30c30c3ULL;
  x = (x ^ (x >> 4)) & 0x100f00f00f00f00fULL;
  x = (x ^ (x >> 8)) & 0x1f0000ff0000ffULL;
  x = (x ^ (x >> 16)) & 0x1f00000000ffffULL;
  x = (x ^ (x >> 32)) & 0x1fffffULL;
  return uint32_t(x);
}

uint32_t quantise(double v, double origin, double scale) {
  double q = (v - origin) * scale;
  if (!(q > 0)) return 0;  // also catches NaN
  if (q >= double(kHilbertMaxCoord)) return kHilbertMaxCoord;
  return uint32_t(q);
}

// Skilling's AxestoTranspose: the reference encoder the lookup tables are derived from.
uint64_t skilling_encode(uint32_t x, uint32_t y, uint32_t z) {
  uint32_t X[3] = {x & kHilbertMaxCoord, y & kHilbertMaxCoord, z & kHilbertMaxCoord};
  // Branch-free "inverse undo" of the excess work...
  for (uint32_t Q = uint32_t(1) << (kHilbertBits - 1); Q > 1; Q >>= 1) {
    const uint32_t P = Q - 1;
    for (int i = 0; i < 3; ++i) {
      const uint32_t set = 0u - ((X[i] & Q) != 0);  // all ones when bit Q of X[i] is set
      X[0] ^= P & set;                              // invert low bits of X[0]
      const uint32_t t = (X[0] ^ X[i]) & P & ~set;  // or exchange low bits of X[0] and X[i]
      X[0] ^= t;
      X[i] ^= t;
    }
  }
  // ...then Gray encode.
  X[1] ^= X[0];
  X[2] ^= X[1];
  uint32_t t = 0;
  for (uint32_t Q = uint32_t(1) << (kHilbertBits - 1); Q > 1; Q >>= 1)
    if (X[2] & Q) t ^= Q - 1;
  for (uint32_t& c : X) c ^= t;
  // The transposed index holds the key's bits round-robin, X[0] first (most significant).
  return (spread_bits(X[0]) << 2) | (spread_bits(X[1]) << 1) | spread_bits(X[2]);
}

// Table-driven encoder, ~10x faster than the bit loop. A Hilbert curve is self-similar: each cell
// is traversed in one of a few orientations ("states"); the state and the child octant give the
// next key digit and the child's state. The tables are read off skilling_encode itself, so the
// two encoders agree by construction (and hilbert_decode, Skilling's inverse, undoes both).
struct HilbertTables {
  static constexpr int kMaxStates = 48;  // orientations of a cube
  int root = 0;
  uint8_t digit1[kMaxStates][8];  // one level: octant (x y z bits) → key digit, next state
  uint8_t next1[kMaxStates][8];
  // Three levels per step (21 = 7·3): 9 bits of the Morton code (x2 y2 z2 x1 y1 z1 x0 y0 z0)
  // → 9 key bits and the next state. ≤ 72 KiB, cache-resident during a bulk encode.
  uint16_t digits3[kMaxStates][512];
  uint8_t next3[kMaxStates][512];
};

// Coordinates of child `octant` (bits x y z) of the node at `depth` with corner `p`.
std::array<uint32_t, 3> child(std::array<uint32_t, 3> p, int depth, int octant) {
  const uint32_t bit = uint32_t(1) << (kHilbertBits - 1 - depth);
  if (octant & 4) p[0] |= bit;
  if (octant & 2) p[1] |= bit;
  if (octant & 1) p[2] |= bit;
  return p;
}

// Key digit (3 bits) of the cell at `depth` + 1 holding point p.
int digit_at(std::array<uint32_t, 3> p, int depth) {
  return int(skilling_encode(p[0], p[1], p[2]) >> (3 * (kHilbertBits - 1 - depth))) & 7;
}

// How a node orders its children and grandchildren: identifies its orientation.
std::array<uint8_t, 72> signature(std::array<uint32_t, 3> p, int depth) {
  std::array<uint8_t, 72> sig{};
  for (int o = 0; o < 8; ++o) {
    auto c = child(p, depth, o);
    sig[o] = uint8_t(digit_at(c, depth));
    for (int g = 0; g < 8; ++g) sig[8 + 8 * o + g] = uint8_t(digit_at(child(c, depth + 1, g), depth + 1));
  }
  return sig;
}

HilbertTables derive_tables() {
  HilbertTables t{};
  struct Node {
    std::array<uint32_t, 3> corner;
    int depth;
  };
  std::vector<std::array<uint8_t, 72>> sigs;
  std::vector<Node> reps;  // one node of each state, in discovery order
  auto state_of = [&](const Node& n) {
    auto sig = signature(n.corner, n.depth);
    auto it = std::find(sigs.begin(), sigs.end(), sig);
    if (it != sigs.end()) return int(it - sigs.begin());
    sigs.push_back(sig);
    reps.push_back(n);
    return int(sigs.size() - 1);
  };
  t.root = state_of({{0, 0, 0}, 0});
  for (size_t s = 0; s < reps.size(); ++s) {
    if (s >= size_t(HilbertTables::kMaxStates)) throw std::logic_error("hilbert: too many curve states");
    const Node n = reps[s];
    for (int o = 0; o < 8; ++o) {
      t.digit1[s][o] = sigs[s][o];
      t.next1[s][o] = uint8_t(state_of({child(n.corner, n.depth, o), n.depth + 1}));
    }
  }
  for (size_t s = 0; s < reps.size(); ++s)
    for (int o = 0; o < 512; ++o) {
      const int s1 = t.next1[s][o >> 6], s2 = t.next1[s1][(o >> 3) & 7];
      t.digits3[s][o] = uint16_t(t.digit1[s][o >> 6] << 6 | t.digit1[s1][(o >> 3) & 7] << 3 | t.digit1[s2][o & 7]);
      t.next3[s][o] = t.next1[s2][o & 7];
    }
  return t;
}

const HilbertTables& tables() {
  static const HilbertTables t = derive_tables();
  return t;
}

// The key of cell (x, y, z): its Morton code read three levels (9 bits) at a time through the
// state machine.
static_assert(kHilbertBits % 3 == 0, "encode() consumes three levels per step");
uint64_t encode(const HilbertTables& t, uint32_t x, uint32_t y, uint32_t z) {
  const uint64_t morton = spread_bits(x) << 2 | spread_bits(y) << 1 | spread_bits(z);
  uint64_t key = 0;
  int state = t.root;
  for (int step = kHilbertBits / 3 - 1; step >= 0; --step) {
    const uint32_t o = uint32_t(morton >> (9 * step)) & 511;
    key = key << 9 | t.digits3[state][o];
    state = t.next3[state][o];
  }
  return key;
}

}  // namespace

uint64_t hilbert_encode(uint32_t x, uint32_t y, uint32_t z) { return encode(tables(), x, y, z); }

std::array<uint32_t, 3> hilbert_decode(uint64_t key) {
  uint32_t X[3] = {compact_bits(key >> 2), compact_bits(key >> 1), compact_bits(key)};
  // Skilling's TransposetoAxes: Gray decode by H ^ (H/2)...
  uint32_t t = X[2] >> 1;
  X[2] ^= X[1];
  X[1] ^= X[0];
  X[0] ^= t;
  // ...then undo the excess work.
  for (uint32_t Q = 2; Q != (uint32_t(1) << kHilbertBits); Q <<= 1) {
    const uint32_t P = Q - 1;
    for (int i = 2; i >= 0; --i) {
      if (X[i] & Q) {
        X[0] ^= P;
      } else {
        t = (X[0] ^ X[i]) & P;
        X[0] ^= t;
        X[i] ^= t;
      }
    }
  }
  return {X[0], X[1], X[2]};
}

HilbertGrid make_hilbert_grid(const float bbox_min[3], const float bbox_max[3]) {
  HilbertGrid g;
  double extent = 0;
  for (int k = 0; k < 3; ++k) {
    g.origin[k] = std::isfinite(bbox_min[k]) ? double(bbox_min[k]) : 0.0;
    double e = double(bbox_max[k]) - double(bbox_min[k]);
    if (std::isfinite(e) && e > extent) extent = e;
  }
  // 2^21 cells across the largest extent; quantise() clamps the far face into the last cell.
  g.scale = extent > 0 ? double(uint32_t(1) << kHilbertBits) / extent : 0.0;
  return g;
}

uint64_t hilbert_key(const HilbertGrid& grid, const float position[3]) {
  return hilbert_encode(quantise(position[0], grid.origin[0], grid.scale),
                        quantise(position[1], grid.origin[1], grid.scale),
                        quantise(position[2], grid.origin[2], grid.scale));
}

void hilbert_keys(std::span<const float> positions, const HilbertGrid& grid, std::span<uint64_t> keys) {
  assert(keys.size() * 3 <= positions.size());
  const HilbertTables& t = tables();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, keys.size(), 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t v = r.begin(); v != r.end(); ++v) {
      const float* p = &positions[3 * v];
      keys[v] = encode(t, quantise(p[0], grid.origin[0], grid.scale), quantise(p[1], grid.origin[1], grid.scale),
                       quantise(p[2], grid.origin[2], grid.scale));
    }
  });
}

}  // namespace streamcvd
