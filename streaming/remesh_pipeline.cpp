#include "streamcvd/core/dual/placement.h"
#include "streamcvd/streaming/remesh_pipeline.h"

#include <tbb/parallel_invoke.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <optional>

#include "streamcvd/core/mesh/anonymous_pages.h"
#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/store_stats.h"
#include "streamcvd/core/mesh/subdivide.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/store/subdivision_stream.h"
#include "streamcvd/streaming/schedule/work_space.h"
#include "streamcvd/core/mesh/timer.h"

namespace streamcvd {

namespace {
std::string default_work_directory() {
  const char* tmp = std::getenv("TMPDIR");
  return tmp && *tmp ? tmp : "/tmp";
}

// The share of the limit the per-vertex arrays may keep in RAM: half of what a RAM store leaves
// (the page cache of a mapped store and of the work files needs the rest). ~0 = no limit.
uint64_t work_ram_budget(uint64_t limit, uint64_t ram_store_bytes) {
  if (limit == 0) return ~uint64_t(0);
  return limit > ram_store_bytes ? (limit - ram_store_bytes) / 2 : 0;
}

// Bytes of left chunks (the store slices their visits read and their per-vertex work arrays)
// the scheduler keeps before releasing: the page-cache share of the limit, what the per-vertex
// arrays' RAM budget leaves. ~0 = no limit.
uint64_t resident_budget(uint64_t limit, uint64_t work_ram_bytes) {
  if (limit == 0) return ~uint64_t(0);
  return std::max<uint64_t>(limit > work_ram_bytes ? limit - work_ram_bytes : 0, 64ull << 20);
}

// The columns of `available` that options select, in the order given (file order for All).
// Throws InputError for a name the input lacks, listing those it has.
std::vector<uint32_t> selected_attribute_columns(const std::vector<VertexAttribute>& available, const PipelineOptions& options) {
  std::vector<uint32_t> columns;
  if (options.attributes == ReadOptions::Attributes::None) return columns;
  if (options.attributes == ReadOptions::Attributes::All) {
    for (uint32_t k = 0; k < available.size(); ++k) columns.push_back(k);
    return columns;
  }
  for (const std::string& name : options.attribute_names) {
    const auto it = std::find_if(available.begin(), available.end(), [&](const VertexAttribute& a) { return a.name == name; });
    if (it == available.end()) {
      std::string list;
      for (const VertexAttribute& a : available) list += (list.empty() ? "" : ", ") + a.name;
      throw InputError("no vertex attribute '" + name + "' in the input (it has " +
                       (list.empty() ? std::string("none") : list) + ")");
    }
    if (std::find(columns.begin(), columns.end(), uint32_t(it - available.begin())) == columns.end())
      columns.push_back(uint32_t(it - available.begin()));
  }
  return columns;
}

void report(const PipelineOptions& options, const StageProgress& p) {
  if (options.progress) options.progress(p);
}

}  // namespace

InputSummary summarize_input(const MeshView& mesh, uint64_t components) {
  const InputClosure closure = input_closure(mesh);
  return {mesh.vertex_count(), mesh.face_count(), components, closure.boundary_vertices, closure.closed,
          closure.euler_characteristic};
}

PipelineResult remesh_store(const MeshStore& store, const PipelineOptions& options) {
  PipelineResult result;
  result.memory_limit = options.memory_limit;
  const std::string work = options.work_directory.empty() ? default_work_directory() : options.work_directory;
  result.work_directory = work;
  MeshView view = store.view();
  const std::vector<uint32_t> columns = selected_attribute_columns(store.attributes(), options);
  for (uint32_t k : columns) result.attributes.push_back(store.attributes()[k]);
  result.subdivision_levels = subdivision_levels(view.vertex_count(), options.remesh.vertices, options.subdivide);
  const uint64_t levels = uint64_t(result.subdivision_levels);
  // Subdivision streams each level from the current store into the builder (RAM or work files),
  // with the attributes when any is carried (midpoints get their edge's mean).
  MeshStore subdivided;
  for (int level = 0; level < result.subdivision_levels; ++level) {
    report(options, {"subdivide", uint64_t(level), levels, "levels"});
    const auto t = std::chrono::steady_clock::now();
    StoreBuildOptions build;
    build.memory_limit = options.memory_limit;
    build.work_directory = work;
    build.clean_topology = false;  // a subdivided clean store is clean: no check pass
    WorkSpace scratch(work, work_ram_budget(options.memory_limit, 0));
    const MeshStore& current = level == 0 ? store : subdivided;
    const VertexAttributeRows rows =
        columns.empty() ? VertexAttributeRows{} : VertexAttributeRows{current.attributes(), current.vertex_attributes()};
    MeshStore next = MeshStore::build_from_stream(
        [&](MeshSink& sink) { stream_subdivision(view, sink, scratch, rows); }, build, nullptr, options.progress);
    subdivided = std::move(next);
    view = subdivided.view();
    result.subdivide_seconds += seconds_since(t);
    if (subdivided.ram_bytes() == 0) result.temporary_store_bytes += subdivided.size_bytes();
  }
  if (levels > 0) report(options, {.stage = "subdivide", .done = levels, .total = levels, .unit = "levels", .finished = true});
  result.remeshed_vertices = view.vertex_count();
  result.remeshed_faces = view.face_count();
  RemeshOptions remesh_options = options.remesh;
  if (!remesh_options.density.empty() && result.subdivision_levels > 0) remesh_options.density.clear();
  StoreBuildReport cleaning;
  if (store.cleaning_report(cleaning) && cleaning.cleaning.rebuilt) remesh_options.drop_cut_sheets = true;
  const uint64_t ram_store = result.subdivision_levels > 0 ? subdivided.ram_bytes() : store.ram_bytes();
  result.work_ram_bytes = work_ram_budget(options.memory_limit, ram_store);
  WorkSpace space(work, result.work_ram_bytes);
  // A store mapped from files is visited chunk by chunk through the scheduler; one in RAM is
  // resident as a whole.
  const MeshStore& remeshed = result.subdivision_levels > 0 ? subdivided : store;
  std::optional<ChunkScheduler> scheduler;
  const uint64_t resident = resident_budget(options.memory_limit, result.work_ram_bytes);
  if (remeshed.ram_bytes() == 0 && !view.chunks.empty()) {
    scheduler.emplace(remeshed, &space, resident);
    view.residency = &*scheduler;
  }
  // A store that stays resident: fresh pages are taken as in core until the job ends, however
  // it ends. Out of core no scope: 256 MiB of malloc's kept at x121 in 2 GiB took the page
  // cache's room (139.8 -> 150.6 s).
  std::optional<InCoreMemory> in_core;
  if (remeshed.ram_bytes() > 0 || remeshed.size_bytes() <= resident) in_core.emplace(options.memory_limit);
  if (!columns.empty())  // a subdivided store has every column of the input's
    remesh_options.attributes = {remeshed.vertex_attributes(), remeshed.header().attribute_count, columns};
  remesh_options.keep_vertex_labels = false;  // only the output mesh leaves the job
  remesh_options.progress = options.progress;
  result.remesh = remesh(view, remesh_options, space);
  result.work_file_peak_bytes = space.peak_file_bytes();
  if (scheduler) result.schedule = scheduler->report();
  if (result.remesh.mesh.face_count() == 0)
    // An empty file is no answer: every component was dropped, or is thinner than a cluster
    // everywhere (a needle), or has no area.
    throw InputError("remeshing left no triangle (" + std::to_string(result.remesh.clusters) +
                     " clusters; components too small or too thin for the budget of " +
                     std::to_string(options.remesh.vertices) + " vertices)");
  const auto summary_start = std::chrono::steady_clock::now();
  // The input's summary beside the output's figures (their topology and quality side by side).
  tbb::parallel_invoke(
      [&] { result.input = summarize_input(store.view(), result.remesh.budget.clusters_per_component.size()); },
      [&] {
        MeshFigures output = compute_mesh_figures(result.remesh.mesh.view());
        result.output_topology = output.topology;
        result.output_quality = std::move(output.quality);
      });
  result.summary_seconds = seconds_since(summary_start);
  return result;
}

namespace {

// The common end of remesh_path and remesh_stream: remeshes `store`, built from (or opened as)
// `input`, and fills in what the load did.
PipelineResult remesh_loaded(const MeshStore& store, const std::string& input, const PipelineOptions& o,
                             const StoreBuildReport& build_report, double load_seconds, double store_seconds,
                             bool from_store, const std::string& kept) {
  PipelineResult result;
  try {
    result = remesh_store(store, o);
  } catch (const InputError& e) {
    throw InputError(error_at(input, e.what()));  // name the file, as every CLI error does
  }
  result.input_build = build_report;
  result.load_seconds = load_seconds;
  result.store_seconds += store_seconds;
  result.store_in_ram = store.ram_bytes() > 0 || store.view().vertex_count() == 0;
  result.kept_store = kept;
  // A file input's store mapped from anonymous work files (a kept store is a result, not scratch).
  if (!from_store && kept.empty() && store.ram_bytes() == 0) result.temporary_store_bytes += store.size_bytes();
  return result;
}

StoreBuildOptions temporary_store_options(const PipelineOptions& o) {
  StoreBuildOptions build;
  build.memory_limit = o.memory_limit;
  build.work_directory = o.work_directory.empty() ? default_work_directory() : o.work_directory;
  return build;
}

}  // namespace

PipelineResult remesh_stream(const std::function<void(MeshSink&)>& produce, const std::string& name,
                             const PipelineOptions& options) {
  const auto t = std::chrono::steady_clock::now();
  report(options, {"ingest"});
  StoreBuildReport build_report;
  MeshStore store = MeshStore::build_from_stream(produce, temporary_store_options(options), &build_report, options.progress);
  const double store_seconds = seconds_since(t);
  report(options, {.stage = "ingest", .done = store.view().face_count(), .unit = "faces", .finished = true});
  return remesh_loaded(store, name, options, build_report, 0, store_seconds, false, "");
}

PipelineResult remesh_path(const std::string& input, const PipelineOptions& options) {
  auto t = std::chrono::steady_clock::now();
  MeshStore store;
  double load_seconds = 0, store_seconds = 0;
  PipelineOptions o = options;
  std::string kept;
  StoreBuildReport build_report;
  const bool from_store = is_store_directory(input);
  if (from_store) {
    report(o, {"open"});
    store = MeshStore::open(input);
    store.validate_all();  // every chunk read once: a long stage for a big store
    if (store.cleaning_report(build_report)) build_report.cleaning.cleaned = compute_topology_stats(store.view());
    report(o, {.stage = "open", .done = store.view().face_count(), .unit = "faces", .finished = true});
    if (o.work_directory.empty()) o.work_directory = input;  // work files beside the store
    load_seconds = seconds_since(t);
  } else {
    report(o, {"ingest"});
    StoreBuildOptions build = temporary_store_options(o);
    // Attributes not carried need not be stored (a kept store keeps them all, for reruns); named
    // ones are all read, so that a missing name can be reported with the ones the file has.
    ReadOptions read;
    if (o.attributes == ReadOptions::Attributes::None && !o.keep_work) read.attributes = ReadOptions::Attributes::None;
    if (o.keep_work) {
      // A named store in the work folder, kept for a rerun.
      std::string name = std::filesystem::path(input == "-" ? "stdin" : input).filename().string();
      kept = (std::filesystem::path(build.work_directory) / (name + ".store")).string();
      store = MeshStore::ingest(input, kept, build, read, &build_report, o.progress);
    } else {
      store = MeshStore::build_from_file(input, build, read, &build_report, o.progress);
    }
    store_seconds = seconds_since(t);
    report(o, {.stage = "ingest", .done = store.view().face_count(), .unit = "faces", .finished = true});
  }
  return remesh_loaded(store, input, o, build_report, load_seconds, store_seconds, from_store, kept);
}

}  // namespace streamcvd
