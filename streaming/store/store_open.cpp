// Opening a store directory (MeshStore::open: header checks at open, each chunk validated when
// first used), its madvise hints, accessors, and the file-or-store loader.
#include "streamcvd/streaming/store/store.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/store/page_advice.h"
#include "streamcvd/streaming/store/store_clean.h"
#include "streamcvd/streaming/store/store_layout.h"

namespace streamcvd {

using namespace store_detail;

namespace {

[[noreturn]] void fail_open(const std::string& directory, const std::string& file, const std::string& problem) {
  throw InputError(error_at(directory + "/" + file, problem));
}

constexpr ScalarType kScalarTypes[] = {ScalarType::I8,  ScalarType::U8,  ScalarType::I16, ScalarType::U16,
                                       ScalarType::I32, ScalarType::U32, ScalarType::F32, ScalarType::F64};

}  // namespace

MeshStore MeshStore::open(const std::string& directory) {
  MeshStore store;
  Impl& s = *store.impl_;
  s.directory = directory;
  s.bytes.clear();
  auto fail = [&](const std::string& file, const std::string& problem) { fail_open(directory, file, problem); };
  auto open_file = [&](const std::string& name, struct stat& st) {
    const std::string path = directory + "/" + name;
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);  // a FIFO must not block
    if (fd < 0) fail(name, std::string("cannot open: ") + std::strerror(errno));
    if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
      ::close(fd);
      fail(name, "not a regular file");
    }
    return fd;
  };
  {
    struct stat st {};
    const int fd = open_file(kHeaderFile, st);
    const ssize_t got = st.st_size == sizeof(StoreHeader) ? ::read(fd, &s.header, sizeof(StoreHeader)) : -1;
    ::close(fd);
    if (got != ssize_t(sizeof(StoreHeader)))
      fail(kHeaderFile, "size " + std::to_string(st.st_size) + " bytes, expected " + std::to_string(sizeof(StoreHeader)));
  }
  const StoreHeader& h = s.header;
  if (std::memcmp(h.magic, StoreHeader{}.magic, sizeof h.magic) != 0) fail(kHeaderFile, "bad magic (not a streamcvd store)");
  if (h.version != kStoreVersion)
    fail(kHeaderFile, "unsupported version " + std::to_string(h.version) + " (expected " + std::to_string(kStoreVersion) +
                          "; ingest the mesh again)");
  if (h.vertex_count > std::numeric_limits<uint32_t>::max() || h.face_count > std::numeric_limits<uint32_t>::max())
    fail(kHeaderFile, "vertex or face count over 2^32-1");
  if (h.vertex_face_count != 3 * h.face_count) fail(kHeaderFile, "vertex-face count is not 3 x face count");
  if ((h.chunk_count == 0) != (h.vertex_count == 0) || h.chunk_count > h.vertex_count)
    fail(kHeaderFile, "chunk count " + std::to_string(h.chunk_count) + " impossible for " + std::to_string(h.vertex_count) +
                          " vertices");
  if (h.attribute_count > 4096) fail(kHeaderFile, "attribute count " + std::to_string(h.attribute_count) + " too large");
  // Fewer store vertices than input ones when STL corners merge, more when the cleaning copied
  // vertices at a non-manifold spot (streaming/store/store_clean.h); never vertices without an input.
  if ((h.input_vertex_count == 0) != (h.vertex_count == 0) || h.input_vertex_count > std::numeric_limits<uint32_t>::max())
    fail(kHeaderFile, "input vertex count " + std::to_string(h.input_vertex_count) + " impossible for " +
                          std::to_string(h.vertex_count) + " vertices");
  // Arrays: sizes must match the header exactly, then map them.
  const std::vector<ArrayFile> files = array_files(h);
  s.mappings.resize(kArrayCount);
  for (int i = 0; i < kArrayCount; ++i) {
    const ArrayFile& file = files[i];
    struct stat st {};
    const int fd = open_file(file.name, st);
    const uint64_t size = uint64_t(st.st_size);
    if (file.count > size / file.element || size != file.count * file.element) {
      ::close(fd);
      fail(file.name, "size " + std::to_string(size) + " bytes, expected " + std::to_string(file.count) + " entries of " +
                          std::to_string(file.element) + " bytes");
    }
    void* address = nullptr;
    if (size > 0) {
      address = ::mmap(nullptr, size, PROT_READ, MAP_SHARED, fd, 0);
      if (address == MAP_FAILED) {
        ::close(fd);
        fail(file.name, std::string("cannot map: ") + std::strerror(errno));
      }
      s.mappings[i] = {address, size};
    }
    ::close(fd);
    s.bytes.emplace_back(static_cast<const std::byte*>(address), size);
  }
  s.ram.clear();
  {
    struct stat st {};
    ::close(open_file(kAttributesFile, st));
    std::ifstream in(directory + "/" + kAttributesFile);
    std::string name, type;
    while (in >> name >> type) {
      VertexAttribute a{name, ScalarType::F32};
      bool known = false;
      for (const ScalarType t : kScalarTypes)
        if (type == scalar_type_name(t)) a.type = t, known = true;
      if (!known) fail(kAttributesFile, "unknown attribute type '" + type + "'");
      s.attributes.push_back(a);
    }
    if (s.attributes.size() != h.attribute_count)
      fail(kAttributesFile, std::to_string(s.attributes.size()) + " attributes listed, the header says " +
                                std::to_string(h.attribute_count));
  }
  if (std::ifstream in(directory + "/" + kCleaningFile); in) {  // optional: a cleaned store's record
    s.cleaning.assign(std::istreambuf_iterator<char>(in), {});
    try {
      StoreBuildReport check;
      parse_cleaning_record(s.cleaning, check);
    } catch (const InputError& e) {
      fail(kCleaningFile, e.what());
    }
  }
  s.make_views();
  // The small tables are checked now: chunks tile [0, V) and [0, F), neighbours are chunk ids.
  const MeshView& m = s.view;
  uint64_t v_next = 0, f_next = 0;
  for (size_t i = 0; i < m.chunks.size(); ++i) {
    const Chunk& c = m.chunks[i];
    if (c.vertex_begin != v_next || c.vertex_end <= c.vertex_begin || c.face_begin != f_next || c.face_end < c.face_begin)
      fail(files[kChunks].name, "chunk " + std::to_string(i) + " does not continue the previous one");
    if (uint64_t(c.neighbour_begin) + c.neighbour_count > h.chunk_neighbour_count)
      fail(files[kChunks].name, "chunk " + std::to_string(i) + " has neighbours past the table");
    v_next = c.vertex_end;
    f_next = c.face_end;
  }
  if (v_next != h.vertex_count || f_next != h.face_count)
    fail(files[kChunks].name, "chunks do not cover all vertices and faces");
  for (size_t i = 0; i < m.chunk_neighbours.size(); ++i)
    if (m.chunk_neighbours[i] >= h.chunk_count)
      fail(files[kNeighbours].name, "entry " + std::to_string(i) + " is chunk " + std::to_string(m.chunk_neighbours[i]) +
                                        " of " + std::to_string(h.chunk_count));
  auto check_ends = [&](std::span<const uint64_t> off, uint64_t total, const char* name) {
    if (off[0] != 0) fail(name, "offset 0 is " + std::to_string(off[0]) + ", expected 0");
    if (off[h.vertex_count] != total)
      fail(name, "last offset " + std::to_string(off[h.vertex_count]) + " does not match " + std::to_string(total) +
                     " entries");
  };
  check_ends(m.vertex_vertex_offsets, h.vertex_vertex_count, files[kVvOffsets].name);
  check_ends(m.vertex_face_offsets, h.vertex_face_count, files[kVfOffsets].name);
  return store;
}

void MeshStore::validate_chunk(uint32_t c) const {
  const Impl& s = *impl_;
  if (s.validated[c].load(std::memory_order_acquire)) return;
  const MeshView& m = s.view;
  const Chunk& ch = m.chunks[c];
  const std::vector<ArrayFile> files = array_files(s.header);
  auto fail = [&](int file, const std::string& problem) { fail_open(s.directory, files[file].name, problem); };
  const uint64_t V = s.header.vertex_count, F = s.header.face_count;
  auto check_csr = [&](int off_file, std::span<const uint64_t> off, std::span<const uint32_t> entries, uint64_t limit,
                       int entry_file, const char* what) {
    for (uint64_t v = ch.vertex_begin; v < ch.vertex_end; ++v)
      if (off[v] > off[v + 1] || off[v + 1] > entries.size())
        fail(off_file, "offsets decrease or overflow at entry " + std::to_string(v + 1));
    for (uint64_t i = off[ch.vertex_begin]; i < off[ch.vertex_end]; ++i)
      if (entries[i] >= limit)
        fail(entry_file, "entry " + std::to_string(i) + " is " + what + " " + std::to_string(entries[i]) + " of " +
                             std::to_string(limit));
  };
  check_csr(kVvOffsets, m.vertex_vertex_offsets, m.vertex_vertex, V, kVv, "vertex");
  check_csr(kVfOffsets, m.vertex_face_offsets, m.vertex_face, F, kVf, "face");
  for (uint64_t i = 3 * ch.face_begin; i < 3 * ch.face_end; ++i)
    if (m.triangles[i] >= V)
      fail(kTriangles, "entry " + std::to_string(i) + " is vertex " + std::to_string(m.triangles[i]) + " of " +
                           std::to_string(V));
  for (uint64_t v = ch.vertex_begin; v < ch.vertex_end; ++v)
    if (s.original_view[v] >= s.header.input_vertex_count)
      fail(kOriginal, "entry " + std::to_string(v) + " is vertex " + std::to_string(s.original_view[v]) + " of " +
                          std::to_string(s.header.input_vertex_count));
  s.validated[c].store(1, std::memory_order_release);
}

void MeshStore::validate_all() const {
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, impl_->header.chunk_count, 1),
                    [&](const tbb::blocked_range<uint32_t>& r) {
                      for (uint32_t c = r.begin(); c != r.end(); ++c) validate_chunk(c);
                    });
}

void MeshStore::advise(uint32_t chunk, Advice advice, uint8_t arrays) const {
  const Impl& s = *impl_;
  if (s.mappings.empty()) return;
  const int how = advice == Advice::WillNeed ? MADV_WILLNEED
                  : advice == Advice::DontNeed ? MADV_DONTNEED
                  : advice == Advice::Sequential ? MADV_SEQUENTIAL
                  : advice == Advice::Cold       ? MADV_COLD
                  : advice == Advice::Normal     ? MADV_NORMAL
                                                 : MADV_RANDOM;
  auto advise_bytes = [&](int file, uint64_t begin, uint64_t end) {
    const Impl::Mapping& mp = s.mappings[file];
    end = std::min<uint64_t>(end, mp.length);
    if (!mp.address || begin >= end) return;
    advise_pages(static_cast<const std::byte*>(mp.address) + begin, end - begin, how, PageSpan::Covering);
  };
  if (chunk == kAllChunks) {
    for (int f = 0; f < kArrayCount; ++f) advise_bytes(f, 0, s.mappings[f].length);
    return;
  }
  const Chunk& c = s.view.chunks[chunk];
  const MeshView& m = s.view;
  const uint64_t vb = c.vertex_begin, ve = c.vertex_end;
  if (arrays & kReadsPositions) advise_bytes(kPositions, 12 * vb, 12 * ve);
  if (arrays & kReadsTriangles) advise_bytes(kTriangles, 12 * c.face_begin, 12 * c.face_end);
  if (arrays & kReadsNeighbours) {
    advise_bytes(kVvOffsets, 8 * vb, 8 * (ve + 1));
    advise_bytes(kVv, 4 * m.vertex_vertex_offsets[vb], 4 * m.vertex_vertex_offsets[ve]);
  }
  if (arrays & kReadsVertexFaces) {
    advise_bytes(kVfOffsets, 8 * vb, 8 * (ve + 1));
    advise_bytes(kVf, 4 * m.vertex_face_offsets[vb], 4 * m.vertex_face_offsets[ve]);
  }
  if (arrays & kReadsFlags) advise_bytes(kFlags, vb, ve);
  if (arrays != kReadsAllArrays) return;
  advise_bytes(kOriginal, 4 * vb, 4 * ve);
  advise_bytes(kAttributes, 4 * s.header.attribute_count * vb, 4 * s.header.attribute_count * ve);
}

MeshView MeshStore::view() const { return impl_->view; }
const StoreHeader& MeshStore::header() const { return impl_->header; }
std::span<const uint32_t> MeshStore::original_vertex_ids() const { return impl_->original_view; }
std::span<const float> MeshStore::vertex_attributes() const { return impl_->attribute_view; }
const std::vector<VertexAttribute>& MeshStore::attributes() const { return impl_->attributes; }

uint64_t MeshStore::size_bytes() const {
  uint64_t total = sizeof(StoreHeader);
  for (const ArrayFile& f : array_files(impl_->header)) total += f.count * f.element;
  return total;
}

uint64_t MeshStore::ram_bytes() const {
  uint64_t total = 0;
  for (const auto& a : impl_->ram) total += a.size();
  return total;
}

bool is_store_directory(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_directory(path, ec)) return false;
  const int fd = ::open((path + "/" + kHeaderFile).c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) return false;
  char magic[sizeof StoreHeader{}.magic];
  const bool ok = ::read(fd, magic, sizeof magic) == ssize_t(sizeof magic) &&
                  std::memcmp(magic, StoreHeader{}.magic, sizeof magic) == 0;
  ::close(fd);
  return ok;
}

MeshStore load_mesh_or_store(const std::string& path, const StoreBuildOptions& options) {
  if (is_store_directory(path)) {
    MeshStore store = MeshStore::open(path);
    store.validate_all();
    return store;
  }
  return MeshStore::build_from_file(path, options);
}

}  // namespace streamcvd
