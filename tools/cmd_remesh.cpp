// `streamcvd remesh`: the main job. Reads a mesh or store, remeshes it to N vertices, writes the
// output atomically, checks the output guarantees and writes a JSON report.
#include <tbb/global_control.h>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/io/output_file.h"
#include "streamcvd/core/clustering/parallel_clustering.h"
#include "streamcvd/streaming/remesh_pipeline.h"
#include "streamcvd/streaming/run_reports.h"
#include "streamcvd/streaming/schedule/memory_budget.h"
#include "tools/commands.h"
#include "tools/job_options.h"

namespace streamcvd::cli {

void print_quality(const QualityStats& q);
void print_cleaning(std::FILE* out, const StoreBuildReport& build, const char* indent);

namespace {

// The library's defaults (RemeshOptions{}): the command line's, option by option.
const RemeshOptions kDefaults;

struct RemeshArgs {
  std::string input, output, report, subdivide = "auto";
  std::string small_components = small_components_name(kDefaults.small_components);
  std::string metric = metric_name(kDefaults.clustering.metric);
  std::string algorithm = algorithm_name(kDefaults.clustering.algorithm);
  std::string attributes = "all";
  int curvature_rings = kDefaults.curvature_rings;
  double gradation = kDefaults.gradation, qem_threshold = kDefaults.clustering.qem_threshold;
  uint32_t vertices = kDefaults.vertices;
  uint32_t threads = kDefaults.clustering.loops.threads;
  uint64_t seed = kDefaults.seed;
  bool no_strips = !kDefaults.boundary_strips, no_project = !kDefaults.project_to_surface;
  bool no_optimize = !kDefaults.optimize_quality, deterministic = kDefaults.clustering.loops.deterministic;
  bool ascii = false, quiet = false, keep_work = false;
  JobOptions job;
};

// --attributes: all, none, or a comma-separated list of names.
void parse_attributes(const std::string& text, PipelineOptions& options) {
  if (text == "all") {
    options.attributes = ReadOptions::Attributes::All;
    return;
  }
  if (text == "none") {
    options.attributes = ReadOptions::Attributes::None;
    return;
  }
  options.attributes = ReadOptions::Attributes::Named;
  for (size_t begin = 0;;) {
    const size_t end = std::min(text.find(',', begin), text.size());
    const std::string name = text.substr(begin, end - begin);
    if (name.empty() || name.find_first_of(" \t") != std::string::npos)
      throw InputError("--attributes: expected all, none or comma-separated names, got '" + text + "'");
    options.attribute_names.push_back(name);
    if (end == text.size()) break;
    begin = end + 1;
  }
}

}  // namespace

void add_remesh_command(CLI::App& app) {
  auto args = std::make_shared<RemeshArgs>();
  auto* cmd = app.add_subcommand("remesh", "Remesh a mesh to N vertices by discrete centroidal Voronoi clustering");
  cmd->add_option("input", args->input, "Mesh file (PLY/OBJ/OFF/STL, optionally .zst) or store directory")->required();
  cmd->add_option("-o,--output", args->output, "Output mesh (.ply .obj .off .stl, optionally + .zst)")->required();
  cmd->add_option("-n,--vertices", args->vertices, "Output vertices N, exactly (boundary-strip vertices included); not met only when the strips alone need N/2 or more, or small components kept need more: the report's vertex_count_note says why and by how much")->required()->check(CLI::Range(1u, 2000000000u));
  cmd->add_option("--seed", args->seed, "Seed of the initial sampling (same seed, same output)")->capture_default_str();
  cmd->add_option("--report", args->report, "Write a JSON report of the run to this file");
  cmd->add_option("--subdivide", args->subdivide,
                  "Linear 1->4 subdivision first: auto (when fewer than ~10 input vertices per cluster), none, or K levels")
      ->capture_default_str();
  cmd->add_option("--small-components", args->small_components,
                  "Components too small for one cluster of the budget: keep (give them the few clusters they need) or drop")
      ->capture_default_str()
      ->check(CLI::IsMember({"keep", "drop"}));
  cmd->add_option("--metric", args->metric,
                  "Clustering metric (paper §V): I isotropic, IQ isotropic with QEM vertex placement (faithful to "
                  "features), A anisotropic (curvature tensors), AQ anisotropic with QEM placement")
      ->capture_default_str()
      ->transform(CLI::IsMember({"I", "IQ", "A", "AQ"}, CLI::ignore_case));
  cmd->add_option("--algorithm", args->algorithm,
                  "Clustering algorithm: cvd (Algorithm 1 of the paper) or lloyd (Lloyd relaxation baseline of "
                  "§VII, metrics I and IQ only)")
      ->capture_default_str()
      ->transform(CLI::IsMember({"cvd", "lloyd"}, CLI::ignore_case));
  cmd->add_option("--gradation", args->gradation,
                  "Curvature-adapted density, eq. 20: rho = area * |curvature|^gamma (0 = uniform); with A/AQ it "
                  "only shapes the initial sampling")
      ->capture_default_str()
      ->check(CLI::Range(-8.0, 8.0));
  cmd->add_option("--curvature-rings", args->curvature_rings,
                  "Rings of the curvature fit used by --gradation and A/AQ (3 as in the paper; 6-8 for noisy scans)")
      ->capture_default_str()
      ->check(CLI::Range(1, 10));
  cmd->add_option("--qem-threshold", args->qem_threshold,
                  "IQ/AQ: quadric eigenvalues below this fraction of the largest are ignored when placing a vertex; "
                  "1e-3 keeps more sharp corners of clean CAD models, larger values suit noisy scans")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 1.0));
  cmd->add_flag("--no-boundary-strips", args->no_strips, "Do not add the triangle strips along input boundaries (§VI-D)");
  cmd->add_flag("--no-project", args->no_project,
                "Output vertices at the raw cluster centroids (eq. 15) instead of projected onto the input surface");
  cmd->add_flag("--no-optimize", args->no_optimize,
                "Skip the quality post-pass (edge flips between nearly coplanar triangles, tangential relaxation)");
  cmd->add_option("--attributes", args->attributes,
                  "Vertex attributes carried to the output as area-weighted means over each cluster: all, none, or "
                  "names separated by commas (e.g. red,green,blue,confidence). PLY output keeps their names and types "
                  "(integers rounded and clamped); OBJ gets the colours as 'v x y z r g b' in [0,1] and drops the "
                  "other scalars; OFF and STL drop them all. Normals (nx ny nz) are never carried: the output has "
                  "none (recompute them from its faces)")
      ->capture_default_str();
  cmd->add_flag("--ascii", args->ascii, "Write ascii PLY");
  cmd->add_flag("-q,--quiet", args->quiet, "No summary on stderr (and no progress unless --progress always)");
  cmd->add_option("--threads", args->threads,
                  "Worker threads (store build, items, sorts and the clustering); default all cores. With more "
                  "than one thread the clustering runs in parallel and, without --deterministic, two runs with "
                  "the same seed and thread count may give slightly different (equally valid) outputs; "
                  "--threads 1 is the serial, reproducible clustering")
      ->check(CLI::Range(1u, 4096u));
  cmd->add_flag("--deterministic", args->deterministic,
                "Parallel clustering whose output is byte-identical for every thread count and run (lock-free "
                "phases over fixed regions; slightly slower)");
  add_job_options(cmd, args->job, /*with_threads=*/false);
  cmd->add_flag("--keep-work", args->keep_work,
                "Keep the store built from a file input in the work folder (named <input>.store), for reruns");
  cmd->callback([args] {
    PipelineOptions options;
    RemeshOptions& remesh = options.remesh;
    remesh.vertices = args->vertices;
    remesh.seed = args->seed;
    if (!parse_metric(args->metric, remesh.clustering.metric))
      throw InputError("--metric: expected I, IQ, A or AQ, got '" + args->metric + "'");
    if (!parse_algorithm(args->algorithm, remesh.clustering.algorithm))
      throw InputError("--algorithm: expected cvd or lloyd, got '" + args->algorithm + "'");
    if (remesh.clustering.algorithm == ClusteringOptions::Algorithm::Lloyd && is_anisotropic(remesh.clustering.metric))
      throw InputError("--algorithm lloyd: only the metrics I and IQ are implemented, got " + args->metric);
    remesh.gradation = args->gradation;
    remesh.curvature_rings = args->curvature_rings;
    remesh.clustering.qem_threshold = args->qem_threshold;
    remesh.clustering.loops.threads = args->threads;  // 0: all cores (within the limit below)
    remesh.clustering.loops.deterministic = args->deterministic;
    remesh.boundary_strips = !args->no_strips;
    remesh.project_to_surface = !args->no_project;
    remesh.optimize_quality = !args->no_optimize;
    if (!parse_small_components(args->small_components, remesh.small_components))
      throw InputError("--small-components: expected keep or drop, got '" + args->small_components + "'");
    if (args->subdivide == "auto") options.subdivide = -1;
    else if (args->subdivide == "none") options.subdivide = 0;
    else {
      try {
        size_t used = 0;
        options.subdivide = std::stoi(args->subdivide, &used);
        if (used != args->subdivide.size() || options.subdivide < 0 || options.subdivide > 6) throw std::invalid_argument("");
      } catch (const std::exception&) {
        throw InputError("--subdivide: expected auto, none or a level 0-6, got '" + args->subdivide + "'");
      }
    }
    parse_attributes(args->attributes, options);
    format_from_path(args->output);  // reject an unknown output extension before the work
    install_signal_cleanup();
    std::unique_ptr<tbb::global_control> thread_limit;
    if (args->threads > 0)
      thread_limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, args->threads);
    options.memory_limit = memory_limit(args->job);
    options.work_directory = args->job.work_dir;
    options.keep_work = args->keep_work;
    // One line per stage on a terminal (or with --progress always): batch logs stay clean, and
    // -q, which silences the summary, silences the automatic progress too.
    auto progress = std::make_shared<ProgressLine>("remesh", args->job, args->quiet);
    auto stage_io = std::make_shared<StageIoLog>();
    if (progress->active() || !args->report.empty())
      options.progress = [progress, stage_io](const StageProgress& p) {
        stage_io->see(p);
        progress->update(p);
      };
    double t0 = now_seconds();
    const IoCounters io0 = read_io_counters();
    stage_io->start();
    PipelineResult r = remesh_path(args->input, options);
    double t_write = now_seconds();
    progress->update({"write"});
    WriteOptions write_options;
    write_options.ascii = args->ascii;
    write_options.comment = remesh_output_comment(options);
    if (!r.attributes.empty()) write_options.attributes = {r.attributes, r.remesh.vertex_attributes};
    write_mesh(args->output, r.remesh.mesh.view(), write_options);
    double write_seconds = now_seconds() - t_write;
    progress->update({.stage = "write", .done = r.remesh.mesh.face_count(), .unit = "faces", .finished = true});
    progress->finish();
    double total = now_seconds() - t0;
    bool all_ok = false;
    const nlohmann::json checks = guarantee_checks(r, args->vertices, all_ok);
    const RemeshResult& rm = r.remesh;
    const ClusteringReport& cr = rm.clustering;
    if (!args->report.empty()) {
      const RemeshJobRecord job{args->input, args->output, write_seconds, total, io0, stage_io.get()};
      const nlohmann::json j = remesh_report(r, options, job);
      write_file_atomic(args->report, j.dump(2) + "\n");
    }
    if (!args->quiet) {
      std::fprintf(stderr, "remesh: %s -> %s (metric %s)\n", args->input.c_str(), args->output.c_str(),
                   metric_name(rm.clustering.metric));
      std::fprintf(stderr, "  input  %llu vertices, %llu faces, %llu components%s\n",
                   (unsigned long long)r.input.vertices, (unsigned long long)r.input.faces,
                   (unsigned long long)r.input.components, r.subdivision_levels ? " (subdivided)" : "");
      if (r.input_build.cleaning.rebuilt) print_cleaning(stderr, r.input_build, "  ");
      std::fprintf(stderr, "  output %llu vertices (%llu clusters + %llu on boundary strips), %llu faces, Qav %.3f, angles<30 %.2f%%\n",
                   (unsigned long long)r.output_topology.vertices,
                   (unsigned long long)(r.output_topology.vertices - rm.dual.boundary_vertices_added),
                   (unsigned long long)rm.dual.boundary_vertices_added, (unsigned long long)r.output_topology.faces,
                   r.output_quality.q_avg, r.output_quality.percent_angles_below_30);
      std::fprintf(stderr, "  loops  %u + %u, repair rounds %u; time %.2f s (load %.2f, clustering %.2f); peak %.0f MB\n",
                   cr.unconstrained_loops, cr.constrained_loops, rm.repair.rounds, total, r.load_seconds,
                   rm.seconds.clustering, double(peak_rss_bytes()) / 1e6);
      std::fprintf(stderr, "  checks %s\n", all_ok ? "all passed" : "FAILED (below)");
    }
    if (!all_ok) throw CheckFailed(args->output + ": " + failed_checks(checks));
  });
}

}  // namespace streamcvd::cli
