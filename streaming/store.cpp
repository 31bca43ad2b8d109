#include "streaming/store.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <limits>
#include <numeric>
#include <optional>
#include <type_traits>
#include <utility>

#include "core/adjacency.h"
#include "core/default_init_vector.h"
#include "core/errors.h"
#include "core/hilbert.h"
#include "streaming/mesh_io.h"
#include "streaming/output_file.h"
#include "streaming/store_writer.h"

namespace streamcvd {

static_assert(std::endian::native == std::endian::little, "the store's arrays are little-endian and mapped as is");
static_assert(std::is_trivially_copyable_v<StoreHeader> && sizeof(StoreHeader) == 104,
              "StoreHeader is an on-disk record");

namespace {
constexpr uint32_t kStoreVersion = 1;
constexpr const char* kHeaderFile = "header.bin";
constexpr size_t kGrain = 1 << 14;

// ---------------------------------------------------------------------------------------------
// Build helpers

struct Bbox {
  float lo[3] = {std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity(),
                 std::numeric_limits<float>::infinity()};
  float hi[3] = {-std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                 -std::numeric_limits<float>::infinity()};
  void add(const float* p) {
    for (int k = 0; k < 3; ++k)
      if (std::isfinite(p[k])) lo[k] = std::min(lo[k], p[k]), hi[k] = std::max(hi[k], p[k]);
  }
  void add(const Bbox& b) {
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], b.lo[k]), hi[k] = std::max(hi[k], b.hi[k]);
  }
  // An empty box (no finite coordinate on an axis) becomes [0, 0] on that axis.
  void finish() {
    for (int k = 0; k < 3; ++k)
      if (!(lo[k] <= hi[k])) lo[k] = hi[k] = 0;
  }
};

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

// Smallest i in [0, n) with bad(i), or n. Parallel and deterministic.
template <typename Pred>
uint64_t first_violation(uint64_t n, Pred bad) {
  return tbb::parallel_reduce(
      tbb::blocked_range<uint64_t>(0, n, 1 << 16), n,
      [&](const tbb::blocked_range<uint64_t>& r, uint64_t found) {
        for (uint64_t i = r.begin(); i != r.end() && i < found; ++i)
          if (bad(i)) return i;
        return found;
      },
      [](uint64_t a, uint64_t b) { return std::min(a, b); });
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
  start.resize(size_t(buckets) + 1);
  uint32_t sum = 0;
  for (uint32_t b = 0; b < buckets; ++b) {
    start[b] = sum;
    for (uint32_t p = 0; p < parts; ++p) sum += std::exchange(cursor[p][b], sum);
  }
  start[buckets] = sum;
  tbb::parallel_for(uint32_t(0), parts, [&](uint32_t p) {
    uint32_t* at = cursor[p].data();
    for (uint64_t i = item_begin(p); i != item_begin(p + 1); ++i) place(i, at[bucket_of(i)]++);
  });
}

// Input vertex id of each store vertex: sorted by (Hilbert key, input id), the id breaking ties
// so the order is a pure function of the input. A stable counting sort of the ids on the key's
// top octree levels (~2 vertices per bucket of a surface... up to a few hundred), straight into
// `order`, then a sort of each bucket: O(V) passes instead of a full O(V log V) sort, and no
// (key, id) array for all vertices.
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
  // scattered keys.
  struct KeyId {
    uint64_t key;
    uint32_t id;
    bool operator<(const KeyId& o) const { return key < o.key || (key == o.key && id < o.id); }
  };
  tbb::enumerable_thread_specific<std::vector<KeyId>> buffers;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, start.size() - 1, 4096), [&](const tbb::blocked_range<size_t>& r) {
    std::vector<KeyId>& local = buffers.local();
    for (size_t b = r.begin(); b != r.end(); ++b) {
      const uint32_t first = start[b], count = start[b + 1] - first;
      if (count < 2) continue;
      local.resize(count);
      for (uint32_t i = 0; i < count; ++i) local[i] = {keys[order[first + i]], order[first + i]};
      if (count > 16) {
        std::sort(local.begin(), local.end());
      } else {
        for (uint32_t i = 1; i < count; ++i) {
          const KeyId x = local[i];
          uint32_t j = i;
          for (; j > 0 && x < local[j - 1]; --j) local[j] = local[j - 1];
          local[j] = x;
        }
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
void chunk_extras(const MeshView& m, Chunk& c, HaloScratch& s) {
  Bbox box = bounding_box(m.positions, c.vertex_begin, c.vertex_end);
  box.finish();
  std::copy(box.lo, box.lo + 3, c.bbox_min);
  std::copy(box.hi, box.hi + 3, c.bbox_max);
  auto outside_v = [&](uint32_t v) { return v < c.vertex_begin || v >= c.vertex_end; };
  auto outside_f = [&](uint64_t f) { return f < c.face_begin || f >= c.face_end; };
  s.faces.clear();
  s.ring1.clear();
  for (uint32_t v = c.vertex_begin; v < c.vertex_end; ++v) {
    for (uint32_t f : m.faces_of(v))
      if (outside_f(f)) s.faces.push_back(f);
    for (uint32_t u : m.neighbours(v))
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

// ---------------------------------------------------------------------------------------------
// Files

// One array file of the store: its name, element size and entry count from the header.
struct ArrayFile {
  const char* name;
  size_t element;
  uint64_t count;
};

std::vector<ArrayFile> array_files(const StoreHeader& h) {
  return {{"positions.f32", 4, 3 * h.vertex_count},  {"triangles.u32", 4, 3 * h.face_count},
          {"vv_offsets.u64", 8, h.vertex_count + 1}, {"vv.u32", 4, h.vertex_vertex_count},
          {"vf_offsets.u64", 8, h.vertex_count + 1}, {"vf.u32", 4, h.vertex_face_count},
          {"flags.u8", 1, h.vertex_count},           {"chunks.bin", sizeof(Chunk), h.chunk_count},
          {"original_ids.u32", 4, h.vertex_count}};
}

template <typename T>
std::span<const std::byte> bytes_of(std::span<const T> s) {
  return std::as_bytes(s);
}

// A mapped file's bytes as an array of T (the size was checked against the header).
template <typename T>
std::span<const T> array_of(std::span<const std::byte> bytes) {
  return {reinterpret_cast<const T*>(bytes.data()), bytes.size() / sizeof(T)};
}

[[noreturn]] void fail_open(const std::string& directory, const std::string& file, const std::string& problem) {
  throw InputError(error_at(directory + "/" + file, problem));
}

// A read-only mapping, unmapped with its owner.
struct Mapping {
  void* address = nullptr;
  size_t length = 0;
};

}  // namespace

// ---------------------------------------------------------------------------------------------

struct MeshStore::Impl {
  StoreHeader header;
  // Arrays of a store built in RAM (empty for an opened store).
  // Filled by parallel passes: not zeroed first (DefaultInitVector). vertex_face takes over the
  // consumed soup's index array when there is one.
  DefaultInitVector<float> positions;
  DefaultInitVector<uint32_t> triangles, vertex_vertex, original_ids;
  std::vector<uint32_t> vertex_face;
  DefaultInitVector<uint64_t> vv_offsets{0}, vf_offsets{0};  // V + 1 entries, also when empty
  DefaultInitVector<uint8_t> flags;
  std::vector<Chunk> chunks;
  // Files of an opened store.
  std::vector<Mapping> mappings;
  // What callers see, pointing into either.
  MeshView view;
  std::span<const uint32_t> original_view;

  Impl() = default;
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
  ~Impl() {
    for (const Mapping& m : mappings) ::munmap(m.address, m.length);
  }

  void view_vectors() {
    view = {positions, triangles, vv_offsets, vertex_vertex, vf_offsets, vertex_face, flags, chunks};
    original_view = original_ids;
  }

  // The arrays of view()/original_view in the order of array_files().
  std::vector<std::span<const std::byte>> array_bytes() const {
    return {bytes_of(view.positions),
            bytes_of(view.triangles),
            bytes_of(view.vertex_vertex_offsets),
            bytes_of(view.vertex_vertex),
            bytes_of(view.vertex_face_offsets),
            bytes_of(view.vertex_face),
            bytes_of(view.vertex_flags),
            bytes_of(view.chunks),
            bytes_of(original_view)};
  }
};

MeshStore::MeshStore() : impl_(std::make_unique<Impl>()) { impl_->view_vectors(); }
MeshStore::~MeshStore() = default;
MeshStore::MeshStore(MeshStore&&) noexcept = default;
MeshStore& MeshStore::operator=(MeshStore&&) noexcept = default;

MeshStore MeshStore::build(const TriangleSoupView& soup, const StoreBuildOptions& options) {
  return build_from(soup, options, nullptr, nullptr);
}

MeshStore MeshStore::build(MeshBuffers&& soup, const StoreBuildOptions& options) {
  MeshBuffers owned = std::move(soup);
  return build_from(owned.view(), options, &owned, nullptr);
}

MeshStore MeshStore::build_and_write(MeshBuffers&& soup, const std::string& directory,
                                     const StoreBuildOptions& options) {
  MeshBuffers owned = std::move(soup);
  return build_from(owned.view(), options, &owned, &directory);
}

MeshStore MeshStore::build_from(const TriangleSoupView& soup, const StoreBuildOptions& options, MeshBuffers* consumed,
                                const std::string* directory) {
  check_soup(soup);
  if (options.faces_per_chunk == 0) throw InputError("store build: faces_per_chunk must be positive");
  // Writing while building: each array is handed to the writer thread as soon as it is final.
  // Created only after the input checks, since it removes an older store's header.
  std::optional<StoreDirectoryWriter> writer;
  if (directory) writer.emplace(*directory, /*background=*/true);
  auto hand_over = [&](const char* name, const auto& array) {
    if (writer) writer->add(name, std::as_bytes(std::span(array)));
  };
  const uint32_t v_count = soup.vertex_count();
  const uint64_t f_count = soup.face_count();
  MeshStore store;
  Impl& s = *store.impl_;
  Bbox box = bounding_box(soup.positions, 0, v_count);
  box.finish();

  // 1. Vertex order (Hilbert curve), its inverse, positions in the new order.
  s.original_ids.resize(v_count);
  if (options.hilbert_order)
    hilbert_order(soup.positions, box, s.original_ids);
  else
    std::iota(s.original_ids.begin(), s.original_ids.end(), 0u);
  DefaultInitVector<uint32_t> owned;
  {
    DefaultInitVector<uint32_t> new_of_old(v_count);
    s.positions.resize(3 * size_t(v_count));
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, v_count, kGrain), [&](const tbb::blocked_range<uint32_t>& r) {
      for (uint32_t i = r.begin(); i != r.end(); ++i) {
        const uint32_t old = s.original_ids[i];
        new_of_old[old] = i;
        for (int k = 0; k < 3; ++k) s.positions[3 * size_t(i) + k] = soup.positions[3 * size_t(old) + k];
      }
    });
    hand_over("positions.f32", s.positions);
    hand_over("original_ids.u32", s.original_ids);
    // 2. Faces remapped and sorted by owner.
    sort_faces_by_owner(soup.triangles, consumed ? std::span(consumed->triangles) : std::span<uint32_t>(),
                        new_of_old, owned, s.triangles);
  }
  hand_over("triangles.u32", s.triangles);
  if (consumed) {  // `soup` views it: not used past this point
    // Its index array has the size of vf.u32 and is paged in already: reuse it.
    s.vertex_face = std::move(consumed->triangles);
    *consumed = MeshBuffers{};
  }

  // 3. Adjacency and flags.
  build_vertex_face_adjacency(s.triangles, v_count, s.vf_offsets, s.vertex_face);
  hand_over("vf_offsets.u64", s.vf_offsets);
  hand_over("vf.u32", s.vertex_face);
  s.flags.resize(v_count);
  build_vertex_vertex_adjacency(s.triangles, s.vf_offsets, s.vertex_face, s.vv_offsets, s.vertex_vertex, s.flags);
  hand_over("vv_offsets.u64", s.vv_offsets);
  hand_over("vv.u32", s.vertex_vertex);
  hand_over("flags.u8", s.flags);

  // 4. Chunks.
  s.chunks = cut_chunks(owned, options.faces_per_chunk);
  DefaultInitVector<uint32_t>().swap(owned);
  s.view_vectors();
  tbb::enumerable_thread_specific<HaloScratch> scratch;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, s.chunks.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t c = r.begin(); c != r.end(); ++c) chunk_extras(s.view, s.chunks[c], scratch.local());
  });

  StoreHeader& h = s.header;
  h.version = kStoreVersion;
  h.chunk_count = uint32_t(s.chunks.size());
  h.vertex_count = v_count;
  h.face_count = f_count;
  h.vertex_vertex_count = s.vertex_vertex.size();
  h.vertex_face_count = s.vertex_face.size();
  std::copy(box.lo, box.lo + 3, h.bbox_min);
  std::copy(box.hi, box.hi + 3, h.bbox_max);
  if (writer) {
    hand_over("chunks.bin", s.chunks);
    writer->finish(kHeaderFile, std::as_bytes(std::span(&h, 1)));
  }
  return store;
}

void MeshStore::write(const std::string& directory) const {
  StoreDirectoryWriter writer(directory, /*background=*/false);
  const std::vector<ArrayFile> files = array_files(impl_->header);
  const std::vector<std::span<const std::byte>> arrays = impl_->array_bytes();
  for (size_t i = 0; i < files.size(); ++i) writer.add(files[i].name, arrays[i]);
  writer.finish(kHeaderFile, std::as_bytes(std::span(&impl_->header, 1)));
}

MeshStore MeshStore::open(const std::string& directory) {
  MeshStore store;
  Impl& s = *store.impl_;
  auto fail = [&](const std::string& file, const std::string& problem) { fail_open(directory, file, problem); };
  // Header.
  {
    const std::string path = directory + "/" + kHeaderFile;
    int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);  // a FIFO must not block
    if (fd < 0) fail(kHeaderFile, std::string("cannot open: ") + std::strerror(errno));
    struct stat st {};
    ssize_t got = ::fstat(fd, &st) == 0 && S_ISREG(st.st_mode) && st.st_size == sizeof(StoreHeader)
                      ? ::read(fd, &s.header, sizeof(StoreHeader))
                      : -1;
    ::close(fd);
    if (got != ssize_t(sizeof(StoreHeader)))
      fail(kHeaderFile,
           "size " + std::to_string(st.st_size) + " bytes, expected " + std::to_string(sizeof(StoreHeader)));
  }
  const StoreHeader& h = s.header;
  if (std::memcmp(h.magic, StoreHeader{}.magic, sizeof h.magic) != 0)
    fail(kHeaderFile, "bad magic (not a streamcvd store)");
  if (h.version != kStoreVersion)
    fail(kHeaderFile,
         "unsupported version " + std::to_string(h.version) + " (expected " + std::to_string(kStoreVersion) + ")");
  if (h.vertex_count > std::numeric_limits<uint32_t>::max() || h.face_count > std::numeric_limits<uint32_t>::max())
    fail(kHeaderFile, "vertex or face count over 2^32-1");
  if (h.vertex_face_count != 3 * h.face_count) fail(kHeaderFile, "vertex-face count is not 3 x face count");
  if ((h.chunk_count == 0) != (h.vertex_count == 0) || h.chunk_count > h.vertex_count)
    fail(kHeaderFile, "chunk count " + std::to_string(h.chunk_count) + " impossible for " +
                          std::to_string(h.vertex_count) + " vertices");

  // Arrays: sizes must match the header exactly, then map them.
  const std::vector<ArrayFile> files = array_files(h);
  std::vector<std::span<const std::byte>> arrays;
  for (const ArrayFile& file : files) {
    const std::string path = directory + "/" + file.name;
    int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
    if (fd < 0) fail(file.name, std::string("cannot open: ") + std::strerror(errno));
    struct stat st {};
    const bool stat_ok = ::fstat(fd, &st) == 0;
    if (!stat_ok || !S_ISREG(st.st_mode)) {
      const int e = errno;
      ::close(fd);
      fail(file.name, stat_ok ? std::string("not a regular file") : std::string("cannot stat: ") + std::strerror(e));
    }
    const uint64_t size = uint64_t(st.st_size);
    if (file.count > size / file.element || size != file.count * file.element) {
      ::close(fd);
      fail(file.name, "size " + std::to_string(size) + " bytes, expected " + std::to_string(file.count) +
                          " entries of " + std::to_string(file.element) + " bytes");
    }
    void* address = nullptr;
    if (size > 0) {
      address = ::mmap(nullptr, size, PROT_READ, MAP_SHARED, fd, 0);
      if (address == MAP_FAILED) {
        ::close(fd);
        fail(file.name, std::string("cannot map: ") + std::strerror(errno));
      }
      s.mappings.push_back({address, size});
    }
    ::close(fd);
    arrays.push_back({static_cast<const std::byte*>(address), size});
  }
  MeshView& m = s.view;
  m.positions = array_of<float>(arrays[0]);
  m.triangles = array_of<uint32_t>(arrays[1]);
  m.vertex_vertex_offsets = array_of<uint64_t>(arrays[2]);
  m.vertex_vertex = array_of<uint32_t>(arrays[3]);
  m.vertex_face_offsets = array_of<uint64_t>(arrays[4]);
  m.vertex_face = array_of<uint32_t>(arrays[5]);
  m.vertex_flags = array_of<uint8_t>(arrays[6]);
  m.chunks = array_of<Chunk>(arrays[7]);
  s.original_view = array_of<uint32_t>(arrays[8]);

  // Contents that would make an algorithm read out of bounds: offsets, indices, chunk ranges.
  // One parallel pass over the index arrays (O(V + F)); values only, so it stays cheap.
  const uint64_t v_count = h.vertex_count, f_count = h.face_count;
  auto check_offsets = [&](std::span<const uint64_t> off, uint64_t total, const char* name) {
    if (off[0] != 0) fail(name, "offset 0 is " + std::to_string(off[0]) + ", expected 0");
    uint64_t bad = first_violation(v_count, [&](uint64_t i) { return off[i] > off[i + 1]; });
    if (bad < v_count) fail(name, "offsets decrease at entry " + std::to_string(bad + 1));
    if (off[v_count] != total)
      fail(name,
           "last offset " + std::to_string(off[v_count]) + " does not match " + std::to_string(total) + " entries");
  };
  check_offsets(m.vertex_vertex_offsets, h.vertex_vertex_count, files[2].name);
  check_offsets(m.vertex_face_offsets, h.vertex_face_count, files[4].name);
  auto check_indices = [&](std::span<const uint32_t> a, uint64_t limit, const char* name, const char* what) {
    uint64_t bad = first_violation(a.size(), [&](uint64_t i) { return a[i] >= limit; });
    if (bad < a.size())
      fail(name, "entry " + std::to_string(bad) + " is " + what + " " + std::to_string(a[bad]) + " of " +
                     std::to_string(limit));
  };
  check_indices(m.triangles, v_count, files[1].name, "vertex");
  check_indices(m.vertex_vertex, v_count, files[3].name, "vertex");
  check_indices(m.vertex_face, f_count, files[5].name, "face");
  check_indices(s.original_view, v_count, files[8].name, "vertex");  // a permutation of [0, V) when built here
  uint64_t v_next = 0, f_next = 0;
  for (size_t i = 0; i < m.chunks.size(); ++i) {
    const Chunk& c = m.chunks[i];
    if (c.vertex_begin != v_next || c.vertex_end <= c.vertex_begin || c.face_begin != f_next ||
        c.face_end < c.face_begin)
      fail(files[7].name, "chunk " + std::to_string(i) + " does not continue the previous one");
    v_next = c.vertex_end;
    f_next = c.face_end;
  }
  if (v_next != v_count || f_next != f_count) fail(files[7].name, "chunks do not cover all vertices and faces");
  return store;
}

MeshView MeshStore::view() const { return impl_->view; }
const StoreHeader& MeshStore::header() const { return impl_->header; }
std::span<const uint32_t> MeshStore::original_vertex_ids() const { return impl_->original_view; }

uint64_t MeshStore::size_bytes() const {
  uint64_t total = sizeof(StoreHeader);
  for (const ArrayFile& f : array_files(impl_->header)) total += f.count * f.element;
  return total;
}

bool is_store_directory(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_directory(path, ec)) return false;
  int fd = ::open((path + "/" + kHeaderFile).c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) return false;
  char magic[sizeof StoreHeader{}.magic];
  const bool ok = ::read(fd, magic, sizeof magic) == ssize_t(sizeof magic) &&
                  std::memcmp(magic, StoreHeader{}.magic, sizeof magic) == 0;
  ::close(fd);
  return ok;
}

MeshStore load_mesh_or_store(const std::string& path, const StoreBuildOptions& options) {
  if (is_store_directory(path)) return MeshStore::open(path);
  return MeshStore::build(read_mesh(path).view(), options);
}

}  // namespace streamcvd
