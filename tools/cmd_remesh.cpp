// `streamcvd remesh`: the main job. Reads a mesh or store, remeshes it to N vertices, writes the
// output atomically, checks the output guarantees and writes a JSON report.
#include <tbb/global_control.h>

#include <algorithm>
#include <cstdio>
#include <memory>
#include <string>

#include "core/errors.h"
#include "streaming/mesh_io.h"
#include "streaming/output_file.h"
#include "core/parallel_clustering.h"
#include "streaming/remesh_pipeline.h"
#include "streaming/memory_budget.h"
#include "tools/commands.h"
#include "tools/job_options.h"

namespace streamcvd::cli {

nlohmann::json quality_json(const QualityStats& q);  // cmd_inspect.cpp
void print_quality(const QualityStats& q);
nlohmann::json cleaning_json(const StoreBuildReport& build);
void print_cleaning(std::FILE* out, const StoreBuildReport& build, const char* indent);

namespace {

struct RemeshArgs {
  std::string input, output, report, subdivide = "auto", small_components = "keep", metric = "IQ", algorithm = "cvd";
  std::string attributes = "all";
  int curvature_rings = 3;
  double gradation = 0, qem_threshold = ClusteringOptions{}.qem_threshold;
  uint32_t vertices = 10000;
  uint32_t threads = 0;
  uint64_t seed = RemeshOptions{}.seed;
  bool no_strips = false, no_project = false, no_optimize = false, ascii = false, quiet = false, deterministic = false;
  bool keep_work = false;
  JobOptions job;
};

// The output guarantees of a run (issue: closed manifold in → closed, oriented manifold out).
nlohmann::json guarantee_checks(const PipelineResult& r, uint32_t requested, bool& all_ok) {
  const TopologyStats& out = r.output_topology;
  const RemeshResult& rm = r.remesh;
  uint64_t cluster_vertices = out.vertices - rm.boundary_vertices_added;
  bool closed_in = r.input.closed;
  bool single_component = r.input.components == 1;
  nlohmann::json j = {
      {"input_closed_manifold", closed_in},
      {"output_closed_manifold", out.closed_manifold},
      {"output_consistently_oriented", out.consistently_oriented},
      {"output_nonmanifold_edges", out.nonmanifold_edges},
      {"output_nonmanifold_vertices", out.nonmanifold_vertices},
      {"output_duplicate_faces", out.duplicate_faces},
      {"output_degenerate_faces", out.degenerate_faces},
      {"output_isolated_vertices", out.isolated_vertices},
      {"clusters_connected", rm.clusters_connected},
      {"defect_vertices_after_repair", rm.defect_vertices},
      {"requested_vertices", requested},
      {"cluster_vertices", cluster_vertices},
      {"boundary_strip_vertices", rm.boundary_vertices_added},
      {"exact_vertex_count", out.vertices == requested},
      {"input_euler_characteristic", r.input.euler_characteristic},
      {"output_euler_characteristic", out.euler_characteristic},
  };
  if (!rm.budget.note.empty()) j["vertex_count_note"] = rm.budget.note;
  bool manifold_ok = out.nonmanifold_edges == 0 && out.nonmanifold_vertices == 0 && out.duplicate_faces == 0 &&
                     out.degenerate_faces == 0 && out.isolated_vertices == 0;
  bool closed_ok = !closed_in || (out.closed_manifold && out.consistently_oriented);
  bool genus_ok = !closed_in || out.euler_characteristic == r.input.euler_characteristic;
  if (closed_in && single_component) j["genus_preserved"] = genus_ok;
  else if (closed_in) j["euler_characteristic_preserved"] = genus_ok;
  j["manifold_ok"] = manifold_ok;
  j["closed_ok"] = closed_ok;
  j["topology_changed"] = rm.topology_changed;
  const bool components_ok = rm.components.ok();
  j["components_ok"] = components_ok;
  j["input_components_with_clusters"] = rm.components.input_components;
  j["output_components"] = rm.components.output_components;
  if (!components_ok) j["component_problems"] = rm.components.problems;
  // Against the input as cleaned (its sheets and their boundaries, streaming/store_clean.h): a
  // hole below the output resolution may close, none may open; no piece may come apart.
  const bool holes_ok = out.boundary_loops <= rm.components.input_boundary_loops;
  const bool pieces_ok = out.components <= rm.components.input_components;
  j["cleaned_input_boundary_loops"] = rm.components.input_boundary_loops;
  j["output_boundary_loops"] = out.boundary_loops;
  j["holes_ok"] = holes_ok;
  j["pieces_ok"] = pieces_ok;
  all_ok = manifold_ok && closed_ok && genus_ok && !rm.topology_changed && rm.defect_vertices == 0 && components_ok &&
           holes_ok && pieces_ok;
  j["all_ok"] = all_ok;
  return j;
}

// The failed guarantees of `checks`, with their figures, on one line.
std::string failed_checks(const nlohmann::json& checks) {
  std::string out;
  auto add = [&](const std::string& what) { out += (out.empty() ? "" : "; ") + what; };
  if (!checks.value("manifold_ok", true))
    add("not a clean manifold (" + std::to_string(checks.value("output_nonmanifold_edges", 0)) + " non-manifold edges, " +
        std::to_string(checks.value("output_nonmanifold_vertices", 0)) + " non-manifold vertices, " +
        std::to_string(checks.value("output_duplicate_faces", 0)) + " duplicate and " +
        std::to_string(checks.value("output_degenerate_faces", 0)) + " degenerate faces, " +
        std::to_string(checks.value("output_isolated_vertices", 0)) + " isolated vertices)");
  if (!checks.value("closed_ok", true)) add("the input is closed, the output is not");
  if (!checks.value("genus_preserved", true) || !checks.value("euler_characteristic_preserved", true))
    add("Euler characteristic " + std::to_string(checks.value("output_euler_characteristic", 0)) + ", the input has " +
        std::to_string(checks.value("input_euler_characteristic", 0)));
  if (checks.value("topology_changed", false)) add("topology changed (faces deleted around defects)");
  if (checks.value("defect_vertices_after_repair", 0) > 0)
    add(std::to_string(checks.value("defect_vertices_after_repair", 0)) + " vertices still on defects");
  if (!checks.value("holes_ok", true))
    add(std::to_string(checks.value("output_boundary_loops", 0)) + " boundary loops, the cleaned input has " +
        std::to_string(checks.value("cleaned_input_boundary_loops", 0)));
  if (!checks.value("pieces_ok", true))
    add(std::to_string(checks.value("output_components", 0)) + " components, the cleaned input has " +
        std::to_string(checks.value("input_components_with_clusters", 0)) + " with clusters");
  if (!checks.value("components_ok", true)) {
    std::string list;
    for (const auto& p : checks["component_problems"]) list += (list.empty() ? "" : ", ") + p.get<std::string>();
    add("components: " + list);
  }
  return out;
}

// Disk bytes read and written per stage (the report's io.stages): the counters are read when a
// stage's final report arrives, so a stage gets what happened since the previous one ended.
// Out of core this tells which stage pays for the paging.
class StageIoLog {
 public:
  void see(const StageProgress& p) {
    if (!p.finished) return;
    const IoCounters now = read_io_counters();
    auto it = std::find_if(stages_.begin(), stages_.end(), [&](const auto& s) { return s.first == p.stage; });
    if (it == stages_.end()) it = stages_.insert(stages_.end(), {p.stage, IoCounters{}});
    it->second.read_bytes += now.read_bytes - last_.read_bytes;
    it->second.write_bytes += now.write_bytes - last_.write_bytes;
    last_ = now;
  }
  void start() { last_ = read_io_counters(); }
  nlohmann::json json() const {
    nlohmann::json j = nlohmann::json::object();
    for (const auto& [stage, io] : stages_) j[stage] = {{"read_bytes", io.read_bytes}, {"write_bytes", io.write_bytes}};
    return j;
  }

 private:
  IoCounters last_;
  std::vector<std::pair<std::string, IoCounters>> stages_;  // in the order they ended
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

// The report's attributes: those carried (input names and types) and those the output's format
// holds.
nlohmann::json attributes_json(const PipelineResult& r, const std::string& output) {
  nlohmann::json carried = nlohmann::json::array(), written = nlohmann::json::array();
  for (const VertexAttribute& a : r.attributes) carried.push_back({{"name", a.name}, {"type", scalar_type_name(a.type)}});
  for (size_t k : attributes_written(format_from_path(output), r.attributes)) written.push_back(r.attributes[k].name);
  return {{"carried", carried}, {"written", written}, {"normals", "not carried (not written)"}};
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
    options.remesh.vertices = args->vertices;
    options.remesh.seed = args->seed;
    if (!parse_metric(args->metric, options.remesh.clustering.metric))
      throw InputError("--metric: expected I, IQ, A or AQ, got '" + args->metric + "'");
    if (args->algorithm == "lloyd") {
      if (is_anisotropic(options.remesh.clustering.metric))
        throw InputError("--algorithm lloyd: only the metrics I and IQ are implemented, got " + args->metric);
      options.remesh.clustering.algorithm = ClusteringOptions::Algorithm::Lloyd;
    }
    options.remesh.gradation = args->gradation;
    options.remesh.curvature_rings = args->curvature_rings;
    options.remesh.clustering.qem_threshold = args->qem_threshold;
    options.remesh.clustering.threads = args->threads;  // 0: all cores (within the limit below)
    options.remesh.clustering.deterministic = args->deterministic;
    options.remesh.boundary_strips = !args->no_strips;
    options.remesh.project_to_surface = !args->no_project;
    options.remesh.optimize_quality = !args->no_optimize;
    options.remesh.small_components = args->small_components == "drop" ? SmallComponents::Drop : SmallComponents::Keep;
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
    write_options.comment = "streamcvd remesh -n " + std::to_string(args->vertices) + " --seed " + std::to_string(args->seed);
    if (!r.attributes.empty()) write_options.attributes = {r.attributes, r.remesh.vertex_attributes};
    write_mesh(args->output, r.remesh.mesh.view(), write_options);
    double write_seconds = now_seconds() - t_write;
    progress->update({.stage = "write", .done = r.remesh.mesh.face_count(), .unit = "faces", .finished = true});
    progress->finish();
    double total = now_seconds() - t0;
    bool all_ok = false;
    nlohmann::json checks = guarantee_checks(r, args->vertices, all_ok);
    const RemeshResult& rm = r.remesh;
    const ClusteringReport& cr = rm.clustering;
    if (!args->report.empty()) {
      nlohmann::json j;
      j["input"] = {{"file", args->input},
                    {"vertices", r.input.vertices},
                    {"faces", r.input.faces},
                    {"components", r.input.components},
                    {"closed_manifold", r.input.closed},
                    {"euler_characteristic", r.input.euler_characteristic},
                    {"subdivision_levels", r.subdivision_levels},
                    {"remeshed_vertices", r.remeshed_vertices},
                    {"remeshed_faces", r.remeshed_faces}};
      if (r.input_build.topology_checked) j["cleaning"] = cleaning_json(r.input_build);
      j["options"] = {{"vertices", args->vertices},
                      {"threads", args->threads},
                      {"clustering_threads", clustering_thread_count(args->threads)},
                      {"deterministic", args->deterministic},
                      {"seed", args->seed},
                      {"metric", metric_name(rm.clustering.metric)},
                      {"algorithm", args->algorithm},
                      {"gradation", args->gradation},
                      {"curvature_rings", args->curvature_rings},
                      {"qem_threshold", args->qem_threshold},
                      {"subdivide", args->subdivide},
                      {"small_components", args->small_components},
                      {"boundary_strips", !args->no_strips},
                      {"vertex_placement", uses_quadrics(rm.clustering.metric) ? "QEM point"
                                           : args->no_project                   ? "centroid"
                                                                                : "centroid projected onto the input surface"}};
      j["seconds"] = {{"load", r.load_seconds},          {"store", r.store_seconds},
                      {"subdivide", r.subdivide_seconds}, {"curvature", rm.seconds.curvature},
                      {"items", rm.seconds.items},
                      {"sampling", rm.seconds.sampling},  {"clustering", rm.seconds.clustering},
                      {"clustering_cpu", rm.seconds.clustering_cpu},
                      {"repair", rm.seconds.repair},      {"dual", rm.seconds.dual},         {"optimize", rm.seconds.optimize},
                      {"placement", rm.seconds.placement}, {"checks", rm.seconds.checks},
                      {"attributes", rm.seconds.attributes},
                      {"summary", r.summary_seconds},
                      {"cleaning", r.input_build.cleaning.seconds},
                      {"write", write_seconds},           {"total", total}};
      j["clustering"] = {{"clusters", rm.clusters},
                         {"unconstrained_loops", cr.unconstrained_loops},
                         {"constrained_loops", cr.constrained_loops},
                         {"moves_per_loop", cr.moves_per_loop},
                         {"energy_per_loop", cr.energy_per_loop},
                         {"seconds_per_loop", cr.seconds_per_loop},
                         {"cleaned_vertices", cr.cleaned_vertices},
                         {"disconnected_clusters_cleaned", cr.disconnected_clusters},
                         {"final_energy", rm.final_energy},
                         {"clustering_energy", cr.final_energy},
                         {"repair_rounds", rm.repair_rounds_used},
                         {"repair_count_rounds", rm.repair_count_rounds},
                         {"repaired_clusters", rm.repaired_clusters},
                         {"repair_splits", rm.repair_splits},
                         {"repair_merges", rm.repair_merges},
                         {"repair_islands_dissolved", rm.repair_islands},
                         {"repair_relaxed", rm.repair_relaxed},
                         {"qem_sites_reverted", rm.sites_reverted},
                         {"flat_faces_removed", rm.flat_faces_removed},
                         {"flat_faces_flipped_or_nudged", rm.flat_face_flips},
                         {"defect_faces_removed", rm.defect_faces_removed},
                         {"defect_vertices_removed", rm.defect_vertices_removed}};
      j["quality_pass"] = {{"enabled", !args->no_optimize}, {"flips", rm.quality_flips}, {"moves", rm.quality_moves},
                           {"strip_moves", rm.strip_moves}};
      j["strips"] = {{"faces", rm.strip_faces}, {"q_min", rm.strip_q_min}, {"q_avg", rm.strip_q_avg},
                     {"other_q_avg", rm.other_q_avg}};
      j["components"] = {{"count", rm.budget.clusters_per_component.size()},
                         {"small_kept", rm.budget.small_components_kept},
                         {"dropped", rm.budget.components_dropped}};
      j["output"] = {{"file", args->output},
                     {"vertices", r.output_topology.vertices},
                     {"faces", r.output_topology.faces},
                     {"boundary_edges", r.output_topology.boundary_edges},
                     {"boundary_loops", r.output_topology.boundary_loops},
                     {"holes_closed", rm.holes_closed},
                     {"duplicate_faces_removed", rm.duplicate_faces_removed},
                     {"components", r.output_topology.components}};
      j["attributes"] = attributes_json(r, args->output);
      j["quality"] = quality_json(r.output_quality);
      j["checks"] = checks;
      j["peak_rss_bytes"] = peak_rss_bytes();
      const MemoryPeak peak = measure_peak_memory();
      const IoCounters io1 = read_io_counters();
      j["memory"] = {{"limit_bytes", r.memory_limit},
                     {"peak_bytes", peak.bytes},
                     {"peak_source", peak.source == PeakSource::Cgroup ? "cgroup" : "rss"},
                     {"work_ram_budget_bytes", r.work_ram_bytes == ~uint64_t(0) ? 0 : r.work_ram_bytes},
                     {"work_file_peak_bytes", r.work_file_peak_bytes},
                     {"temporary_store_bytes", r.temporary_store_bytes},
                     {"work_directory", r.work_directory},
                     {"store_in_ram", r.store_in_ram}};
      j["io"] = {{"read_bytes", io1.read_bytes - io0.read_bytes},
                 {"write_bytes", io1.write_bytes - io0.write_bytes},
                 {"stages", stage_io->json()}};
      {  // Always there, so that scripts read one shape: a store in RAM has no scheduler, no stages.
        nlohmann::json stages = nlohmann::json::object();
        for (const StageVisits& s : r.schedule.stages)
          stages[s.stage] = {{"visits", s.visits}, {"vertices", s.vertices}, {"chunks_fetched", s.chunks_fetched}};
        j["chunk_visits"] = {{"scheduled", !r.schedule.stages.empty()},
                             {"chunks", r.schedule.chunks},
                             {"resident_budget_bytes", r.schedule.resident_budget_bytes == ~uint64_t(0) ? 0 : r.schedule.resident_budget_bytes},
                             {"chunks_released", r.schedule.chunks_released},
                             {"stages", stages}};
      }
      if (!r.kept_store.empty()) j["kept_store"] = r.kept_store;
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
                   (unsigned long long)(r.output_topology.vertices - rm.boundary_vertices_added),
                   (unsigned long long)rm.boundary_vertices_added, (unsigned long long)r.output_topology.faces,
                   r.output_quality.q_avg, r.output_quality.percent_angles_below_30);
      std::fprintf(stderr, "  loops  %u + %u, repair rounds %u; time %.2f s (load %.2f, clustering %.2f); peak %.0f MB\n",
                   cr.unconstrained_loops, cr.constrained_loops, rm.repair_rounds_used, total, r.load_seconds,
                   rm.seconds.clustering, double(peak_rss_bytes()) / 1e6);
      std::fprintf(stderr, "  checks %s\n", all_ok ? "all passed" : "FAILED (below)");
    }
    if (!all_ok) throw CheckFailed(args->output + ": " + failed_checks(checks));
  });
}

}  // namespace streamcvd::cli
