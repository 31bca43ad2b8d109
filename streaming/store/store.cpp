#include "streamcvd/streaming/store/store.h"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cstdlib>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <optional>
#include <iterator>
#include <limits>
#include <map>
#include <sstream>
#include <type_traits>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/store_stats.h"
#include "streamcvd/streaming/io/output_file.h"
#include "streamcvd/streaming/io/pipelined_sink.h"
#include "streamcvd/streaming/store/store_clean.h"
#include "streamcvd/streaming/store/store_writer.h"

namespace streamcvd {

static_assert(std::endian::native == std::endian::little, "the store's arrays are little-endian and mapped as is");
static_assert(std::is_trivially_copyable_v<StoreHeader> && sizeof(StoreHeader) == 104,
              "StoreHeader is an on-disk record");

namespace {
constexpr uint32_t kStoreVersion = 2;
constexpr const char* kHeaderFile = "header.bin";
constexpr const char* kAttributesFile = "attributes.txt";
constexpr const char* kCleaningFile = "cleaning.txt";  // a cleaned store's record (store_clean.h)

// One array file of the store: its name, element size and entry count from the header.
struct ArrayFile {
  const char* name;
  size_t element;
  uint64_t count;
};

enum ArrayIndex { kPositions, kTriangles, kVvOffsets, kVv, kVfOffsets, kVf, kFlags, kChunks, kNeighbours, kOriginal,
                  kAttributes, kArrayCount };

std::vector<ArrayFile> array_files(const StoreHeader& h) {
  return {{"positions.f32", 4, 3 * h.vertex_count},
          {"triangles.u32", 4, 3 * h.face_count},
          {"vv_offsets.u64", 8, h.vertex_count + 1},
          {"vv.u32", 4, h.vertex_vertex_count},
          {"vf_offsets.u64", 8, h.vertex_count + 1},
          {"vf.u32", 4, h.vertex_face_count},
          {"flags.u8", 1, h.vertex_count},
          {"chunks.bin", sizeof(Chunk), h.chunk_count},
          {"chunk_neighbours.u32", 4, h.chunk_neighbour_count},
          {"original_ids.u32", 4, h.vertex_count},
          {"vertex_attributes.f32", 4, uint64_t(h.attribute_count) * h.vertex_count}};
}

// A mapped file's bytes as an array of T (the size was checked against the header).
template <typename T>
std::span<const T> array_of(std::span<const std::byte> bytes) {
  return {reinterpret_cast<const T*>(bytes.data()), bytes.size() / sizeof(T)};
}

[[noreturn]] void fail_open(const std::string& directory, const std::string& file, const std::string& problem) {
  throw InputError(error_at(directory + "/" + file, problem));
}

constexpr ScalarType kScalarTypes[] = {ScalarType::I8,  ScalarType::U8,  ScalarType::I16, ScalarType::U16,
                                       ScalarType::I32, ScalarType::U32, ScalarType::F32, ScalarType::F64};

std::string attributes_text(const std::vector<VertexAttribute>& attributes) {
  std::string text;
  for (const VertexAttribute& a : attributes) text += a.name + " " + scalar_type_name(a.type) + "\n";
  return text;
}

// The store's arrays of a store built in RAM, filled front to back by the builder.
class MemoryOutputs final : public StoreOutputs {
 public:
  ArrayOutput& array(const char* name) override { return arrays_[name]; }
  void expect(const char* name, uint64_t bytes) override { arrays_[name].reserve(bytes); }
  void read_back(const char* name, uint64_t offset, void* dst, size_t n) override {
    if (n > 0) std::memcpy(dst, arrays_.at(name).data().data() + offset, n);
  }
  DefaultInitVector<std::byte> take(const char* name) {
    auto it = arrays_.find(name);
    return it == arrays_.end() ? DefaultInitVector<std::byte>() : std::move(it->second.data());
  }

 private:
  std::map<std::string, MemoryArrayOutput> arrays_;
};

// The arrays of a store written to a directory, each a stream of its own. The directory
// writer (which invalidates an old store there) starts with the first array, so an input that
// fails in its header or vertices leaves an existing store untouched.
class DirectoryOutputs final : public StoreOutputs {
 public:
  DirectoryOutputs(std::string directory, uint32_t blocks_in_flight)
      : directory_(std::move(directory)), in_flight_(blocks_in_flight) {}
  ArrayOutput& array(const char* name) override { return stream(name); }
  void read_back(const char* name, uint64_t offset, void* dst, size_t n) override {
    stream(name).read_back(offset, dst, n);
  }
  StoreArrayStream& stream(const char* name) {
    auto it = streams_.find(name);
    if (it == streams_.end()) it = streams_.emplace(name, &writer().stream(name, in_flight_)).first;
    return *it->second;
  }
  StoreDirectoryWriter& writer() {
    if (!writer_) writer_.emplace(directory_, /*background=*/false);
    return *writer_;
  }

 private:
  std::string directory_;
  uint32_t in_flight_;
  std::optional<StoreDirectoryWriter> writer_;
  std::map<std::string, StoreArrayStream*> streams_;
};

// The arrays of a store kept in anonymous files of a work folder, mapped once built: a
// temporary store for an input too large for RAM. Nothing is ever named, so nothing is left
// behind whatever ends the process.
class ScratchOutputs final : public StoreOutputs {
 public:
  ScratchOutputs(std::string folder, uint32_t blocks_in_flight) : folder_(std::move(folder)), in_flight_(blocks_in_flight) {}
  ArrayOutput& array(const char* name) override { return stream(name); }
  void read_back(const char* name, uint64_t offset, void* dst, size_t n) override {
    stream(name).read_back(offset, dst, n);
  }
  StoreArrayStream& stream(const std::string& name) {
    auto it = streams_.find(name);
    if (it == streams_.end())
      it = streams_.emplace(name, std::make_unique<StoreArrayStream>(folder_ + "/" + name, /*scratch=*/true, in_flight_))
               .first;
    return *it->second;
  }
  const std::string& folder() const { return folder_; }

 private:
  std::string folder_;
  uint32_t in_flight_;
  std::map<std::string, std::unique_ptr<StoreArrayStream>> streams_;
};

// RAM when the store fits half the memory limit, else scratch files: decided by plan(), before
// the first array exists.
class AutoOutputs final : public StoreOutputs {
 public:
  AutoOutputs(uint64_t memory_limit, std::string folder) : limit_(memory_limit), folder_(std::move(folder)) {}
  void plan(uint64_t vertices, uint64_t faces) override {
    const uint64_t bytes = 52 * faces + 33 * vertices;  // the store's size, 52 B/face + 33 B/vertex
    if (limit_ > 0 && bytes > limit_ / 2) scratch_.emplace(folder_, stream_blocks_in_flight(limit_));
  }
  ArrayOutput& array(const char* name) override { return out().array(name); }
  void expect(const char* name, uint64_t bytes) override { out().expect(name, bytes); }
  void read_back(const char* name, uint64_t offset, void* dst, size_t n) override { out().read_back(name, offset, dst, n); }
  StoreOutputs& out() { return scratch_ ? static_cast<StoreOutputs&>(*scratch_) : ram_; }
  MemoryOutputs& ram() { return ram_; }
  ScratchOutputs* scratch() { return scratch_ ? &*scratch_ : nullptr; }

 private:
  uint64_t limit_;
  std::string folder_;
  MemoryOutputs ram_;
  std::optional<ScratchOutputs> scratch_;
};

StoreHeader header_of(const StoreBuildResult& r, uint32_t attribute_count) {
  StoreHeader h;
  h.version = kStoreVersion;
  h.chunk_count = uint32_t(r.chunks.size());
  h.vertex_count = r.vertex_count;
  h.face_count = r.face_count;
  h.vertex_vertex_count = r.vertex_vertex_count;
  h.vertex_face_count = 3 * r.face_count;
  std::copy(r.bbox_min, r.bbox_min + 3, h.bbox_min);
  std::copy(r.bbox_max, r.bbox_max + 3, h.bbox_max);
  h.chunk_neighbour_count = r.chunk_neighbours.size();
  h.input_vertex_count = r.report.input_vertices;
  h.attribute_count = attribute_count;
  return h;
}

// Reads `input` into `builder` (the reader's blocks go straight to the builder).
void stream_file(const std::string& input, MeshSink& builder, const ReadOptions& read,
                 const std::function<void(const BuildProgress&)>& progress) {
  ReadOptions options = read;
  if (progress && !options.progress)
    options.progress = [&](uint64_t bytes, uint64_t total) { progress({"read", bytes, total, "bytes"}); };
  // The reader parses on this thread while the builder consumes the previous block on another.
  PipelinedSink pipeline(builder);
  read_mesh_stream(input, pipeline, options);
}

}  // namespace

// ---------------------------------------------------------------------------------------------

struct MeshStore::Impl {
  StoreHeader header;
  std::string directory;                        // of an opened store ("" in RAM)
  std::vector<DefaultInitVector<std::byte>> ram;  // arrays of a store built in RAM (by ArrayIndex)
  struct Mapping {
    void* address = nullptr;
    size_t length = 0;
  };
  std::vector<Mapping> mappings;                // files of an opened store (by ArrayIndex)
  std::vector<std::span<const std::byte>> bytes;  // every array, in RAM or mapped
  std::vector<VertexAttribute> attributes;
  std::string cleaning;                         // cleaning_record() of a cleaned store, else ""
  MeshView view;
  std::span<const uint32_t> original_view;
  std::span<const float> attribute_view;
  std::unique_ptr<std::atomic<uint8_t>[]> validated;  // per chunk

  Impl() = default;
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
  ~Impl() {
    for (const Mapping& m : mappings)
      if (m.address) ::munmap(m.address, m.length);
  }

  void make_views() {
    MeshView& m = view;
    m.positions = array_of<float>(bytes[kPositions]);
    m.triangles = array_of<uint32_t>(bytes[kTriangles]);
    m.vertex_vertex_offsets = array_of<uint64_t>(bytes[kVvOffsets]);
    m.vertex_vertex = array_of<uint32_t>(bytes[kVv]);
    m.vertex_face_offsets = array_of<uint64_t>(bytes[kVfOffsets]);
    m.vertex_face = array_of<uint32_t>(bytes[kVf]);
    m.vertex_flags = array_of<uint8_t>(bytes[kFlags]);
    m.chunks = array_of<Chunk>(bytes[kChunks]);
    m.chunk_neighbours = array_of<uint32_t>(bytes[kNeighbours]);
    original_view = array_of<uint32_t>(bytes[kOriginal]);
    attribute_view = array_of<float>(bytes[kAttributes]);
    validated = std::make_unique<std::atomic<uint8_t>[]>(header.chunk_count);
  }
};

// Assembles a RAM store from the builder's outputs.
struct StoreAssembly {
  static MeshStore from_scratch(ScratchOutputs& out, StoreBuildResult& r);
  static MeshStore from_memory(MemoryOutputs& out, StoreBuildResult& r) {
    MeshStore store;
    MeshStore::Impl& s = *store.impl_;
    s.bytes.clear();
    s.header = header_of(r, uint32_t(r.attributes.size()));
    s.attributes = r.attributes;
    const std::vector<ArrayFile> files = array_files(s.header);
    s.ram.resize(kArrayCount);
    for (int i = 0; i < kArrayCount; ++i) s.ram[i] = out.take(files[i].name);
    auto put = [&](int i, const auto& v) {
      s.ram[i].resize(v.size() * sizeof(v[0]));
      if (!v.empty()) std::memcpy(s.ram[i].data(), v.data(), s.ram[i].size());
    };
    put(kChunks, r.chunks);
    put(kNeighbours, r.chunk_neighbours);
    for (int i = 0; i < kArrayCount; ++i) s.bytes.emplace_back(s.ram[i].data(), s.ram[i].size());
    s.make_views();
    for (uint32_t c = 0; c < s.header.chunk_count; ++c) s.validated[c] = 1;  // built here: valid
    return store;
  }
};

MeshStore StoreAssembly::from_scratch(ScratchOutputs& out, StoreBuildResult& r) {
  MeshStore store;
  MeshStore::Impl& s = *store.impl_;
  s.bytes.clear();
  s.ram.assign(kArrayCount, {});
  s.header = header_of(r, uint32_t(r.attributes.size()));
  s.attributes = r.attributes;
  s.directory = out.folder();
  out.array("chunks.bin").append(std::span<const Chunk>(r.chunks));
  out.array("chunk_neighbours.u32").append(std::span<const uint32_t>(r.chunk_neighbours));
  const std::vector<ArrayFile> files = array_files(s.header);
  s.mappings.resize(kArrayCount);
  for (int i = 0; i < kArrayCount; ++i) {
    StoreArrayStream& a = out.stream(files[i].name);
    a.finish();
    const size_t size = size_t(a.bytes());
    void* address = nullptr;
    if (size > 0) {
      address = ::mmap(nullptr, size, PROT_READ, MAP_SHARED, a.file().descriptor(), 0);
      if (address == MAP_FAILED)
        throw OutputError(error_at(out.folder(), std::string("cannot map a work file: ") + std::strerror(errno)));
      s.mappings[i] = {address, size};
    }
    s.bytes.emplace_back(static_cast<const std::byte*>(address), size);
  }
  s.make_views();
  for (uint32_t c = 0; c < s.header.chunk_count; ++c) s.validated[c] = 1;  // built here: valid
  return store;  // the mappings keep the anonymous files alive once `out` closes them
}

MeshStore::MeshStore() : impl_(std::make_unique<Impl>()) {
  impl_->header.vertex_count = 0;
  impl_->ram.assign(kArrayCount, {});
  // An empty store still has V + 1 = 1 offset per CSR.
  impl_->ram[kVvOffsets].resize(8);
  impl_->ram[kVfOffsets].resize(8);
  for (auto& a : impl_->ram) impl_->bytes.emplace_back(a.data(), a.size());
  impl_->make_views();
}
MeshStore::~MeshStore() = default;
MeshStore::MeshStore(MeshStore&&) noexcept = default;
MeshStore& MeshStore::operator=(MeshStore&&) noexcept = default;

MeshStore MeshStore::build(const TriangleSoupView& soup, const StoreBuildOptions& options) {
  MemoryOutputs out;
  StoreBuilder builder(out, options);
  stream_soup(soup, builder);
  MeshStore store = StoreAssembly::from_memory(out, builder.result());
  if (!options.clean_topology) return store;
  StoreBuildReport report = builder.result().report;
  return clean_store_topology(std::move(store), options, report, {});
}

MeshStore MeshStore::build(MeshBuffers&& soup, const StoreBuildOptions& options) {
  MeshBuffers owned = std::move(soup);
  return build(owned.view(), options);
}

MeshStore MeshStore::build_from_file(const std::string& input, const StoreBuildOptions& options,
                                     const ReadOptions& read, StoreBuildReport* report,
                                     std::function<void(const BuildProgress&)> progress) {
  return build_from_stream([&](MeshSink& sink) { stream_file(input, sink, read, progress); }, options, report, progress);
}

namespace {

// The store of what `produce` streams, as read: in RAM when it fits half the memory limit, else
// in anonymous work files.
MeshStore build_as_read(const std::function<void(MeshSink&)>& produce, const StoreBuildOptions& options,
                        StoreBuildReport& report, const std::function<void(const BuildProgress&)>& progress) {
  StoreBuildOptions o = options;
  if (o.work_directory.empty()) {
    const char* tmp = std::getenv("TMPDIR");
    o.work_directory = tmp && *tmp ? tmp : "/tmp";
  }
  AutoOutputs out(o.memory_limit, o.work_directory);
  StoreBuilder builder(out, o, progress);
  produce(builder);
  report = builder.result().report;
  if (ScratchOutputs* scratch = out.scratch()) return StoreAssembly::from_scratch(*scratch, builder.result());
  return StoreAssembly::from_memory(out.ram(), builder.result());
}

}  // namespace

MeshStore clean_store_topology(MeshStore&& built, const StoreBuildOptions& options, StoreBuildReport& report,
                               const std::function<void(const BuildProgress&)>& progress) {
  const auto t0 = std::chrono::steady_clock::now();
  auto seconds = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
  // The build's screen found nothing: the store is clean as built (the usual scan), and the
  // input's figures are left to whoever prints them.
  report.topology_checked = true;
  report.cleaning = {};
  if (!report.screen.any()) {
    report.input_topology_known = false;
    return std::move(built);
  }
  // Pass 1: the figures as read (what `info` prints). A store the screen flagged for zero-area
  // faces only, or for nothing the cleaning acts on, ends here, as built.
  if (progress) progress({"check"});
  report.input_topology = compute_topology_stats(built.view());
  report.input_topology_known = true;
  report.cleaning.cleaned = report.input_topology;
  if (!needs_topology_cleaning(report.input_topology, built.view())) {
    report.cleaning.seconds = seconds();
    return std::move(built);
  }
  // Pass 2: the plan, fan by fan. Pass 3: the cleaned soup through the same builder, with the
  // original ids mapped back to the file's (a copy has its vertex's). A cut that did not come
  // apart (an edge still non-manifold) gets a second round dropping its unpaired faces, and a
  // third if that split a vertex into fans once more.
  MeshStore current = std::move(built);
  constexpr uint32_t kMaxRounds = 3;
  const uint64_t input_vertices = current.header().input_vertex_count;
  for (uint32_t round = 0; round < kMaxRounds; ++round) {
    if (progress) progress({"clean"});
    const CleaningPlan plan = plan_topology_cleaning(current.view(), report.cleaning, round > 0);
    StoreBuildOptions o = options;
    o.clean_topology = false;
    const std::span<const uint32_t> original = current.original_vertex_ids();
    o.map_original_ids = [&](std::span<uint32_t> ids) {
      for (uint32_t& id : ids) id = original[id < plan.vertices ? id : plan.copy_source[id - plan.vertices]];
    };
    o.original_vertex_count = input_vertices;
    // The previous store stays while the next is built: what it holds in RAM is not the build's.
    if (o.memory_limit > 0)
      o.memory_limit = std::max(o.memory_limit - std::min(o.memory_limit, current.ram_bytes()), o.memory_limit / 4);
    StoreBuildReport rebuilt;
    MeshStore cleaned = build_as_read([&](MeshSink& sink) { stream_cleaned_soup(current, plan, sink); }, o, rebuilt, progress);
    current = std::move(cleaned);
    report.vertices = rebuilt.vertices;
    report.faces = rebuilt.faces;
    report.chunks = rebuilt.chunks;
    report.spilled_bytes += rebuilt.spilled_bytes;
    report.cleaning.rebuilt = true;
    report.cleaning.rounds = round + 1;
    report.cleaning.cleaned = compute_topology_stats(current.view());
    const TopologyStats& c = report.cleaning.cleaned;
    if (c.nonmanifold_edges == 0 && c.nonmanifold_vertices == 0) break;
  }
  report.cleaning.seconds = seconds();
  current.impl_->cleaning = cleaning_record(report);
  return current;
}

bool MeshStore::cleaning_report(StoreBuildReport& out) const {
  if (impl_->cleaning.empty()) return false;
  parse_cleaning_record(impl_->cleaning, out);  // checked when the store was opened
  return true;
}

MeshStore MeshStore::build_from_stream(const std::function<void(MeshSink&)>& produce, const StoreBuildOptions& options,
                                       StoreBuildReport* report, std::function<void(const BuildProgress&)> progress) {
  StoreBuildReport r;
  MeshStore store = build_as_read(produce, options, r, progress);
  if (options.clean_topology) store = clean_store_topology(std::move(store), options, r, progress);
  if (report) *report = r;
  return store;
}

MeshStore MeshStore::ingest(const std::string& input, const std::string& directory, const StoreBuildOptions& options,
                            const ReadOptions& read, StoreBuildReport* report,
                            std::function<void(const BuildProgress&)> progress) {
  StoreBuildOptions o = options;
  std::error_code stale;
  std::filesystem::remove(std::filesystem::path(directory) / kCleaningFile, stale);  // the store it may replace
  if (o.work_directory.empty()) o.work_directory = directory;
  // The store's folder (scratch files go there by default) exists from here, and a failed or
  // interrupted build that made it leaves none behind.
  CreatedDirectory folder(directory);
  DirectoryOutputs out(directory, stream_blocks_in_flight(o.memory_limit));
  StoreBuilder builder(out, o, progress);
  stream_file(input, builder, read, progress);
  StoreBuildResult& r = builder.result();
  const StoreHeader h = header_of(r, uint32_t(r.attributes.size()));
  // Arrays the build may not have produced (no attributes, no vertices at all) are empty files.
  for (const ArrayFile& f : array_files(h)) out.array(f.name);
  out.array("chunks.bin").append(std::span<const Chunk>(r.chunks));
  out.array("chunk_neighbours.u32").append(std::span<const uint32_t>(r.chunk_neighbours));
  const std::string text = attributes_text(r.attributes);
  out.array(kAttributesFile).append(text.data(), text.size());
  out.writer().finish(kHeaderFile, std::as_bytes(std::span(&h, 1)));
  StoreBuildReport built = r.report;
  MeshStore store = open(directory);
  if (o.clean_topology) {
    // A defective input's cleaned store replaces the one written (the old files stay mapped by
    // `store` until it is gone); a clean one stays as written.
    MeshStore cleaned = clean_store_topology(std::move(store), o, built, progress);
    if (built.cleaning.rebuilt) {
      cleaned.write(directory);
      cleaned = MeshStore();
      store = open(directory);
    } else {
      store = std::move(cleaned);
    }
  }
  if (report) *report = built;
  folder.keep();
  return store;
}

void MeshStore::write(const std::string& directory) const {
  StoreDirectoryWriter writer(directory, /*background=*/false);
  const std::vector<ArrayFile> files = array_files(impl_->header);
  for (size_t i = 0; i < files.size(); ++i) writer.add(files[i].name, impl_->bytes[i]);
  const std::string text = attributes_text(impl_->attributes);
  writer.add(kAttributesFile, std::as_bytes(std::span(text.data(), text.size())));
  if (!impl_->cleaning.empty())
    writer.add(kCleaningFile, std::as_bytes(std::span(impl_->cleaning.data(), impl_->cleaning.size())));
  writer.finish(kHeaderFile, std::as_bytes(std::span(&impl_->header, 1)));
}

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
                                                 : MADV_RANDOM;
  const uintptr_t page = uintptr_t(::sysconf(_SC_PAGESIZE));
  auto advise_bytes = [&](int file, uint64_t begin, uint64_t end) {
    const Impl::Mapping& mp = s.mappings[file];
    if (!mp.address || begin >= end) return;
    const uintptr_t base = uintptr_t(mp.address);
    const uintptr_t lo = (base + begin) & ~(page - 1), hi = std::min<uintptr_t>(base + end, base + mp.length);
    if (hi > lo) ::madvise(reinterpret_cast<void*>(lo), hi - lo, how);
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
