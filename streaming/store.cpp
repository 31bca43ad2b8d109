#include "streaming/store.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <limits>
#include <numeric>
#include <optional>
#include <type_traits>

#include "core/adjacency.h"
#include "core/default_init_vector.h"
#include "core/errors.h"
#include "streaming/mesh_io.h"
#include "streaming/output_file.h"
#include "streaming/store_build.h"
#include "streaming/store_writer.h"

namespace streamcvd {

static_assert(std::endian::native == std::endian::little, "the store's arrays are little-endian and mapped as is");
static_assert(std::is_trivially_copyable_v<StoreHeader> && sizeof(StoreHeader) == 104,
              "StoreHeader is an on-disk record");

using namespace store_build;  // the build passes

namespace {
constexpr uint32_t kStoreVersion = 1;
constexpr const char* kHeaderFile = "header.bin";
constexpr size_t kGrain = 1 << 14;

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
  chunk_extras(s.view, s.chunks);

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
