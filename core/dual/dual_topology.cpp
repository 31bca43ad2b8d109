// Dual triples by chunks, their merge with the strip faces, and the fan test
// (core/dual/dual_topology.h).
#include "streamcvd/core/dual/dual_topology.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <iterator>
#include <numeric>
#include <stdexcept>
#include <string>

#include "streamcvd/core/mesh/errors.h"

namespace streamcvd::dual {

namespace {

// The pair {a, b} of two distinct ids, packed smaller first (a << 32 | b for a < b).
inline uint64_t pair_key(uint32_t a, uint32_t b) { return uint64_t(std::min(a, b)) << 32 | std::max(a, b); }

// Drops most repeats of a pair before a list of pairs is sorted: a pair of clusters repeats
// along their whole frontier, once per edge or face there. A direct-mapped table of the last
// pairs seen; the list is sort_unique'd afterwards as before, so the result is the same
// (dragon ×9 → 300,000: the pairs' sorts took 2.8 % of the run's samples).
class RecentPairs {
 public:
  RecentPairs() { slots_.fill(~uint64_t(0)); }  // no pair of ids below 2^31 has all bits set
  /// Whether `key` is not among the recent pairs (it is now). O(1).
  bool fresh(uint64_t key) {
    uint64_t& slot = slots_[(key * 0x9E3779B97F4A7C15ull) >> 56];
    if (slot == key) return false;
    slot = key;
    return true;
  }

 private:
  std::array<uint64_t, 256> slots_;
};

// sort_unique with a parallel sort, for the merged lists (D-sized).
template <class T>
void parallel_sort_unique(std::vector<T>& v) {
  tbb::parallel_sort(v.begin(), v.end());
  v.erase(std::unique(v.begin(), v.end()), v.end());
}

// Keeps one copy of each face of `sorted` and appends the others to `repeats`. O(n).
void move_repeats(std::vector<Face>& sorted, std::vector<Face>& repeats) {
  size_t kept = 0;
  for (size_t i = 0; i < sorted.size(); ++i) {
    if (kept > 0 && sorted[i] == sorted[kept - 1]) repeats.push_back(sorted[i]);
    else sorted[kept++] = sorted[i];
  }
  sorted.resize(kept);
}

// Concatenates the blocks' faces (each sorted and unique) and their repeats, and splits the
// result into unique faces and repeats, both sorted.
void merge_blocks(std::vector<std::vector<Face>>& found, std::vector<std::vector<Face>>& block_repeats,
                  std::vector<Face>& faces, std::vector<Face>& repeats) {
  size_t total = 0, total_repeats = 0;
  for (size_t i = 0; i < found.size(); ++i) total += found[i].size(), total_repeats += block_repeats[i].size();
  faces.reserve(faces.size() + total);
  for (std::vector<Face>& f : found) {  // block order
    faces.insert(faces.end(), f.begin(), f.end());
    std::vector<Face>().swap(f);
  }
  tbb::parallel_sort(faces.begin(), faces.end());
  repeats.reserve(repeats.size() + total_repeats);
  move_repeats(faces, repeats);  // a face two blocks gave
  for (std::vector<Face>& r : block_repeats) repeats.insert(repeats.end(), r.begin(), r.end());
  std::sort(repeats.begin(), repeats.end());
}


}  // namespace

std::vector<FaceRange> chunk_face_blocks(const MeshView& mesh, uint64_t max_faces) {
  const uint64_t F = mesh.face_count();
  std::vector<FaceRange> out;
  auto cut = [&](uint64_t begin, uint64_t end) {
    const uint64_t n = end - begin, parts = std::max<uint64_t>(1, (n + max_faces - 1) / std::max<uint64_t>(max_faces, 1));
    for (uint64_t k = 0; k < parts; ++k) out.push_back({begin + n * k / parts, begin + n * (k + 1) / parts});
  };
  if (mesh.chunks.empty()) {
    if (F > 0) cut(0, F);
    return out;
  }
  uint64_t next = 0;
  for (const Chunk& c : mesh.chunks) {
    if (c.face_begin != next || c.face_end < c.face_begin)
      throw InputError("dual mesh: the chunks' owned faces do not tile the faces (chunk at face " + std::to_string(c.face_begin) +
                       ", expected " + std::to_string(next) + ")");
    if (c.face_end > c.face_begin) cut(c.face_begin, c.face_end);
    next = c.face_end;
  }
  if (next != F)
    throw InputError("dual mesh: the chunks own " + std::to_string(next) + " faces of " + std::to_string(F));
  return out;
}

std::vector<uint32_t> cluster_sizes(const MeshView& mesh, std::span<const int32_t> labels, uint32_t cluster_count) {
  if (labels.size() != mesh.vertex_count())
    throw std::invalid_argument("cluster_sizes: " + std::to_string(labels.size()) + " labels for " +
                                std::to_string(mesh.vertex_count()) + " vertices");
  std::vector<uint32_t> size(cluster_count, 0);
  const std::vector<VertexRange> ranges = chunk_vertex_blocks(mesh);
  // Integer counts: the same whatever the order of the increments.
  tbb::parallel_for(tbb::blocked_range<size_t>(0, ranges.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      const RangeVisit visit(mesh, "dual", ranges[i], kReadsWorkArrays);  // labels only
      for (uint32_t v = ranges[i].begin; v < ranges[i].end; ++v)
        if (labels[v] >= 0) std::atomic_ref<uint32_t>(size[labels[v]]).fetch_add(1, std::memory_order_relaxed);
    }
  });
  return size;
}

void merge_faces(std::vector<Face>& faces, std::vector<Face> more) {
  std::sort(more.begin(), more.end());
  const size_t before = faces.size();
  faces.insert(faces.end(), more.begin(), more.end());
  std::inplace_merge(faces.begin(), faces.begin() + std::ptrdiff_t(before), faces.end());
  faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
}

Triples collect_triples(const MeshView& mesh, std::span<const int32_t> labels, bool neighbour_pairs) {
  const std::vector<FaceRange> blocks = chunk_face_blocks(mesh);
  std::vector<std::vector<Face>> found(blocks.size()), block_repeats(blocks.size());
  std::vector<std::vector<uint64_t>> pairs(neighbour_pairs ? blocks.size() : 0);
  const uint32_t* T = mesh.triangles.data();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      std::vector<Face>& out = found[i];
      Face t;
      if (blocks[i].end <= blocks[i].begin) continue;
      // Faces are sorted by owner (their least corner): the block's owners form one range.
      const VertexRange owners{face_owner(mesh.triangles, blocks[i].begin), face_owner(mesh.triangles, blocks[i].end - 1) + 1};
      const RangeVisit visit(mesh, "dual", owners, kReadsTriangles);
      for (uint64_t f = blocks[i].begin; f < blocks[i].end; ++f)
        if (face_triple(T + 3 * f, labels, t)) out.push_back(t);
      if (neighbour_pairs) {  // every input edge is an edge of a face: the faces give them all
        std::vector<uint64_t>& p = pairs[i];
        RecentPairs recent;
        for (uint64_t f = blocks[i].begin; f < blocks[i].end; ++f)
          for (int k = 0; k < 3; ++k) {
            const int32_t a = labels[T[3 * f + k]], b = labels[T[3 * f + (k + 1) % 3]];
            if (a < 0 || b < 0 || a == b) continue;
            if (const uint64_t key = pair_key(uint32_t(a), uint32_t(b)); recent.fresh(key)) p.push_back(key);
          }
        sort_unique(p);
      }
      std::sort(out.begin(), out.end());
      move_repeats(out, block_repeats[i]);
    }
  });
  Triples result;
  merge_blocks(found, block_repeats, result.faces, result.repeats);
  for (std::vector<uint64_t>& p : pairs) {
    result.neighbour_pairs.insert(result.neighbour_pairs.end(), p.begin(), p.end());
    std::vector<uint64_t>().swap(p);
  }
  parallel_sort_unique(result.neighbour_pairs);
  return result;
}

std::vector<Face> triples_around(const MeshView& mesh, std::span<const int32_t> labels,
                                 std::span<const uint32_t> vertices, std::span<const uint8_t> in_set,
                                 std::vector<Face>* repeats) {
  constexpr size_t kBlock = 4096;
  const size_t blocks = (vertices.size() + kBlock - 1) / kBlock;
  std::vector<std::vector<Face>> found(blocks), block_repeats(blocks);
  const uint32_t* T = mesh.triangles.data();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks, 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t b = r.begin(); b != r.end(); ++b) {
      std::vector<Face>& out = found[b];
      Face t;
      for (size_t i = b * kBlock; i < std::min(vertices.size(), (b + 1) * kBlock); ++i) {
        const uint32_t v = vertices[i];
        for (uint32_t f : mesh.faces_of(v)) {
          const uint32_t* c = T + 3 * size_t(f);
          if (!face_triple(c, labels, t)) continue;
          // Each face once: from its first corner in the set.
          const int first = in_set[labels[c[0]]] ? 0 : in_set[labels[c[1]]] ? 1 : 2;
          if (c[first] == v) out.push_back(t);
        }
      }
      std::sort(out.begin(), out.end());
      move_repeats(out, block_repeats[b]);
    }
  });
  std::vector<Face> faces, dropped;
  merge_blocks(found, block_repeats, faces, repeats ? *repeats : dropped);
  return faces;
}

void replace_triples(Triples& triples, std::span<const uint8_t> in_set, std::vector<Face> faces,
                     std::vector<Face> repeats) {
  auto replace = [&](std::vector<Face>& kept, std::vector<Face>& added) {
    std::erase_if(kept, [&](const Face& f) { return in_set[f[0]] | in_set[f[1]] | in_set[f[2]]; });
    const size_t before = kept.size();
    kept.insert(kept.end(), added.begin(), added.end());
    std::inplace_merge(kept.begin(), kept.begin() + std::ptrdiff_t(before), kept.end());
  };
  // The faces left have no corner in the set and the added ones all have one: no face is in both.
  replace(triples.faces, faces);
  replace(triples.repeats, repeats);
}

std::vector<uint64_t> unjoined_pairs(std::span<const uint64_t> neighbour_pairs, std::span<const Face> faces,
                                     uint32_t cluster_count) {
  std::vector<uint64_t> edges;  // dual edges between clusters, packed min << 32 | max
  edges.reserve(3 * faces.size());
  for (const Face& f : faces)
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = f[k], b = f[(k + 1) % 3];
      if (a < cluster_count && b < cluster_count) edges.push_back(pair_key(a, b));
    }
  parallel_sort_unique(edges);
  std::vector<uint64_t> missing;
  std::set_difference(neighbour_pairs.begin(), neighbour_pairs.end(), edges.begin(), edges.end(),
                      std::back_inserter(missing));
  return missing;
}

std::vector<uint64_t> neighbour_pairs_around(const MeshView& mesh, std::span<const int32_t> labels,
                                             std::span<const uint32_t> vertices) {
  constexpr size_t kBlock = 4096;
  const size_t blocks = (vertices.size() + kBlock - 1) / kBlock;
  std::vector<std::vector<uint64_t>> found(blocks);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks, 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t b = r.begin(); b != r.end(); ++b) {
      std::vector<uint64_t>& out = found[b];
      RecentPairs recent;
      for (size_t i = b * kBlock; i < std::min(vertices.size(), (b + 1) * kBlock); ++i) {
        const int32_t a = labels[vertices[i]];
        if (a < 0) continue;
        for (uint32_t n : mesh.neighbours(vertices[i])) {
          if (labels[n] < 0 || labels[n] == a) continue;
          if (const uint64_t key = pair_key(uint32_t(a), uint32_t(labels[n])); recent.fresh(key)) out.push_back(key);
        }
      }
      sort_unique(out);  // a pair repeats along a whole frontier
    }
  });
  std::vector<uint64_t> pairs;
  for (const std::vector<uint64_t>& f : found) pairs.insert(pairs.end(), f.begin(), f.end());
  sort_unique(pairs);
  return pairs;
}

namespace {

struct FanShape {
  bool edges_manifold = true;  // every edge at x in at most two faces, one each way
  bool closed = true;          // every edge at x in two faces
  uint32_t fans = 0;
};

// The fans round x: faces joined through their shared edges at x. Stops at the first edge
// that is not manifold. O(n log n) for n faces.
FanShape fan_shape(uint32_t x, std::span<const Face> faces, FanScratch& scratch) {
  // One 64-bit key per (face, edge at x): the other end of the edge, the face, and whether the
  // face runs x → other (1) or other → x (0); sorted, a run of keys is one edge at x.
  auto& entries = scratch.entries;
  entries.clear();
  for (uint32_t i = 0; i < faces.size(); ++i) {
    const Face& t = faces[i];
    const int k = t[0] == x ? 0 : t[1] == x ? 1 : 2;
    entries.push_back(uint64_t(t[(k + 1) % 3]) << 32 | uint64_t(i) << 1 | 1u);  // x → next
    entries.push_back(uint64_t(t[(k + 2) % 3]) << 32 | uint64_t(i) << 1);       // previous → x
  }
  std::sort(entries.begin(), entries.end());
  auto& parent = scratch.parent;
  parent.resize(faces.size());
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](uint32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  FanShape shape;
  shape.fans = uint32_t(faces.size());
  for (size_t i = 0; i < entries.size();) {
    size_t j = i;
    uint32_t out = 0;
    while (j < entries.size() && entries[j] >> 32 == entries[i] >> 32) out += uint32_t(entries[j++] & 1);
    const size_t n = j - i, in = n - out;
    if (n > 2 || out == 2 || in == 2) {
      shape.edges_manifold = false;
      return shape;
    }
    if (n == 2) {
      const uint32_t a = find(uint32_t(entries[i]) >> 1), b = find(uint32_t(entries[i + 1]) >> 1);
      if (a != b) {
        parent[a] = b;
        --shape.fans;
      }
    } else {
      shape.closed = false;
    }
    i = j;
  }
  return shape;
}

}  // namespace

bool fan_defective(uint32_t x, std::span<const Face> faces, FanScratch& scratch) {
  const FanShape shape = fan_shape(x, faces, scratch);
  if (!shape.edges_manifold || shape.fans != 1) return true;
  // Two faces on one vertex set {x, y, z} hold both edges x-y and x-z, which then have no other
  // face: past the tests above they are the whole fan. So only a fan of two faces can hold them.
  if (faces.size() != 2) return false;
  Face a = faces[0], b = faces[1];
  std::sort(a.begin(), a.end());
  std::sort(b.begin(), b.end());
  return a == b;
}

std::vector<std::vector<uint32_t>> closed_fans(uint32_t x, std::span<const Face> faces, FanScratch& scratch) {
  const FanShape shape = fan_shape(x, faces, scratch);
  if (!shape.edges_manifold || !shape.closed) return {};
  // Faces by fan (the root of each face in fan_shape's union-find), then each fan's link.
  std::vector<std::pair<uint32_t, uint32_t>> fan_of;  // (root, face)
  for (uint32_t i = 0; i < faces.size(); ++i) {
    uint32_t r = i;
    while (scratch.parent[r] != r) r = scratch.parent[r];
    fan_of.push_back({r, i});
  }
  std::sort(fan_of.begin(), fan_of.end());
  std::vector<std::vector<uint32_t>> fans;
  for (size_t i = 0; i < fan_of.size(); ++i) {
    if (i == 0 || fan_of[i].first != fan_of[i - 1].first) fans.emplace_back();
    for (uint32_t y : faces[fan_of[i].second])
      if (y != x) fans.back().push_back(y);
  }
  for (std::vector<uint32_t>& link : fans) sort_unique(link);
  return fans;
}

std::vector<FanVerdict> check_fan_csr(std::span<const Face> faces, std::span<const uint32_t> ids,
                                      std::span<const uint32_t> offsets, std::span<const uint32_t> face_of) {
  const uint32_t n = offsets.empty() ? 0 : uint32_t(offsets.size() - 1);
  constexpr uint32_t kBlock = 4096;
  const uint32_t blocks = (n + kBlock - 1) / kBlock;
  std::vector<std::vector<FanVerdict>> verdicts(blocks);
  tbb::enumerable_thread_specific<std::pair<FanScratch, std::vector<Face>>> scratch;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, blocks, 1), [&](const tbb::blocked_range<uint32_t>& r) {
    auto& [fan_scratch, fan] = scratch.local();
    for (uint32_t b = r.begin(); b != r.end(); ++b)
      for (uint32_t x = b * kBlock; x < std::min(n, (b + 1) * kBlock); ++x) {
        if (offsets[x] == offsets[x + 1]) continue;
        fan.clear();
        for (uint32_t i = offsets[x]; i < offsets[x + 1]; ++i) fan.push_back(faces[face_of[i]]);
        const uint32_t id = ids.empty() ? x : ids[x];
        verdicts[b].push_back({id, fan_defective(id, fan, fan_scratch)});
      }
  });
  std::vector<FanVerdict> out;
  for (const auto& v : verdicts) out.insert(out.end(), v.begin(), v.end());
  return out;
}

}  // namespace streamcvd::dual
