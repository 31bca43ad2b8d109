#include "streaming/store_build.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <array>
#include <string>
#include <utility>

#include "core/errors.h"
#include "core/hilbert.h"

namespace streamcvd::store_build {
namespace {

constexpr size_t kGrain = 1 << 14;
constexpr uint32_t kScanBlocks = 64;  // bucket blocks of the parallel prefix sums

// Number of item ranges of counting_sort: one per thread, at most 8, fewer for small inputs
// (each range costs a count array). The output never depends on it.
uint32_t sort_parts(uint64_t items) {
  const int threads = tbb::this_task_arena::max_concurrency();
  return uint32_t(std::clamp<uint64_t>(std::min<uint64_t>(uint64_t(std::max(threads, 1)), 8), 1,
                                       std::max<uint64_t>(1, items >> 16)));
}

// Stable counting sort of items 0..n-1 by bucket_of(i) < buckets: start gets buckets + 1 entries
// (bucket b holds positions [start[b], start[b+1])), and place(i, position) is called once per
// item, in increasing i within each bucket. The items are split into sort_parts() contiguous
// ranges, each counted and placed by one task with its own cursor per bucket (the prefix sum
// runs in (bucket, range) order): one branch-free pass over the input per phase, and the result
// is the unique stable order whatever the number of ranges.
template <typename BucketOf, typename Place>
void counting_sort(uint64_t n, uint32_t buckets, BucketOf bucket_of, DefaultInitVector<uint32_t>& start, Place place) {
  const uint32_t parts = sort_parts(n);
  auto item_begin = [&](uint32_t p) { return n * p / parts; };
  std::vector<std::vector<uint32_t>> cursor(parts);
  tbb::parallel_for(uint32_t(0), parts, [&](uint32_t p) {
    cursor[p].assign(buckets, 0);  // here, so that each task pages in its own array
    for (uint64_t i = item_begin(p); i != item_begin(p + 1); ++i) ++cursor[p][bucket_of(i)];
  });
  // Prefix sum in (bucket, range) order, in parallel over kScanBlocks bucket blocks: their totals,
  // then each block from its base. Integer sums: the same result for any split.
  start.resize(size_t(buckets) + 1);
  auto block_begin = [&](uint32_t k) { return uint32_t(uint64_t(buckets) * k / kScanBlocks); };
  std::array<uint32_t, kScanBlocks + 1> base{};
  tbb::parallel_for(uint32_t(0), kScanBlocks, [&](uint32_t k) {
    uint32_t total = 0;
    for (uint32_t p = 0; p < parts; ++p)
      for (uint32_t b = block_begin(k); b != block_begin(k + 1); ++b) total += cursor[p][b];
    base[k + 1] = total;
  });
  for (uint32_t k = 0; k < kScanBlocks; ++k) base[k + 1] += base[k];
  tbb::parallel_for(uint32_t(0), kScanBlocks, [&](uint32_t k) {
    uint32_t sum = base[k];
    for (uint32_t b = block_begin(k); b != block_begin(k + 1); ++b) {
      start[b] = sum;
      for (uint32_t p = 0; p < parts; ++p) sum += std::exchange(cursor[p][b], sum);
    }
  });
  start[buckets] = base[kScanBlocks];
  tbb::parallel_for(uint32_t(0), parts, [&](uint32_t p) {
    uint32_t* at = cursor[p].data();
    for (uint64_t i = item_begin(p); i != item_begin(p + 1); ++i) place(i, at[bucket_of(i)]++);
  });
}

struct KeyId {
  uint64_t key;
  uint32_t id;
  bool operator<(const KeyId& o) const { return key < o.key || (key == o.key && id < o.id); }
};

// O(n + inversions).
void insertion_sort(KeyId* first, KeyId* last) {
  for (KeyId* i = first + (first != last); i < last; ++i) {
    const KeyId x = *i;
    KeyId* j = i;
    for (; j > first && x < *(j - 1); --j) *j = *(j - 1);
    *j = x;
  }
}

// Insertion sort for the usual few items, std::sort past 32 (many vertices in one cell).
void sort_key_ids(KeyId* first, KeyId* last) {
  if (last - first > 32)
    std::sort(first, last);
  else
    insertion_sort(first, last);
}

// Per-thread scratch of chunk_extras.
struct HaloScratch {
  std::vector<uint32_t> faces, ring1, ring2;
};

void sort_unique(std::vector<uint32_t>& a) {
  std::sort(a.begin(), a.end());
  a.erase(std::unique(a.begin(), a.end()), a.end());
}

// Bounding box and halo face counts of one chunk. halo1 = faces not owned by the chunk that touch
// one of its vertices; halo3 = faces not owned by the chunk within 3 rings: touching a vertex at
// graph distance ≤ 2 from the chunk (their vertices are then all within distance 3). Found by a
// two-step BFS from the chunk's border, O(chunk size + halo size).
void chunk_extras_of(const MeshView& m, Chunk& c, HaloScratch& s) {
  Bbox box = bounding_box(m.positions, c.vertex_begin, c.vertex_end);
  box.finish();
  std::copy(box.lo, box.lo + 3, c.bbox_min);
  std::copy(box.hi, box.hi + 3, c.bbox_max);
  auto outside_v = [&](uint32_t v) { return v < c.vertex_begin || v >= c.vertex_end; };
  auto outside_f = [&](uint64_t f) { return f < c.face_begin || f >= c.face_end; };
  s.faces.clear();
  s.ring1.clear();
  for (uint32_t v = c.vertex_begin; v < c.vertex_end; ++v) {
    // Most vertices are interior: all neighbours (sorted) in the chunk, so all their faces are
    // owned by chunk vertices and in its face range too. Nothing to collect there.
    const std::span<const uint32_t> ring = m.neighbours(v);
    if (!ring.empty() && ring.front() >= c.vertex_begin && ring.back() < c.vertex_end) continue;
    for (uint32_t f : m.faces_of(v))
      if (outside_f(f)) s.faces.push_back(f);
    for (uint32_t u : ring)
      if (outside_v(u)) s.ring1.push_back(u);
  }
  sort_unique(s.faces);
  c.halo1_faces = s.faces.size();
  sort_unique(s.ring1);
  s.ring2.clear();
  for (uint32_t u : s.ring1) {
    for (uint32_t f : m.faces_of(u))
      if (outside_f(f)) s.faces.push_back(f);
    for (uint32_t w : m.neighbours(u))
      if (outside_v(w) && !std::binary_search(s.ring1.begin(), s.ring1.end(), w)) s.ring2.push_back(w);
  }
  sort_unique(s.ring2);
  for (uint32_t w : s.ring2)
    for (uint32_t f : m.faces_of(w))
      if (outside_f(f)) s.faces.push_back(f);
  sort_unique(s.faces);
  c.halo3_faces = s.faces.size();
}

}  // namespace

// Bounding box of the finite coordinates of vertices [begin, end). Parallel, deterministic
// (min/max are exact in any order).
Bbox bounding_box(std::span<const float> positions, size_t begin, size_t end) {
  return tbb::parallel_reduce(
      tbb::blocked_range<size_t>(begin, end, kGrain), Bbox{},
      [&](const tbb::blocked_range<size_t>& r, Bbox b) {
        for (size_t v = r.begin(); v != r.end(); ++v) b.add(&positions[3 * v]);
        return b;
      },
      [](Bbox a, const Bbox& b) {
        a.add(b);
        return a;
      });
}

void check_soup(const TriangleSoupView& soup) {
  if (soup.positions.size() % 3 != 0)
    throw InputError("store build: positions hold " + std::to_string(soup.positions.size()) +
                     " floats, not a multiple of 3");
  if (soup.triangles.size() % 3 != 0)
    throw InputError("store build: triangles hold " + std::to_string(soup.triangles.size()) +
                     " indices, not a multiple of 3");
  const uint64_t v = soup.positions.size() / 3, f = soup.triangles.size() / 3;
  if (v > std::numeric_limits<uint32_t>::max())
    throw InputError("store build: " + std::to_string(v) + " vertices, at most 2^32-1 supported");
  if (f > std::numeric_limits<uint32_t>::max())
    throw InputError("store build: " + std::to_string(f) + " faces, at most 2^32-1 supported");
  uint64_t bad = first_violation(soup.triangles.size(), [&](uint64_t i) { return soup.triangles[i] >= v; });
  if (bad < soup.triangles.size())
    throw InputError("store build: face " + std::to_string(bad / 3) + " uses vertex " +
                     std::to_string(soup.triangles[bad]) + " of " + std::to_string(v));
}

// Input vertex id of each store vertex: sorted by (Hilbert key, input id), the id breaking ties
// so the order is a pure function of the input. A stable counting sort of the ids on the key's
// top octree levels (≈ V/2 buckets, but a surface fills few of them: ~100 vertices each),
// straight into `order`, then a sort of each bucket: O(V) passes instead of a full O(V log V)
// sort, and no (key, id) array for all vertices.
void hilbert_order(std::span<const float> positions, const Bbox& box, std::span<uint32_t> order) {
  const uint32_t n = uint32_t(order.size());
  DefaultInitVector<uint64_t> keys(n);
  hilbert_keys(positions, make_hilbert_grid(box.lo, box.hi), keys);
  int levels = 1;  // octree levels of the bucket index: 8^levels ≈ n/2 buckets, at most 2^21
  while (levels < 7 && (uint64_t(1) << (3 * levels)) < n / 2) ++levels;
  const int shift = 3 * kHilbertBits - 3 * levels;
  DefaultInitVector<uint32_t> start;
  counting_sort(
      n, uint32_t(1) << (3 * levels), [&](uint64_t v) { return uint32_t(keys[v] >> shift); }, start,
      [&](uint64_t v, uint32_t at) { order[at] = uint32_t(v); });
  // Each bucket is sorted on a local copy of its (key, id) pairs: comparisons then read no
  // scattered keys. Insertion sort, after a counting sort on the next levels for big buckets.
  struct Scratch {
    std::vector<KeyId> items;
    std::array<uint32_t, 512> count;
  };
  static_assert(kHilbertBits >= 10, "levels ≤ 7 leave at least 9 key bits below the bucket");
  tbb::enumerable_thread_specific<Scratch> scratch;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, start.size() - 1, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t b = r.begin(); b != r.end(); ++b) {
      const uint32_t first = start[b], count = start[b + 1] - first;
      if (count < 2) continue;
      Scratch& sc = scratch.local();
      std::vector<KeyId>& local = sc.items;
      local.resize(count);
      if (count > 32) {
        // A surface fills few cells of a level-7 bucket's subtree, so buckets hold ~100 vertices:
        // counting sort them on the next three levels first (a surface is sparse there too, so
        // sub-buckets hold ~2), then the insertion sort below only fixes those.
        const int sub_shift = shift - 9;
        sc.count.fill(0);
        for (uint32_t i = 0; i < count; ++i) ++sc.count[(keys[order[first + i]] >> sub_shift) & 511];
        uint32_t sum = 0;
        for (uint32_t& c : sc.count) sum += std::exchange(c, sum);
        for (uint32_t i = 0; i < count; ++i) {
          const uint32_t id = order[first + i];
          const uint64_t key = keys[id];
          local[sc.count[(key >> sub_shift) & 511]++] = {key, id};
        }
        // Sub-buckets are in order: one insertion sort fixes them all, unless one is big.
        uint32_t begin = 0, largest = 0;  // count[j] is now the end of sub-bucket j
        for (uint32_t end : sc.count) largest = std::max(largest, end - std::exchange(begin, end));
        if (largest <= 32) {
          insertion_sort(local.data(), local.data() + count);
        } else {
          begin = 0;
          for (uint32_t end : sc.count) sort_key_ids(local.data() + std::exchange(begin, end), local.data() + end);
        }
      } else {
        for (uint32_t i = 0; i < count; ++i) local[i] = {keys[order[first + i]], order[first + i]};
        sort_key_ids(local.data(), local.data() + count);
      }
      for (uint32_t i = 0; i < count; ++i) order[first + i] = local[i].id;
    }
  });
}

// Stable counting sort of the input faces by owner (smallest new vertex id): fills `owned` (V+1
// entries, faces of owner v are [owned[v], owned[v+1])) and writes the remapped triangles in that
// order, corner order kept. Faces of one owner keep their input order, so the result is
// deterministic. With `in_place`, `in` (which it views) is remapped in place first, so each
// corner is looked up in new_of_old once instead of twice.
void sort_faces_by_owner(std::span<const uint32_t> in, std::span<uint32_t> in_place,
                         std::span<const uint32_t> new_of_old, DefaultInitVector<uint32_t>& owned,
                         DefaultInitVector<uint32_t>& out) {
  const uint32_t v_count = uint32_t(new_of_old.size());
  const uint64_t f_count = in.size() / 3;
  DefaultInitVector<uint32_t> owner(f_count);
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, f_count, kGrain), [&](const tbb::blocked_range<uint64_t>& r) {
    for (uint64_t f = r.begin(); f != r.end(); ++f) {
      const uint32_t a = new_of_old[in[3 * f]], b = new_of_old[in[3 * f + 1]], c = new_of_old[in[3 * f + 2]];
      owner[f] = std::min({a, b, c});
      if (!in_place.empty()) in_place[3 * f] = a, in_place[3 * f + 1] = b, in_place[3 * f + 2] = c;
    }
  });
  out.resize(3 * f_count);
  auto place = [&](auto corner) {
    counting_sort(
        f_count, v_count, [&](uint64_t f) { return owner[f]; }, owned,
        [&](uint64_t f, uint32_t at) {
          for (int k = 0; k < 3; ++k) out[3 * size_t(at) + k] = corner(in[3 * f + k]);
        });
  };
  if (in_place.empty())
    place([&](uint32_t old) { return new_of_old[old]; });
  else
    place([](uint32_t remapped) { return remapped; });
}

// Chunk boundaries: C = round(F / target) chunks of ~F/C owned faces each, cut at the vertex whose
// first owned face is nearest to k·F/C (a vertex's owned faces are never split).
std::vector<Chunk> cut_chunks(std::span<const uint32_t> owned, uint64_t target) {
  const uint32_t v_count = uint32_t(owned.size() - 1);
  const uint64_t f_count = owned.back();
  std::vector<Chunk> chunks;
  if (v_count == 0) return chunks;
  const uint64_t c_count = std::max<uint64_t>(1, (f_count + target / 2) / target);
  uint32_t begin = 0;
  for (uint64_t k = 1; k <= c_count; ++k) {
    uint32_t end = v_count;
    if (k < c_count) {
      const uint64_t goal = (k * f_count + c_count / 2) / c_count;
      end = uint32_t(std::lower_bound(owned.begin(), owned.end(), goal) - owned.begin());
      if (end > 0 && goal - owned[end - 1] < owned[end] - goal) --end;
      if (end <= begin || end >= v_count) continue;  // a giant fan swallowed this cut
    }
    Chunk c;
    c.vertex_begin = begin;
    c.vertex_end = end;
    c.face_begin = owned[begin];
    c.face_end = owned[end];
    chunks.push_back(c);
    begin = end;
  }
  return chunks;
}

void chunk_extras(const MeshView& m, std::span<Chunk> chunks) {
  tbb::enumerable_thread_specific<HaloScratch> scratch;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, chunks.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t c = r.begin(); c != r.end(); ++c) chunk_extras_of(m, chunks[c], scratch.local());
  });
}

}  // namespace streamcvd::store_build
