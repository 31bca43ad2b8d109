#include "python/src/functions.h"

#include <tbb/global_control.h>

#include <chrono>
#include <memory>

#include "streamcvd/core/clustering/cluster_energy.h"
#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/measure/surface_distance.h"
#include "python/src/arrays.h"
#include "python/src/job.h"
#include "streamcvd/streaming/schedule/memory_budget.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/io/output_file.h"
#include "streamcvd/streaming/run_reports.h"
#include "streamcvd/streaming/store/store.h"

namespace streamcvd::python {

namespace {

constexpr const char* kArraysName = "<arrays>";  // the input's name in reports and errors

double now() { return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count(); }

bool is_int(py::handle h) { return py::isinstance<py::int_>(h) && !py::isinstance<py::bool_>(h); }

// memory=: None (the CLI's default limit), a byte count, or a size text ("512M", "2G").
uint64_t memory_bytes(py::handle memory) {
  if (memory.is_none()) return default_memory_limit();
  if (py::isinstance<py::str>(memory)) return parse_memory_size(memory.cast<std::string>());
  if (is_int(memory)) {
    const auto bytes = memory.cast<int64_t>();
    if (bytes <= 0) throw py::value_error("memory: expected a positive byte count, got " + std::to_string(bytes));
    return uint64_t(bytes);
  }
  throw py::type_error("memory: expected None, a byte count or a size such as \"512M\", got " +
                       std::string(py::str(memory.get_type())));
}

std::string optional_path(py::handle path) { return path.is_none() ? std::string() : path_text(path); }

// threads=: 0 = all cores, else TBB is limited to that many for the job's lifetime (as --threads).
std::unique_ptr<tbb::global_control> thread_limit(int threads) {
  if (threads < 0 || threads > 4096) throw py::value_error("threads: expected 0 (all cores) to 4096, got " + std::to_string(threads));
  if (threads == 0) return nullptr;
  return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, size_t(threads));
}

template <class T>
void check_range(const char* name, T value, T lo, T hi) {
  if (!(value >= lo && value <= hi))
    throw py::value_error(std::string(name) + ": expected " + std::to_string(lo) + " to " + std::to_string(hi) + ", got " +
                          std::to_string(value));
}

// The CLI's remesh options (tools/cmd_remesh.cpp) from the keyword arguments.
PipelineOptions pipeline_options(const RemeshArgs& a) {
  PipelineOptions o;
  if (!is_int(a.n)) throw py::type_error("n: expected an int (output vertices), got " + std::string(py::str(a.n.get_type())));
  const auto n = a.n.cast<int64_t>();
  if (n < 4) throw py::value_error("n: at least 4 output vertices (a tetrahedron), got " + std::to_string(n));
  check_range<int64_t>("n", n, 4, 2'000'000'000);
  o.remesh.vertices = uint32_t(n);
  o.remesh.seed = a.seed;
  ClusteringOptions& clustering = o.remesh.clustering;
  if (!parse_metric(a.metric, clustering.metric))
    throw py::value_error("metric: expected 'I', 'IQ', 'A' or 'AQ', got '" + a.metric + "'");
  if (!parse_algorithm(a.algorithm, clustering.algorithm))
    throw py::value_error("algorithm: expected 'cvd' or 'lloyd', got '" + a.algorithm + "'");
  if (clustering.algorithm == ClusteringOptions::Algorithm::Lloyd && is_anisotropic(clustering.metric))
    throw py::value_error("algorithm='lloyd': only the metrics I and IQ are implemented, got " + a.metric);
  check_range("gradation", a.gradation, -8.0, 8.0);
  check_range("curvature_rings", a.curvature_rings, 1, 10);
  check_range("qem_threshold", a.qem_threshold, 0.0, 1.0);
  check_range("threads", a.threads, 0, 4096);
  o.remesh.gradation = a.gradation;
  o.remesh.curvature_rings = a.curvature_rings;
  clustering.qem_threshold = a.qem_threshold;
  clustering.loops.threads = uint32_t(a.threads);
  clustering.loops.deterministic = a.deterministic;
  o.remesh.boundary_strips = a.boundary_strips;
  o.remesh.project_to_surface = a.project;
  o.remesh.optimize_quality = a.optimize;
  if (!parse_small_components(a.small_components, o.remesh.small_components))
    throw py::value_error("small_components: expected 'keep' or 'drop', got '" + a.small_components + "'");
  if (py::isinstance<py::str>(a.subdivide) && a.subdivide.cast<std::string>() == "auto") {
    o.subdivide = -1;
  } else if (py::isinstance<py::str>(a.subdivide) && a.subdivide.cast<std::string>() == "none") {
    o.subdivide = 0;
  } else if (is_int(a.subdivide) && a.subdivide.cast<int64_t>() >= 0 && a.subdivide.cast<int64_t>() <= 6) {
    o.subdivide = a.subdivide.cast<int>();
  } else {
    throw py::value_error("subdivide: expected 'auto', 'none' or a level 0-6, got " + std::string(py::repr(a.subdivide)));
  }
  o.memory_limit = memory_bytes(a.memory);
  o.work_directory = optional_path(a.work_dir);
  return o;
}

// One remesh job's control and measurements: the progress callback that obeys Ctrl-C (installed
// in the options), the thread limit, the start time and I/O counters of the report.
struct RemeshRun {
  JobControl control;
  std::unique_ptr<tbb::global_control> limit;
  double t0 = now();
  IoCounters io0 = read_io_counters();

  RemeshRun(PipelineOptions& options, const RemeshArgs& args) : control(args.progress), limit(thread_limit(args.threads)) {
    options.progress = control.callback();
    control.io_log.start();
  }
  RemeshJobRecord record(const std::string& input, const std::string& output, double write_seconds) const {
    return {input, output, write_seconds, now() - t0, io0, &control.io_log};
  }
};

// remesh_file's attributes=: None or "all", "none", or a list of names.
void select_attributes(py::handle selection, PipelineOptions& o) {
  if (selection.is_none() || (py::isinstance<py::str>(selection) && selection.cast<std::string>() == "all")) {
    o.attributes = ReadOptions::Attributes::All;
  } else if (py::isinstance<py::str>(selection) && selection.cast<std::string>() == "none") {
    o.attributes = ReadOptions::Attributes::None;
  } else if ((py::isinstance<py::list>(selection) || py::isinstance<py::tuple>(selection))) {
    o.attributes = ReadOptions::Attributes::Named;
    for (py::handle name : selection) {
      if (!py::isinstance<py::str>(name)) throw py::type_error("attributes: names must be strings");
      o.attribute_names.push_back(name.cast<std::string>());
    }
  } else {
    throw py::type_error("attributes: expected None, 'all', 'none' or a list of names, got " +
                         std::string(py::repr(selection)));
  }
}

// `out` holding `mesh` and its attribute rows, the buffers handed over to numpy.
void hand_over_mesh(Mesh& out, MeshBuffers&& mesh, std::vector<float>&& rows, const std::vector<VertexAttribute>& attributes) {
  const size_t V = mesh.vertex_count(), F = mesh.face_count(), K = attributes.size();
  out.points = hand_over(std::move(mesh.positions), V, 3);
  out.faces = hand_over(std::move(mesh.triangles), F, 3);
  if (K > 0) {
    py::array_t<float> row_array = hand_over(std::move(rows), V, K);
    out.attributes = attribute_columns(row_array, attributes);
    out.attribute_rows = row_array;
  }
  out.attribute_list = attributes;
  out.attribute_types = attribute_types(attributes);
}

// The output of a remesh job, its buffers handed over to numpy.
Result make_result(PipelineResult&& r, const nlohmann::json& report, std::string comment) {
  Result out;
  hand_over_mesh(out, std::move(r.remesh.mesh), std::move(r.remesh.vertex_attributes), r.attributes);
  out.report = to_python(report);
  out.comment = std::move(comment);
  return out;
}

WriteOptions write_options(bool ascii, const std::string& comment, const std::vector<VertexAttribute>& attributes,
                           std::span<const float> rows) {
  WriteOptions w;
  w.ascii = ascii;
  w.comment = comment;
  if (!attributes.empty()) w.attributes = {attributes, rows};
  return w;
}

// A mesh argument of quality(), info(), distance(): a Mesh or Result, or points with faces.
InputMesh mesh_argument(py::handle mesh, py::handle faces, const char* what) {
  if (faces.is_none() && py::hasattr(mesh, "points") && py::hasattr(mesh, "faces"))
    return input_mesh(mesh.attr("points"), mesh.attr("faces"));
  if (faces.is_none() && py::isinstance<py::tuple>(mesh) && py::len(mesh) == 2)
    return input_mesh(mesh[py::int_(0)], mesh[py::int_(1)]);
  if (faces.is_none())
    throw py::type_error(std::string(what) + ": expected a Mesh, a (points, faces) tuple or points with faces=");
  return input_mesh(mesh, faces);
}

bool is_path(py::handle h) { return py::isinstance<py::str>(h) || py::hasattr(h, "__fspath__"); }

}  // namespace

std::string path_text(py::handle path) {
  if (py::isinstance<py::str>(path)) return path.cast<std::string>();
  if (py::hasattr(path, "__fspath__")) {
    py::object text = path.attr("__fspath__")();
    if (py::isinstance<py::str>(text)) return text.cast<std::string>();
  }
  throw py::type_error("expected a path (str or os.PathLike), got " + std::string(py::str(path.get_type())));
}

void Mesh::write(const std::string& path, bool ascii) const {
  const InputMesh mesh = input_mesh(points, faces);  // checked again: the arrays may have been edited
  std::span<const float> rows;
  py::array_t<float, py::array::c_style> row_array;
  if (!attribute_rows.is_none()) {
    row_array = py::array_t<float, py::array::c_style | py::array::forcecast>::ensure(attribute_rows);
    rows = {row_array.data(), size_t(row_array.size())};
  }
  const WriteOptions w = write_options(ascii, comment, attribute_list, rows);
  py::gil_scoped_release release;
  write_mesh(path, mesh.view(), w);
}

Result remesh_arrays(py::handle points, py::handle faces, const RemeshArgs& args) {
  if (!args.attributes.is_none() && !py::isinstance<py::dict>(args.attributes))
    throw py::type_error("attributes: remesh() takes a dict {name: array of V values} (remesh_file() selects by name)");
  const InputMesh mesh = input_mesh(points, faces, args.attributes);
  PipelineOptions options = pipeline_options(args);
  options.attributes = mesh.attributes.empty() ? ReadOptions::Attributes::None : ReadOptions::Attributes::All;
  RemeshRun run(options, args);
  PipelineResult r = run_interruptible(run.control, [&] {
    return remesh_stream([&](MeshSink& sink) { mesh.stream(sink, run.control.cancel); }, kArraysName, options);
  });
  const nlohmann::json report = remesh_report(r, options, run.record(kArraysName, "", 0));
  return make_result(std::move(r), report, remesh_output_comment(options));
}

Result remesh_file(const std::string& input, const std::string& output, const RemeshArgs& args, py::object report_path,
                   bool keep_work, bool ascii) {
  PipelineOptions options = pipeline_options(args);
  select_attributes(args.attributes, options);
  options.keep_work = keep_work;
  format_from_path(output);  // an unknown output extension is refused before the work
  const std::string report_file = optional_path(report_path);
  RemeshRun run(options, args);
  double write_seconds = 0;
  PipelineResult r = run_interruptible(run.control, [&] {
    PipelineResult result = remesh_path(input, options);
    if (run.control.cancel) throw Cancelled{};  // interrupted at the end of the job: no output either
    const double t_write = now();
    const std::span<const float> rows(result.remesh.vertex_attributes);
    write_mesh(output, result.remesh.mesh.view(),
               write_options(ascii, remesh_output_comment(options), result.attributes, rows));
    write_seconds = now() - t_write;
    return result;
  });
  const nlohmann::json report = remesh_report(r, options, run.record(input, output, write_seconds));
  if (!report_file.empty()) write_file_atomic(report_file, report.dump(2) + "\n");
  return make_result(std::move(r), report, remesh_output_comment(options));
}

Mesh read(const std::string& path, py::handle attributes) {
  PipelineOptions selection;
  select_attributes(attributes, selection);
  ReadOptions read;
  read.attributes = selection.attributes;
  read.attribute_names = selection.attribute_names;
  JobControl control;
  read.progress = [&control](uint64_t, uint64_t) {
    if (control.cancel.load(std::memory_order_relaxed)) throw Cancelled{};
  };
  MeshWithAttributes m = run_interruptible(control, [&] { return read_mesh_with_attributes(path, read); });
  Mesh out;
  hand_over_mesh(out, std::move(m.mesh), std::move(m.values), m.attributes);
  return out;
}

void write(const std::string& path, py::handle points, py::handle faces, py::handle attributes, py::handle types,
           bool ascii, const std::string& comment) {
  const InputMesh mesh = input_mesh(points, faces, attributes, types);
  const WriteOptions w = write_options(ascii, comment, mesh.attributes, mesh.attribute_values);
  py::gil_scoped_release release;
  write_mesh(path, mesh.view(), w);
}

py::object ingest(const std::string& input, const std::string& store, py::object memory, py::object work_dir,
                  int threads, uint64_t faces_per_chunk, py::object progress) {
  StoreBuildOptions options;
  options.memory_limit = memory_bytes(memory);
  options.work_directory = optional_path(work_dir);
  if (faces_per_chunk == 0) throw py::value_error("faces_per_chunk: expected at least 1");
  options.faces_per_chunk = faces_per_chunk;
  const auto limit = thread_limit(threads);
  JobControl control(std::move(progress));
  const nlohmann::json j = run_interruptible(control, [&] {
    const double t0 = now();
    StoreBuildReport report;
    MeshStore built = MeshStore::ingest(input, store, options, {}, &report, control.callback());
    return ingest_report(input, store, built, report, now() - t0);
  });
  return to_python(j);
}

py::object quality(py::handle points, py::handle faces) {
  const InputMesh mesh = mesh_argument(points, faces, "quality");
  QualityStats q;
  {
    py::gil_scoped_release release;
    q = compute_quality(mesh.view());
  }
  return to_python(quality_json(q));
}

py::object info(py::handle mesh, py::handle faces, py::object memory, py::object work_dir, int threads) {
  StoreBuildOptions options;
  options.memory_limit = memory_bytes(memory);
  options.work_directory = optional_path(work_dir);
  const auto limit = thread_limit(threads);
  JobControl control;
  if (is_path(mesh) && faces.is_none()) {
    const std::string path = path_text(mesh);
    return to_python(run_interruptible(control, [&] { return info_json(path, inspect_mesh(path, options, control.callback())); }));
  }
  const InputMesh m = mesh_argument(mesh, faces, "info");
  return to_python(run_interruptible(control, [&] {
    const StoreBuildReport build =
        inspect_mesh([&](MeshSink& sink) { m.stream(sink, control.cancel); }, options, control.callback());
    return info_json(kArraysName, build);
  }));
}

py::object distance(py::handle a, py::handle b, uint64_t samples, uint64_t seed, int threads) {
  if (samples > kMaxDistanceSamples)
    throw py::value_error("samples: " + std::to_string(samples) + " is above the limit of " +
                          std::to_string(kMaxDistanceSamples) + " per side");
  auto load = [](py::handle m) {
    if (!is_path(m)) return mesh_argument(m, py::none(), "distance");
    Mesh read_in = read(path_text(m), py::str("none"));
    return input_mesh(read_in.points, read_in.faces);
  };
  const InputMesh ma = load(a), mb = load(b);
  const auto limit = thread_limit(threads);
  JobControl control;
  const DistanceReport d = run_interruptible(control, [&] { return surface_distance(ma.view(), mb.view(), samples, seed); });
  return to_python(distance_json(d));
}

}  // namespace streamcvd::python
