// `info`, `quality`, `convert`, `ingest`, `generate`: the commands that look at or move a mesh.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>

#include "core/errors.h"
#include "core/mesh_stats.h"
#include "core/shapes.h"
#include "core/store_stats.h"
#include "streaming/mesh_io.h"
#include "streaming/store.h"
#include "streaming/memory_budget.h"
#include "tools/commands.h"
#include "tools/job_options.h"
#include "tools/measure.h"

namespace streamcvd::cli {
namespace {

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

void print_topology(const std::string& path, const TopologyStats& s) {
  std::printf("%s\n", path.c_str());
  std::printf("  vertices             %llu\n", (unsigned long long)s.vertices);
  std::printf("  faces                %llu\n", (unsigned long long)s.faces);
  std::printf("  edges                %llu\n", (unsigned long long)s.edges);
  std::printf("  bounding box         [%g %g %g] - [%g %g %g]\n", s.bbox_min[0], s.bbox_min[1], s.bbox_min[2],
              s.bbox_max[0], s.bbox_max[1], s.bbox_max[2]);
  std::printf("  boundary edges/loops %llu / %llu\n", (unsigned long long)s.boundary_edges,
              (unsigned long long)s.boundary_loops);
  std::printf("  non-manifold e/v     %llu / %llu\n", (unsigned long long)s.nonmanifold_edges,
              (unsigned long long)s.nonmanifold_vertices);
  std::printf("  duplicate faces      %llu\n", (unsigned long long)s.duplicate_faces);
  std::printf("  degenerate faces     %llu\n", (unsigned long long)s.degenerate_faces);
  std::printf("  isolated vertices    %llu\n", (unsigned long long)s.isolated_vertices);
  std::printf("  components           %llu\n", (unsigned long long)s.components);
  std::printf("  Euler characteristic %lld\n", (long long)s.euler_characteristic);
  std::printf("  closed manifold      %s%s\n", s.closed_manifold ? "yes" : "no",
              s.genus >= 0 ? (", genus " + std::to_string(s.genus)).c_str() : "");
  std::printf("  consistently oriented %s\n", s.consistently_oriented ? "yes" : "no");
}

}  // namespace

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

void print_quality(const QualityStats& q) {
  std::printf("  triangles            %llu\n", (unsigned long long)q.triangles);
  std::printf("  Qmin / Qav           %.4f / %.4f\n", q.q_min, q.q_avg);
  std::printf("  min angle min / avg  %.2f / %.2f deg\n", q.min_angle_min, q.min_angle_avg);
  std::printf("  max angle            %.2f deg\n", q.max_angle_max);
  std::printf("  angles < 30 deg      %.3f %%\n", q.percent_angles_below_30);
  std::printf("  triangles < 30 deg   %.3f %%\n", q.percent_triangles_below_30);
  std::printf("  valence-6 interior   %.2f %%\n", q.percent_valence6);
  std::printf("  edge length mean/CV  %g / %.4f\n", q.edge_length_mean, q.edge_length_cv);
  if (q.boundary_triangles > 0)
    std::printf("  boundary faces       %llu: Qmin / Qav %.4f / %.4f (other faces Qav %.4f)\n",
                (unsigned long long)q.boundary_triangles, q.q_min_boundary, q.q_avg_boundary, q.q_avg_off_boundary);
}

// What the store build's topology cleaning did (streaming/store_clean.h): the input's defects as
// read, what was dropped and cut, the figures of the cleaned mesh.
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
          {"degenerate_faces_dropped", c.degenerate_faces_dropped},
          {"nonmanifold_edges_cut", c.nonmanifold_edges_cut},
          {"unpaired_edge_faces", c.unpaired_edge_faces},
          {"vertices_split", c.vertices_split},
          {"vertex_copies", c.vertex_copies},
          {"unpaired_faces_dropped", c.unpaired_faces_dropped},
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

void print_cleaning(std::FILE* out, const StoreBuildReport& b, const char* indent) {
  const TopologyCleaning& c = b.cleaning;
  const TopologyStats& m = c.cleaned;
  auto u = [](uint64_t x) { return (unsigned long long)x; };
  if (!c.rebuilt) {
    std::fprintf(out, "%scleaning            none needed\n", indent);
    return;
  }
  std::fprintf(out, "%scleaning            %llu duplicate + %llu degenerate faces dropped, %llu non-manifold edges cut "
               "(%llu faces left unpaired), %llu vertices split into %llu copies, %llu unpaired faces dropped (%u rounds)\n",
               indent, u(c.duplicate_faces_dropped), u(c.degenerate_faces_dropped), u(c.nonmanifold_edges_cut),
               u(c.unpaired_edge_faces), u(c.vertices_split), u(c.vertex_copies), u(c.unpaired_faces_dropped), c.rounds);
  std::fprintf(out, "%scleaned             %llu vertices, %llu faces, %llu boundary loops, %llu components (%lld sheets "
               "made), non-manifold e/v %llu / %llu\n",
               indent, u(m.vertices), u(m.faces), u(m.boundary_loops), u(m.components),
               (long long)c.sheets_made(b.input_topology), u(m.nonmanifold_edges), u(m.nonmanifold_vertices));
}

void add_info_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("info", "Counts, bounding box and topology of a mesh file or store");
  auto path = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  cmd->add_option("input", *path, "Mesh file (PLY/OBJ/OFF/STL, optionally .zst) or store directory")->required();
  cmd->add_flag("--json", *json, "Print JSON instead of text");
  auto job = std::make_shared<JobOptions>();
  add_job_options(cmd, *job);
  cmd->callback([=] {
    // Read chunk by chunk through the store's adjacency, in bounded memory: a mesh file is first
    // streamed into a temporary store (in RAM if it fits --memory, else in anonymous work files).
    auto threads = thread_limit(*job);
    StoreBuildOptions options;
    options.memory_limit = memory_limit(*job);
    options.work_directory = job->work_dir;
    MeshStore store;
    StoreBuildReport build;
    if (is_store_directory(*path)) {
      store = MeshStore::open(*path);
      store.validate_all();
      // A cleaned store keeps the input's figures as read; any other is its input as read.
      build.cleaning.cleaned = compute_topology_stats(store.view());
      if (!store.cleaning_report(build)) {
        build.topology_checked = build.input_topology_known = true;
        build.input_topology = build.cleaning.cleaned;
      }
    } else {
      // The figures of the input as read come from the build's check (the store may be the
      // cleaned one); the cleaning's are added.
      ProgressLine progress("info", *job);
      store = MeshStore::build_from_file(*path, options, {}, &build, [&](const BuildProgress& p) { progress.update(p); });
      if (!build.input_topology_known) {  // the build found nothing to clean: the store is the input as read
        build.input_topology = build.cleaning.cleaned = compute_topology_stats(store.view());
        build.input_topology_known = true;
      }
    }
    const TopologyStats& stats = build.input_topology;
    if (*json) {
      nlohmann::json j = topology_json(stats);
      j["file"] = *path;
      if (build.topology_checked) j["cleaning"] = cleaning_json(build);
      print_json(j);
    } else {
      print_topology(*path, stats);
      if (build.topology_checked) print_cleaning(stdout, build, "  ");
    }
  });
}

void add_quality_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("quality", "Triangle quality figures (Q, angles, valence, edge lengths)");
  auto path = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  cmd->add_option("input", *path, "Mesh file or store directory")->required();
  cmd->add_flag("--json", *json, "Print JSON instead of text");
  auto job = std::make_shared<JobOptions>();
  add_job_options(cmd, *job);
  cmd->callback([=] {
    auto threads = thread_limit(*job);
    LoadedMesh mesh = load_mesh_or_store(*path, memory_limit(*job));
    QualityStats q = compute_quality(mesh.view());
    if (*json) {
      nlohmann::json j = quality_json(q);
      j["file"] = *path;
      print_json(j);
    } else {
      std::printf("%s\n", path->c_str());
      print_quality(q);
    }
  });
}

void add_convert_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("convert", "Convert between mesh formats (by extension; .zst compresses)");
  auto in = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto ascii = std::make_shared<bool>(false);
  cmd->add_option("input", *in, "Mesh file or store directory")->required();
  cmd->add_option("output", *out, "Output mesh file (.ply .obj .off .stl, optionally + .zst)")->required();
  cmd->add_flag("--ascii", *ascii, "Write ascii PLY instead of binary little-endian");
  auto job = std::make_shared<JobOptions>();
  add_job_options(cmd, *job);
  cmd->callback([=] {
    auto threads = thread_limit(*job);
    double t0 = now_seconds();
    LoadedMesh mesh = load_mesh_or_store(*in, memory_limit(*job));
    WriteOptions options;
    options.ascii = *ascii;
    write_mesh(*out, mesh.view(), options);
    std::fprintf(stderr, "convert: %s -> %s: %u vertices, %llu faces in %.2f s\n", in->c_str(), out->c_str(),
                 mesh.view().vertex_count(), (unsigned long long)mesh.view().face_count(), now_seconds() - t0);
  });
}

void add_ingest_command(CLI::App& app) {
  auto* cmd = app.add_subcommand(
      "ingest", "Build the compact store (memory-mappable arrays, Hilbert order, chunks) of a mesh, in bounded memory");
  auto in = std::make_shared<std::string>();
  auto dir = std::make_shared<std::string>();
  auto faces_per_chunk = std::make_shared<uint64_t>(uint64_t(1) << 20);
  auto json = std::make_shared<bool>(false);
  auto job = std::make_shared<JobOptions>();
  cmd->add_option("input", *in, "Mesh file (PLY/OBJ/OFF/STL, optionally .zst), or - for standard input")->required();
  cmd->add_option("store", *dir, "Store directory to create")->required();
  cmd->add_option("--faces-per-chunk", *faces_per_chunk, "Target owned faces per chunk")->capture_default_str();
  cmd->add_flag("--json", *json, "Print a JSON record of the ingest");
  add_job_options(cmd, *job);
  cmd->callback([=] {
    const double t0 = now_seconds();
    auto threads = thread_limit(*job);
    StoreBuildOptions options;
    options.faces_per_chunk = *faces_per_chunk;
    options.memory_limit = memory_limit(*job);
    options.work_directory = job->work_dir;
    ProgressLine progress("ingest", *job);
    StoreBuildReport report;
    MeshStore store = MeshStore::ingest(*in, *dir, options, {}, &report,
                                        [&](const BuildProgress& p) { progress.update(p); });
    progress.finish();
    const double total = now_seconds() - t0;
    const MemoryPeak peak = measure_peak_memory();
    const uint64_t in_bytes = report.input_bytes;
    const StoreHeader& h = store.header();
    nlohmann::json j = {{"input", *in},
                        {"store", *dir},
                        {"input_bytes", in_bytes},
                        {"vertices", h.vertex_count},
                        {"faces", h.face_count},
                        {"chunks", h.chunk_count},
                        {"store_bytes", store.size_bytes()},
                        {"read_seconds", report.read_seconds},
                        {"order_seconds", report.order_seconds},
                        {"faces_seconds", report.faces_seconds},
                        {"adjacency_seconds", report.adjacency_seconds},
                        {"total_seconds", total},
                        {"ingest_mb_per_s", double(in_bytes) / 1e6 / std::max(1e-9, total)},
                        {"memory_limit_bytes", report.memory_limit},
                        {"peak_bytes", peak.bytes},
                        {"peak_source", peak.source == PeakSource::Cgroup ? "cgroup" : "rss"},
                        {"spilled_bytes", report.spilled_bytes},
                        {"key_buckets", report.key_buckets},
                        {"vertex_ranges", report.vertex_ranges},
                        {"polygons_split", report.polygons_split}};
    if (report.topology_checked) j["cleaning"] = cleaning_json(report);
    if (*json) {
      print_json(j);
      return;
    }
    std::fprintf(stderr,
                 "ingest: %s -> %s: %llu vertices, %llu faces, %u chunks, store %s in %.2f s (%s/s of input); "
                 "memory limit %s, peak %s (%s), spilled %s\n",
                 in->c_str(), dir->c_str(), (unsigned long long)h.vertex_count, (unsigned long long)h.face_count,
                 h.chunk_count, format_bytes(double(store.size_bytes())).c_str(), total,
                 format_bytes(double(in_bytes) / std::max(1e-9, total)).c_str(),
                 format_memory_size(report.memory_limit).c_str(), format_memory_size(peak.bytes).c_str(),
                 peak.source == PeakSource::Cgroup ? "cgroup" : "RSS", format_bytes(double(report.spilled_bytes)).c_str());
    if (report.cleaning.rebuilt) print_cleaning(stderr, report, "  ");
  });
}

void add_generate_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("generate", "Write a procedural test surface (sphere, torus, grid)");
  auto shape = std::make_shared<std::string>();
  auto out = std::make_shared<std::string>();
  auto level = std::make_shared<int>(5);
  auto rings = std::make_shared<int>(200);
  auto segments = std::make_shared<int>(100);
  auto ascii = std::make_shared<bool>(false);
  cmd->add_option("shape", *shape, "sphere | torus | grid")->required()->check(CLI::IsMember({"sphere", "torus", "grid"}));
  cmd->add_option("-o,--output", *out, "Output mesh file")->required();
  cmd->add_option("--level", *level, "Sphere subdivision level (20*4^level faces)")->capture_default_str()->check(CLI::Range(0, 11));
  cmd->add_option("--rings", *rings, "Torus/grid vertex rows")->capture_default_str()->check(CLI::Range(3, 200000));
  cmd->add_option("--segments", *segments, "Torus/grid vertex columns")->capture_default_str()->check(CLI::Range(3, 200000));
  cmd->add_flag("--ascii", *ascii, "Write ascii PLY");
  cmd->callback([=] {
    MeshBuffers mesh;
    if (*shape == "sphere") mesh = make_icosphere(*level);
    else if (*shape == "torus") mesh = make_torus(*rings, *segments);
    else mesh = make_grid(*rings, *segments);
    WriteOptions options;
    options.ascii = *ascii;
    write_mesh(*out, mesh.view(), options);
    std::fprintf(stderr, "generate: %s: %u vertices, %llu faces\n", out->c_str(), mesh.vertex_count(),
                 (unsigned long long)mesh.face_count());
  });
}

}  // namespace streamcvd::cli
