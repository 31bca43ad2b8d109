#include "streamcvd/streaming/run_reports.h"

#include <algorithm>

#include "streamcvd/core/clustering/cluster_energy.h"
#include "streamcvd/core/clustering/parallel_clustering.h"
#include "streamcvd/core/measure/store_stats.h"
#include "streamcvd/streaming/io/mesh_io.h"

namespace streamcvd {

namespace {

nlohmann::json one_side_json(const OneSidedDistance& s, const DistanceReport& d) {
  return {{"max", s.max},
          {"mean", s.mean},
          {"rms", s.rms},
          {"samples", s.samples},
          {"max_relative", d.relative(s.max)},
          {"mean_relative", d.relative(s.mean)},
          {"rms_relative", d.relative(s.rms)}};
}

// The report's attributes: those carried (input names and types) and those the output's format
// holds.
nlohmann::json attributes_json(const PipelineResult& r, const std::string& output) {
  nlohmann::json carried = nlohmann::json::array(), written = nlohmann::json::array();
  for (const VertexAttribute& a : r.attributes) carried.push_back({{"name", a.name}, {"type", scalar_type_name(a.type)}});
  if (!output.empty())  // a job whose output stays in memory (the Python binding's remesh()) writes none
    for (size_t k : attributes_written(format_from_path(output), r.attributes)) written.push_back(r.attributes[k].name);
  return {{"carried", carried}, {"written", written}, {"normals", "not carried (not written)"}};
}

}  // namespace

nlohmann::json topology_json(const TopologyStats& s) {
  return {{"vertices", s.vertices},
          {"faces", s.faces},
          {"edges", s.edges},
          {"bbox_min", {s.bbox_min[0], s.bbox_min[1], s.bbox_min[2]}},
          {"bbox_max", {s.bbox_max[0], s.bbox_max[1], s.bbox_max[2]}},
          {"boundary_edges", s.boundary_edges},
          {"boundary_loops", s.boundary_loops},
          {"nonmanifold_edges", s.nonmanifold_edges},
          {"nonmanifold_vertices", s.nonmanifold_vertices},
          {"duplicate_faces", s.duplicate_faces},
          {"degenerate_faces", s.degenerate_faces},
          {"isolated_vertices", s.isolated_vertices},
          {"components", s.components},
          {"euler_characteristic", s.euler_characteristic},
          {"closed_manifold", s.closed_manifold},
          {"consistently_oriented", s.consistently_oriented},
          {"genus", s.genus}};
}

nlohmann::json quality_json(const QualityStats& q) {
  return {{"triangles", q.triangles},
          {"q_min", q.q_min},
          {"q_avg", q.q_avg},
          {"min_angle_min_deg", q.min_angle_min},
          {"min_angle_avg_deg", q.min_angle_avg},
          {"max_angle_max_deg", q.max_angle_max},
          {"percent_angles_below_30", q.percent_angles_below_30},
          {"percent_triangles_below_30", q.percent_triangles_below_30},
          {"percent_valence6", q.percent_valence6},
          {"edge_length_mean", q.edge_length_mean},
          {"edge_length_cv", q.edge_length_cv},
          {"boundary_triangles", q.boundary_triangles},
          {"q_min_boundary", q.q_min_boundary},
          {"q_avg_boundary", q.q_avg_boundary},
          {"q_avg_off_boundary", q.q_avg_off_boundary},
          {"q_histogram", q.q_histogram},
          {"min_angle_histogram", q.min_angle_histogram}};
}

nlohmann::json cleaning_json(const StoreBuildReport& b) {
  if (!b.input_topology_known) {  // the build's screen found nothing to clean
    const StoreBuildReport::TopologyScreen& s = b.screen;
    return {{"rebuilt", false},
            {"input_nonmanifold_vertices", s.nonmanifold_vertices},
            {"input_duplicate_faces", s.isolated_twin_faces},  // all zero here: no duplicate at all
            {"input_repeated_index_faces", s.repeated_index_faces}};
  }
  const TopologyCleaning& c = b.cleaning;
  const TopologyStats& in = b.input_topology;
  const TopologyStats& out = c.cleaned;
  return {{"rebuilt", c.rebuilt},
          {"input_nonmanifold_edges", in.nonmanifold_edges},
          {"input_nonmanifold_vertices", in.nonmanifold_vertices},
          {"input_duplicate_faces", in.duplicate_faces},
          {"input_degenerate_faces", in.degenerate_faces},
          {"input_boundary_loops", in.boundary_loops},
          {"input_components", in.components},
          {"duplicate_faces_dropped", c.duplicate_faces_dropped},
          {"double_layer_faces_dropped", c.double_layer_faces_dropped},
          {"degenerate_faces_dropped", c.degenerate_faces_dropped},
          {"nonmanifold_edges_cut", c.nonmanifold_edges_cut},
          {"unpaired_edge_faces", c.unpaired_edge_faces},
          {"vertices_split", c.vertices_split},
          {"vertex_copies", c.vertex_copies},
          {"unpaired_faces_dropped", c.unpaired_faces_dropped},
          {"faces_flipped", c.faces_flipped},
          {"misoriented_edges_cut", c.misoriented_edges_cut},
          {"misoriented_edges_left", c.misoriented_edges_left},
          {"rounds", c.rounds},
          {"sheets_made", c.sheets_made(in)},
          {"cleaned_vertices", out.vertices},
          {"cleaned_faces", out.faces},
          {"cleaned_boundary_loops", out.boundary_loops},
          {"cleaned_components", out.components},
          {"cleaned_nonmanifold_edges", out.nonmanifold_edges},
          {"cleaned_nonmanifold_vertices", out.nonmanifold_vertices},
          {"cleaned_closed_manifold", out.closed_manifold}};
}

nlohmann::json distance_json(const DistanceReport& d) {
  return {{"a_to_b", one_side_json(d.a_to_b, d)},
          {"b_to_a", one_side_json(d.b_to_a, d)},
          {"hausdorff", d.hausdorff},
          {"hausdorff_relative", d.relative_hausdorff()},
          {"two_sided_rms", d.two_sided_rms()},
          {"two_sided_rms_relative", d.relative(d.two_sided_rms())},
          {"diagonal", d.diagonal}};
}

namespace {

// A store built from an input as read: the build's figures of the input when its screen found
// something to clean, else the store's, which is then the input as read.
void complete_inspection(const MeshStore& store, StoreBuildReport& build) {
  if (!build.input_topology_known) {
    build.input_topology = build.cleaning.cleaned = compute_topology_stats(store.view());
    build.input_topology_known = true;
  }
}

}  // namespace

StoreBuildReport inspect_mesh(const std::function<void(MeshSink&)>& produce, const StoreBuildOptions& options,
                              const ProgressCallback& progress) {
  StoreBuildReport build;
  MeshStore store = MeshStore::build_from_stream(produce, options, &build, progress);
  complete_inspection(store, build);
  return build;
}

StoreBuildReport inspect_mesh(const std::string& path, const StoreBuildOptions& options, const ProgressCallback& progress) {
  StoreBuildReport build;
  // Read chunk by chunk through the store's adjacency, in bounded memory: a mesh file is first
  // streamed into a temporary store (in RAM if it fits the limit, else in anonymous work files).
  if (!is_store_directory(path)) {
    MeshStore store = MeshStore::build_from_file(path, options, {}, &build, progress);
    complete_inspection(store, build);
    return build;
  }
  MeshStore store = MeshStore::open(path);
  store.validate_all();
  // A cleaned store keeps the input's figures as read; any other is its input as read.
  build.cleaning.cleaned = compute_topology_stats(store.view());
  if (!store.cleaning_report(build)) {
    build.topology_checked = build.input_topology_known = true;
    build.input_topology = build.cleaning.cleaned;
  }
  return build;
}

nlohmann::json info_json(const std::string& name, const StoreBuildReport& build) {
  nlohmann::json j = topology_json(build.input_topology);
  j["file"] = name;
  if (build.topology_checked) j["cleaning"] = cleaning_json(build);
  return j;
}

nlohmann::json ingest_report(const std::string& input, const std::string& directory, const MeshStore& store,
                             const StoreBuildReport& report, double total_seconds) {
  const MemoryPeak peak = measure_peak_memory();
  const uint64_t in_bytes = report.input_bytes;
  const StoreHeader& h = store.header();
  nlohmann::json j = {{"input", input},
                      {"store", directory},
                      {"input_bytes", in_bytes},
                      {"vertices", h.vertex_count},
                      {"faces", h.face_count},
                      {"chunks", h.chunk_count},
                      {"store_bytes", store.size_bytes()},
                      {"read_seconds", report.read_seconds},
                      {"order_seconds", report.order_seconds},
                      {"faces_seconds", report.faces_seconds},
                      {"adjacency_seconds", report.adjacency_seconds},
                      {"total_seconds", total_seconds},
                      {"ingest_mb_per_s", double(in_bytes) / 1e6 / std::max(1e-9, total_seconds)},
                      {"memory_limit_bytes", report.memory_limit},
                      {"peak_bytes", peak.bytes},
                      {"peak_source", peak.source == PeakSource::Cgroup ? "cgroup" : "rss"},
                      {"spilled_bytes", report.spilled_bytes},
                      {"key_buckets", report.key_buckets},
                      {"vertex_ranges", report.vertex_ranges},
                      {"polygons_split", report.polygons_split}};
  if (report.topology_checked) j["cleaning"] = cleaning_json(report);
  return j;
}

void StageIoLog::see(const StageProgress& p) {
  if (!p.finished) return;
  const IoCounters now = read_io_counters();
  auto it = std::find_if(stages_.begin(), stages_.end(), [&](const auto& s) { return s.first == p.stage; });
  if (it == stages_.end()) it = stages_.insert(stages_.end(), {p.stage, IoCounters{}});
  it->second.read_bytes += now.read_bytes - last_.read_bytes;
  it->second.write_bytes += now.write_bytes - last_.write_bytes;
  last_ = now;
}

void StageIoLog::start() { last_ = read_io_counters(); }

nlohmann::json StageIoLog::json() const {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& [stage, io] : stages_) j[stage] = {{"read_bytes", io.read_bytes}, {"write_bytes", io.write_bytes}};
  return j;
}

nlohmann::json guarantee_checks(const PipelineResult& r, uint32_t requested, bool& all_ok) {
  const TopologyStats& out = r.output_topology;
  const RemeshResult& rm = r.remesh;
  uint64_t cluster_vertices = out.vertices - rm.dual.boundary_vertices_added;
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
      {"clusters_connected", rm.checks.clusters_connected},
      {"defect_vertices_after_repair", rm.placement.defect_vertices},
      {"requested_vertices", requested},
      {"cluster_vertices", cluster_vertices},
      {"boundary_strip_vertices", rm.dual.boundary_vertices_added},
      {"exact_vertex_count", out.vertices == requested},
      {"input_euler_characteristic", rm.checks.input_euler_characteristic},
      {"output_euler_characteristic", out.euler_characteristic},
  };
  if (!rm.budget.note.empty()) j["vertex_count_note"] = rm.budget.note;
  bool manifold_ok = out.nonmanifold_edges == 0 && out.nonmanifold_vertices == 0 && out.duplicate_faces == 0 &&
                     out.degenerate_faces == 0 && out.isolated_vertices == 0;
  bool closed_ok = !closed_in || (out.closed_manifold && out.consistently_oriented);
  bool genus_ok = !closed_in || out.euler_characteristic == rm.checks.input_euler_characteristic;
  if (closed_in && single_component) j["genus_preserved"] = genus_ok;
  else if (closed_in) j["euler_characteristic_preserved"] = genus_ok;
  j["manifold_ok"] = manifold_ok;
  j["closed_ok"] = closed_ok;
  j["topology_changed"] = rm.checks.topology_changed;
  j["faces_deleted_around_defects"] = rm.placement.defects_removed.faces_removed;
  j["vertices_deleted_around_defects"] = rm.placement.defects_removed.vertices_removed;
  const bool components_ok = rm.checks.components.ok();
  j["components_ok"] = components_ok;
  j["input_components_with_clusters"] = rm.checks.components.input_components;
  j["output_components"] = rm.checks.components.output_components;
  if (!components_ok) j["component_problems"] = rm.checks.components.problems;
  // Against the input as cleaned (its sheets and their boundaries, streaming/store/store_clean.h): a
  // hole below the output resolution may close, none may open; no piece may come apart.
  const bool holes_ok = out.boundary_loops <= rm.checks.components.input_boundary_loops;
  const bool pieces_ok = out.components <= rm.checks.components.input_components;
  j["cleaned_input_boundary_loops"] = rm.checks.components.input_boundary_loops;
  j["output_boundary_loops"] = out.boundary_loops;
  j["holes_ok"] = holes_ok;
  j["pieces_ok"] = pieces_ok;
  all_ok = manifold_ok && closed_ok && genus_ok && !rm.checks.topology_changed && rm.placement.defect_vertices == 0 && components_ok &&
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
  if (checks.value("topology_changed", false)) {
    const uint64_t faces = checks.value("faces_deleted_around_defects", uint64_t(0));
    add(faces > 0 ? "topology changed (" + std::to_string(faces) + " faces and " +
                        std::to_string(checks.value("vertices_deleted_around_defects", uint64_t(0))) +
                        " vertices deleted around defects the repair did not mend)"
                  : "topology changed (handles lost or gained)");
  }
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

std::string remesh_output_comment(const PipelineOptions& options) {
  return "streamcvd remesh -n " + std::to_string(options.remesh.vertices) + " --seed " + std::to_string(options.remesh.seed);
}

nlohmann::json remesh_report(const PipelineResult& r, const PipelineOptions& options, const RemeshJobRecord& job) {
  const RemeshOptions& o = options.remesh;
  const RemeshResult& rm = r.remesh;
  const ClusteringReport& cr = rm.clustering;
  const DefectRepairResult& repair = rm.repair;
  const PlacementReport& placement = rm.placement;
  const FlatFaceRepair& flat = rm.checks.flat_faces;
  bool all_ok = false;
  const nlohmann::json checks = guarantee_checks(r, o.vertices, all_ok);
  const std::string subdivide = options.subdivide < 0    ? "auto"
                            : options.subdivide == 0 ? "none"
                                                     : std::to_string(options.subdivide);
  nlohmann::json j;
  j["input"] = {{"file", job.input},
                {"vertices", r.input.vertices},
                {"faces", r.input.faces},
                {"components", r.input.components},
                {"closed_manifold", r.input.closed},
                {"euler_characteristic", r.input.euler_characteristic},
                {"subdivision_levels", r.subdivision_levels},
                {"remeshed_vertices", r.remeshed_vertices},
                {"remeshed_faces", r.remeshed_faces}};
  if (r.input_build.topology_checked) j["cleaning"] = cleaning_json(r.input_build);
  j["options"] = {{"vertices", o.vertices},
                  {"threads", o.clustering.loops.threads},
                  {"clustering_threads", clustering_thread_count(o.clustering.loops.threads)},
                  {"deterministic", o.clustering.loops.deterministic},
                  {"seed", o.seed},
                  {"metric", metric_name(rm.clustering.metric)},
                  {"algorithm", algorithm_name(o.clustering.algorithm)},
                  {"gradation", o.gradation},
                  {"curvature_rings", o.curvature_rings},
                  {"qem_threshold", o.clustering.qem_threshold},
                  {"subdivide", subdivide},
                  {"small_components", small_components_name(o.small_components)},
                  {"boundary_strips", o.boundary_strips},
                  {"vertex_placement", uses_quadrics(rm.clustering.metric) ? "QEM point"
                                       : !o.project_to_surface                   ? "centroid"
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
                  {"write", job.write_seconds},       {"total", job.total_seconds}};
  j["clustering"] = {{"clusters", rm.clusters},
                     {"unconstrained_loops", cr.unconstrained_loops},
                     {"constrained_loops", cr.constrained_loops},
                     {"moves_per_loop", cr.moves_per_loop},
                     {"energy_per_loop", cr.energy_per_loop},
                     {"seconds_per_loop", cr.seconds_per_loop},
                     {"cleaned_vertices", cr.cleaned_vertices},
                     {"disconnected_clusters_cleaned", cr.disconnected_clusters},
                     {"final_energy", rm.dual.final_energy},
                     {"clustering_energy", cr.final_energy},
                     {"repair_rounds", repair.rounds},
                     {"repair_count_rounds", repair.count_rounds},
                     {"repair_defects_per_round", repair.defects_per_round},
                     {"repaired_clusters", repair.repaired_clusters},
                     {"repair_splits", repair.splits},
                     {"repair_merges", repair.merges},
                     {"repair_islands_dissolved", repair.islands},
                     {"repair_relaxed", repair.relaxed},
                     {"qem_sites_reverted", placement.sites_reverted},
                     {"flat_faces_removed", flat.faces_removed},
                     {"flat_faces_flipped_or_nudged", flat.flips + flat.nudges},
                     {"defect_faces_removed", placement.defects_removed.faces_removed},
                     {"defect_vertices_removed", placement.defects_removed.vertices_removed}};
  j["quality_pass"] = {{"enabled", o.optimize_quality}, {"flips", rm.quality.flips()},
                       {"moves", rm.quality.interior.moves}, {"strip_moves", rm.quality.strip_moves()}};
  const StripQuality& strips = rm.checks.strips;
  j["strips"] = {{"faces", strips.strip_faces}, {"q_min", strips.strip_q_min}, {"q_avg", strips.strip_q_avg},
                 {"other_q_avg", strips.other_q_avg}};
  j["components"] = {{"count", rm.budget.clusters_per_component.size()},
                     {"small_kept", rm.budget.small_components_kept},
                     {"dropped", rm.budget.components_dropped},
                     {"cut_sheets_dropped", rm.budget.sheets_dropped}};
  j["output"] = {{"file", job.output},
                 {"vertices", r.output_topology.vertices},
                 {"faces", r.output_topology.faces},
                 {"boundary_edges", r.output_topology.boundary_edges},
                 {"boundary_loops", r.output_topology.boundary_loops},
                 {"holes_closed", rm.dual.holes_closed},
                 {"duplicate_faces_removed", rm.dual.duplicate_faces_removed},
                 {"components", r.output_topology.components}};
  j["attributes"] = attributes_json(r, job.output);
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
  j["io"] = {{"read_bytes", io1.read_bytes - job.io_start.read_bytes},
             {"write_bytes", io1.write_bytes - job.io_start.write_bytes},
             {"stages", job.stage_io ? job.stage_io->json() : nlohmann::json::object()}};
  {  // Always there, so that scripts read one shape: a store in RAM has no scheduler, no stages.
    nlohmann::json stages = nlohmann::json::object();
    for (const StageVisits& s : r.schedule.stages)
      stages[s.stage] = {{"visits", s.visits},
                         {"vertices", s.vertices},
                         {"chunks_fetched", s.chunks_fetched},
                         {"chunks_refetched", s.chunks_refetched},
                         {"bytes_read_ahead", s.bytes_read_ahead}};
    j["chunk_visits"] = {{"scheduled", !r.schedule.stages.empty()},
                         {"chunks", r.schedule.chunks},
                         {"resident_budget_bytes", r.schedule.resident_budget_bytes == ~uint64_t(0) ? 0 : r.schedule.resident_budget_bytes},
                         {"chunks_released", r.schedule.chunks_released},
                         {"stages", stages}};
  }
  if (!r.kept_store.empty()) j["kept_store"] = r.kept_store;
  return j;
}

}  // namespace streamcvd
