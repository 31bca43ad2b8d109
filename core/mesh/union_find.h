// Disjoint sets over a parent array: the one union-find of the library (components, boundary
// loops, fans around a vertex, repair groups, chunk-wise pieces). Roots are their set's smallest
// member because the smaller root always wins a join, so parent[x] ≤ x holds throughout: callers
// count classes by "root(x) == x" and number them in one ascending pass (chunked_components.cpp).
// Header-only; the parent storage belongs to the caller (a vector, a scratch span, a stack array).
#pragma once

#include <algorithm>
#include <cstdint>
#include <numeric>
#include <span>
#include <vector>

namespace streamcvd {

/// The root of x's set, halving the path on the way (parent[x] == x for a root). Amortised
/// near-constant time; writes `parent`, so not thread-safe on shared storage.
template <class Index>
Index set_root(std::span<Index> parent, Index x) {
  while (parent[x] != x) x = parent[x] = parent[parent[x]];
  return x;
}

/// Joins the sets of a and b; the smaller root becomes the parent of the larger. Returns false
/// when they were already one set. Amortised near-constant time.
template <class Index>
bool join_sets(std::span<Index> parent, Index a, Index b) {
  a = set_root(parent, a);
  b = set_root(parent, b);
  if (a == b) return false;
  parent[std::max(a, b)] = std::min(a, b);
  return true;
}

/// Makes every element its own set: parent[x] = x. O(n).
template <class Index>
void reset_sets(std::span<Index> parent) {
  std::iota(parent.begin(), parent.end(), Index(0));
}

/// The same on a vector, for brevity at the call sites.
template <class Index>
Index set_root(std::vector<Index>& parent, Index x) {
  return set_root(std::span<Index>(parent), x);
}
template <class Index>
bool join_sets(std::vector<Index>& parent, Index a, Index b) {
  return join_sets(std::span<Index>(parent), a, b);
}

/// Disjoint sets that own their parent array (n · sizeof(Index) bytes), for the callers that do
/// not keep it in a scratch of their own.
template <class Index = uint32_t>
struct DisjointSets {
  std::vector<Index> parent;
  explicit DisjointSets(size_t n) : parent(n) { reset_sets(std::span<Index>(parent)); }
  Index find(Index x) { return set_root(parent, x); }
  bool unite(Index a, Index b) { return join_sets(parent, a, b); }
};

}  // namespace streamcvd
