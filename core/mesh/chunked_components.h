// Connected components of a vertex graph in memory bounded by one chunk plus the chunk frontiers
// (DESIGN.md §4: component budgets, cleaning of same-label pieces, topology figures of a store).
//
// A chunk-wise union-find: the vertices come as contiguous ranges (the store's chunks, or any
// tiling of [0, V)). Each range is labelled on its own: a union-find over its vertices, with the
// joins inside it, gives its local *pieces*; the joins that leave it are kept as frontier records
// (which piece here, which vertex there). A small global union-find over (range, piece) ids then
// merges the pieces along those records. Memory: one range's arrays per thread, plus
// O(pieces + frontier) records for the whole graph, never O(V). For scale: the mesh graph of the
// dragon ×11 store (52.7M vertices, 101 chunks) has 573 pieces and 554k records (4.4 MB).
//
// Who joins what is the caller's: it fills each range through a RangePieceBuilder (add a vertex,
// join two vertices), from its own loop over the range, so the graph can be the mesh edges, the
// boundary edges, the edges between same-label vertices...
//
// Numbering: pieces of a range are numbered by their smallest vertex, components by their
// smallest vertex too, whatever the ranges and the threads.
#pragma once

#include <cstdint>
#include <functional>
#include <limits>
#include <span>
#include <vector>

#include "streamcvd/core/mesh/mesh_view.h"
#include "streamcvd/core/mesh/union_find.h"

namespace streamcvd {

/// Label of a vertex that takes no part in the graph (never added nor joined).
inline constexpr uint32_t kNoComponent = std::numeric_limits<uint32_t>::max();

/// (vertex, piece) pair of a frontier record.
struct FrontierTie {
  uint32_t vertex;
  uint32_t piece;
  bool operator<(const FrontierTie& o) const { return vertex != o.vertex ? vertex < o.vertex : piece < o.piece; }
  bool operator==(const FrontierTie&) const = default;
};

/// What one range contributes to the merge.
struct RangePieces {
  uint32_t pieces = 0;
  /// Vertices of this range joined to a vertex of a later range, with their piece; by vertex.
  std::vector<FrontierTie> exported;
  /// Vertices of earlier ranges joined to this range, with the piece here; sorted, unique.
  std::vector<FrontierTie> imported;
};

/// Union-find over the vertices of one range and its frontier records. Reuse one per thread:
/// begin() keeps the arrays' capacity, so a range costs no allocation but finish()'s two
/// exact-size vectors. Memory: 4 bytes per vertex of the largest range, plus its frontier.
/// Not thread-safe (one builder per thread).
class RangePieceBuilder {
 public:
  /// Starts a range: every vertex absent. O(range size).
  void begin(VertexRange range);
  /// Makes v (in the range) a member: alone it is a piece of its own. O(1).
  void add(uint32_t v) {
    const uint32_t l = v - range_.begin;
    if (parent_[l] == kNoComponent) parent_[l] = l;
  }
  /// Joins v (in the range) with u (anywhere); both become members. The joins over all ranges
  /// must be symmetric: when a range joins v to u of another range, u's range joins u to v
  /// (merge_range_pieces checks this). Inside the range join(v, u) and join(u, v) are the same
  /// union, so a caller visiting both ends may skip one (u < v and range().contains(u)).
  /// O(α) inside the range, O(1) amortised across it.
  void join(uint32_t v, uint32_t u) {
    const uint32_t lv = v - range_.begin, lu = u - range_.begin;
    add(v);
    if (lu < range_.size()) {
      if (parent_[lu] == kNoComponent) parent_[lu] = lu;
      unite(lv, lu);
    } else if (u < range_.begin) {
      imported_.push_back({u, lv});
    } else if (exported_.empty() || exported_.back() != lv) {
      exported_.push_back(lv);  // a vertex's joins usually come together: few repeats to sort out
    }
  }
  /// Numbers the pieces and returns them with the frontier records. With a non-empty `piece_of`
  /// (range size entries) also writes each vertex's piece, kNoComponent for non-members.
  /// O(range size + frontier · log frontier).
  RangePieces finish(std::span<uint32_t> piece_of = {});
  /// The range of the last begin().
  VertexRange range() const { return range_; }

 private:
  // The smaller root wins (union_find.h), so parent_[x] ≤ x always: finish() relies on it.
  void unite(uint32_t a, uint32_t b) { join_sets(parent_, a, b); }

  VertexRange range_;
  std::vector<uint32_t> parent_;        // local index → parent, kNoComponent if absent
  std::vector<FrontierTie> imported_;   // (vertex of an earlier range, local vertex here)
  std::vector<uint32_t> exported_;      // local vertices joined to a later range
};

/// Component of every (range, piece): the result of the merge.
struct ComponentTable {
  uint64_t components = 0;
  std::vector<uint32_t> piece_base;          ///< first global piece of each range (ranges + 1 entries)
  std::vector<uint32_t> component_of_piece;  ///< global piece → component id
  uint64_t frontier_records = 0;             ///< exported + imported records merged (a memory figure)
  uint32_t component(size_t range, uint32_t piece) const { return component_of_piece[piece_base[range] + piece]; }
};

/// Merges the pieces of `ranges` (ascending and contiguous; pieces[i] from ranges[i]) into
/// components numbered by their smallest vertex. Serial, O(records · log records + pieces)
/// time, O(pieces + records / 8) memory beyond the inputs; thread-safe (pure). Throws
/// std::logic_error when the ranges do not tile, or a record has no symmetric counterpart.
ComponentTable merge_range_pieces(std::span<const VertexRange> ranges, std::span<const RangePieces> pieces);

/// Ranges for chunk-wise work over a store: its chunks, each cut into equal parts so that no
/// range exceeds max_vertices and there are at least min_ranges when the chunks allow it (a
/// store of few chunks then still runs on every thread). Depends on nothing but the chunk table
/// (not on the thread count). O(ranges); thread-safe (pure).
std::vector<VertexRange> chunk_ranges(std::span<const Chunk> chunks, uint32_t max_vertices = 1u << 20,
                                      uint32_t min_ranges = 16);

/// The ranges of chunk_ranges over a view's chunks (one range of all vertices for a view
/// without chunks), for passes over every vertex. Throws InputError when the chunks do not tile
/// [0, V). O(chunks).
std::vector<VertexRange> chunk_vertex_blocks(const MeshView& mesh);

/// Fills one range: the caller adds/joins the vertices of `range` (called between begin and finish).
using RangeFill = std::function<void(size_t index, VertexRange range, RangePieceBuilder& builder)>;

/// Components of the graph that `fill` describes: fill runs once per range, in parallel (TBB)
/// with one builder per thread, then merge_range_pieces. Memory as the module comment says;
/// time O(V + joins) plus the merge. `fill` must be safe to call concurrently for different ranges.
ComponentTable chunked_components(std::span<const VertexRange> ranges, const RangeFill& fill);

/// Components with per-vertex labels in one union-find pass: each range writes its local piece
/// ids into `component_of_vertex` (V entries, kNoComponent for non-members), the merge numbers
/// the components, and a light pass (no union-find) turns piece ids into component ids. In
/// parallel over the ranges; memory: the caller's array plus one builder per thread.
ComponentTable chunked_component_labels(std::span<const VertexRange> ranges, const RangeFill& fill,
                                        std::span<uint32_t> component_of_vertex);


}  // namespace streamcvd
