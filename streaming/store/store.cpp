#include "streamcvd/streaming/store/store.h"

#include <sys/mman.h>
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
#include <optional>
#include <map>
#include <type_traits>

#include "streamcvd/core/mesh/anonymous_pages.h"
#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/store_stats.h"
#include "streamcvd/streaming/io/output_file.h"
#include "streamcvd/streaming/io/pipelined_sink.h"
#include "streamcvd/streaming/store/store_clean.h"
#include "streamcvd/streaming/store/store_layout.h"
#include "streamcvd/streaming/store/store_writer.h"

namespace streamcvd {

static_assert(std::endian::native == std::endian::little, "the store's arrays are little-endian and mapped as is");
static_assert(std::is_trivially_copyable_v<StoreHeader> && sizeof(StoreHeader) == 104,
              "StoreHeader is an on-disk record");

using namespace store_detail;  // this file writes the layout store_layout.h describes

namespace {
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

// Whether a store of this size fits half the memory limit (0 = no limit): built in RAM, or
// (ingest) with its build's memory taken as in core (InCoreMemory).
bool store_fits_half(uint64_t vertices, uint64_t faces, uint64_t limit) {
  const uint64_t bytes = 52 * faces + 33 * vertices;  // the store's size, 52 B/face + 33 B/vertex
  return limit == 0 || bytes <= limit / 2;
}

// The arrays of a store written to a directory, each a stream of its own. The directory
// writer (which invalidates an old store there) starts with the first array, so an input that
// fails in its header or vertices leaves an existing store untouched.
class DirectoryOutputs final : public StoreOutputs {
 public:
  DirectoryOutputs(std::string directory, uint64_t memory_limit)
      : directory_(std::move(directory)), limit_(memory_limit), in_flight_(stream_blocks_in_flight(memory_limit)) {}
  void plan(uint64_t vertices, uint64_t faces) override {
    if (store_fits_half(vertices, faces, limit_) && !in_core_) in_core_.emplace(limit_);
  }
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
  uint64_t limit_;
  uint32_t in_flight_;
  std::optional<StoreDirectoryWriter> writer_;
  std::map<std::string, StoreArrayStream*> streams_;
  std::optional<InCoreMemory> in_core_;  // a build that fits: fresh pages taken as in core
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
    if (!store_fits_half(vertices, faces, limit_)) scratch_.emplace(folder_, stream_blocks_in_flight(limit_));
    else if (!in_core_) in_core_.emplace(limit_);
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
  std::optional<InCoreMemory> in_core_;  // a store built in RAM: fresh pages taken as in core
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
  // Pass 2: the plan, fan by fan. Pass 3: the cleaned soup through the same builder, with the
  // original ids mapped back to the file's (a copy has its vertex's). A cut that did not come
  // apart (an edge still non-manifold) gets a second round dropping its unpaired faces, and a
  // third if that split a vertex into fans once more.
  MeshStore current = std::move(built);
  const uint64_t input_vertices = current.header().input_vertex_count;
  auto rebuild = [&](const CleaningPlan& plan) {
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
    ++report.cleaning.rounds;
    report.cleaning.cleaned = compute_topology_stats(current.view());
  };
  constexpr uint32_t kMaxRounds = 3;
  if (needs_topology_cleaning(report.input_topology, current.view()))
    for (uint32_t round = 0; round < kMaxRounds; ++round) {
      if (progress) progress({"clean"});
      rebuild(plan_topology_cleaning(current.view(), report.cleaning, round > 0));
      const TopologyStats& c = report.cleaning.cleaned;
      if (c.nonmanifold_edges == 0 && c.nonmanifold_vertices == 0) break;
    }
  // Pass 4, on the manifold the cuts made: faces turned back where two faces run an edge the
  // same way (a face flipped by an exporter or a crude decimation), so that the dual inherits
  // a consistent orientation: a dual edge used twice in one direction is a defect no repair
  // of the clusters can mend.
  if (!report.cleaning.cleaned.consistently_oriented && report.cleaning.cleaned.nonmanifold_edges == 0) {
    if (progress) progress({"orient"});
    CleaningPlan plan;
    plan.vertices = current.view().vertex_count();
    plan.kept_faces = current.view().face_count();
    plan.flipped_faces = plan_face_flips(current.view(), report.cleaning.misoriented_edges_left);
    report.cleaning.faces_flipped = plan.flipped_faces.size();
    if (!plan.flipped_faces.empty()) rebuild(plan);
  }
  // Pass 5: a surface no flip orients (a Möbius band; the fold of a crude decimation) is cut
  // open along the misoriented edges left, as along a non-manifold edge: faces that run an edge
  // the same way are not one fan, so each side gets its own copies of the seam's vertices and
  // the seam becomes boundary. Left, such an edge is a dual edge used twice in one direction
  // (Möbius band → 300: 40 repair rounds, then faces deleted, exit 4). An edge alone inside a
  // surface stays: its ends' fans join round it.
  if (report.cleaning.misoriented_edges_left > 0) {
    uint64_t edges = 0;
    const std::vector<uint32_t> seam = misoriented_edge_vertices(current.view(), edges);
    TopologyCleaning counts;  // vertices split along the seam (nothing else is left to clean)
    const CleaningPlan plan = plan_topology_cleaning(current.view(), counts, false, seam);
    if (!plan.copy_source.empty()) {  // else: lone edges only, nothing to rebuild
      if (progress) progress({"orient"});
      report.cleaning.vertices_split += counts.vertices_split;
      report.cleaning.vertex_copies += counts.vertex_copies;
      rebuild(plan);
      misoriented_edge_vertices(current.view(), report.cleaning.misoriented_edges_left);
      report.cleaning.misoriented_edges_cut = edges - std::min(edges, report.cleaning.misoriented_edges_left);
    }
  }
  report.cleaning.seconds = seconds();
  if (!report.cleaning.rebuilt) return current;
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
  DirectoryOutputs out(directory, o.memory_limit);
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

}  // namespace streamcvd
