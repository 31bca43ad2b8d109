// Chunk-wise union-find (core/mesh/chunked_components.h). Pieces are labelled inside each range with
// a union-find whose parent pointers only point down (the smaller root wins), which lets one
// ascending pass turn the forest into piece numbers in place. The merge is the same trick over
// global piece ids, with the frontier records as its edges: a record (u, p) of range c says that
// piece p of c touches vertex u of an earlier range c', whose own export lists u's piece there.
#include "streamcvd/core/mesh/chunked_components.h"
#include "streamcvd/core/mesh/errors.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <stdexcept>
#include <string>

namespace streamcvd {
namespace {

// Parent pointers with parent[x] ≤ x (roots: parent[x] == x; kNoComponent: absent) become
// labels 0, 1, ... in order of each class's smallest member, in place: when x is reached, every
// y < x already holds its class's label, and x's parent is either x (a new class) or such a y.
uint32_t label_in_place(std::span<uint32_t> parent) {
  uint32_t next = 0;
  for (size_t x = 0; x < parent.size(); ++x) {
    const uint32_t p = parent[x];
    if (p == kNoComponent) continue;
    parent[x] = p == x ? next++ : parent[p];
  }
  return next;
}

// The export record of vertex v in `p`, or null.
const FrontierTie* exported_tie(const RangePieces& p, uint32_t v) {
  auto it = std::lower_bound(p.exported.begin(), p.exported.end(), FrontierTie{v, 0});
  return it != p.exported.end() && it->vertex == v ? &*it : nullptr;
}

void sort_unique(std::vector<FrontierTie>& a) {
  std::sort(a.begin(), a.end());
  a.erase(std::unique(a.begin(), a.end()), a.end());
}

}  // namespace

void RangePieceBuilder::begin(VertexRange range) {
  range_ = range;
  parent_.assign(range.size(), kNoComponent);
  imported_.clear();
  exported_.clear();
}

RangePieces RangePieceBuilder::finish(std::span<uint32_t> piece_of) {
  RangePieces out;
  out.pieces = label_in_place(parent_);
  if (!piece_of.empty()) std::copy(parent_.begin(), parent_.end(), piece_of.begin());
  for (FrontierTie& t : imported_) t.piece = parent_[t.piece];  // local vertex → its piece
  sort_unique(imported_);
  out.imported.assign(imported_.begin(), imported_.end());
  std::sort(exported_.begin(), exported_.end());
  exported_.erase(std::unique(exported_.begin(), exported_.end()), exported_.end());
  out.exported.resize(exported_.size());
  for (size_t i = 0; i < exported_.size(); ++i)
    out.exported[i] = {range_.begin + exported_[i], parent_[exported_[i]]};
  return out;
}

ComponentTable merge_range_pieces(std::span<const VertexRange> ranges, std::span<const RangePieces> pieces) {
  if (ranges.size() != pieces.size()) throw std::logic_error("merge_range_pieces: one RangePieces per range");
  for (size_t i = 1; i < ranges.size(); ++i)
    if (ranges[i].begin != ranges[i - 1].end || ranges[i].end < ranges[i].begin)
      throw std::logic_error("merge_range_pieces: range " + std::to_string(i) + " does not continue the previous one");
  ComponentTable t;
  t.piece_base.resize(ranges.size() + 1, 0);
  uint64_t total = 0;
  for (size_t i = 0; i < ranges.size(); ++i) {
    if (pieces[i].pieces > ranges[i].size()) throw std::logic_error("merge_range_pieces: more pieces than vertices");
    t.piece_base[i] = uint32_t(total);
    total += pieces[i].pieces;
    t.frontier_records += pieces[i].exported.size() + pieces[i].imported.size();
  }
  t.piece_base[ranges.size()] = uint32_t(total);
  std::vector<uint32_t>& parent = t.component_of_piece;
  parent.resize(total);
  reset_sets(std::span<uint32_t>(parent));
  auto range_of = [&](uint32_t v) {
    // Last range beginning at or before v.
    auto it = std::upper_bound(ranges.begin(), ranges.end(), v, [](uint32_t x, const VertexRange& r) { return x < r.begin; });
    return size_t(it - ranges.begin()) - 1;
  };
  // Every record must find its counterpart: an import the export of the vertex it names, and
  // every export some import (`matched`, one flag per export), or the joins were one-sided and
  // the count would be silently wrong.
  std::vector<uint64_t> export_base(ranges.size() + 1, 0);
  for (size_t c = 0; c < ranges.size(); ++c) export_base[c + 1] = export_base[c] + pieces[c].exported.size();
  std::vector<bool> matched(export_base.back(), false);
  for (size_t c = 0; c < ranges.size(); ++c) {
    for (const FrontierTie& rec : pieces[c].imported) {
      const size_t other = rec.vertex < ranges.front().begin ? c : range_of(rec.vertex);
      const FrontierTie* there = other < c ? exported_tie(pieces[other], rec.vertex) : nullptr;
      if (!there)
        throw std::logic_error("chunked components: range " + std::to_string(c) + " joins vertex " +
                               std::to_string(rec.vertex) + ", which does not join it back (joins must be symmetric)");
      matched[export_base[other] + uint64_t(there - pieces[other].exported.data())] = true;
      join_sets(parent, t.piece_base[c] + rec.piece, t.piece_base[other] + there->piece);  // parents point down
    }
  }
  if (auto it = std::find(matched.begin(), matched.end(), false); it != matched.end()) {
    const uint64_t i = uint64_t(it - matched.begin());
    const size_t c = size_t(std::upper_bound(export_base.begin(), export_base.end(), i) - export_base.begin()) - 1;
    throw std::logic_error("chunked components: vertex " + std::to_string(pieces[c].exported[i - export_base[c]].vertex) +
                           " joins a later range that does not join it back (joins must be symmetric)");
  }
  t.components = label_in_place(parent);
  return t;
}

std::vector<VertexRange> chunk_ranges(std::span<const Chunk> chunks, uint32_t max_vertices, uint32_t min_ranges) {
  std::vector<VertexRange> out;
  const uint64_t per_chunk = chunks.empty() ? 1 : (uint64_t(min_ranges) + chunks.size() - 1) / chunks.size();
  for (const Chunk& c : chunks) {
    const uint64_t n = c.vertex_end - c.vertex_begin;
    const uint64_t by_size = max_vertices == 0 ? 1 : (n + max_vertices - 1) / max_vertices;
    const uint64_t parts = std::clamp<uint64_t>(std::max(by_size, per_chunk), 1, std::max<uint64_t>(n, 1));
    for (uint64_t k = 0; k < parts; ++k)
      out.push_back({uint32_t(c.vertex_begin + n * k / parts), uint32_t(c.vertex_begin + n * (k + 1) / parts)});
  }
  return out;
}

namespace {

// Each range filled by a builder of its thread; with `labels`, its piece ids are written there.
std::vector<RangePieces> fill_ranges(std::span<const VertexRange> ranges, const RangeFill& fill,
                                     std::span<uint32_t> labels) {
  std::vector<RangePieces> pieces(ranges.size());
  tbb::enumerable_thread_specific<RangePieceBuilder> builders;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, ranges.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    RangePieceBuilder& b = builders.local();
    for (size_t i = r.begin(); i != r.end(); ++i) {
      b.begin(ranges[i]);
      fill(i, ranges[i], b);
      pieces[i] = labels.empty() ? b.finish() : b.finish(labels.subspan(ranges[i].begin, ranges[i].size()));
    }
  });
  return pieces;
}

}  // namespace

ComponentTable chunked_components(std::span<const VertexRange> ranges, const RangeFill& fill) {
  return merge_range_pieces(ranges, fill_ranges(ranges, fill, {}));
}

ComponentTable chunked_component_labels(std::span<const VertexRange> ranges, const RangeFill& fill,
                                        std::span<uint32_t> component_of_vertex) {
  const std::vector<RangePieces> pieces = fill_ranges(ranges, fill, component_of_vertex);
  ComponentTable table = merge_range_pieces(ranges, pieces);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, ranges.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i)
      for (uint32_t v = ranges[i].begin; v < ranges[i].end; ++v) {
        uint32_t& c = component_of_vertex[v];
        if (c != kNoComponent) c = table.component(i, c);
      }
  });
  return table;
}

std::vector<VertexRange> chunk_vertex_blocks(const MeshView& mesh) {
  const uint32_t V = mesh.vertex_count();
  if (mesh.chunks.empty()) {
    Chunk whole;
    whole.vertex_end = V;
    return V > 0 ? chunk_ranges(std::span<const Chunk>(&whole, 1)) : std::vector<VertexRange>{};
  }
  uint32_t next = 0;
  for (const Chunk& c : mesh.chunks) {
    if (c.vertex_begin != next || c.vertex_end < c.vertex_begin) throw InputError("mesh view: the chunks do not tile the vertices");
    next = c.vertex_end;
  }
  if (next != V) throw InputError("mesh view: the chunks do not cover the vertices");
  return chunk_ranges(mesh.chunks);
}

}  // namespace streamcvd
