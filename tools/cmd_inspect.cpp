// `info`, `quality`, `convert`, `ingest`, `generate`: the commands that look at or move a mesh.
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/core/measure/store_stats.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/store/store.h"
#include "streamcvd/streaming/schedule/memory_budget.h"
#include "tools/commands.h"
#include "tools/job_options.h"
#include "streamcvd/streaming/run_reports.h"
#include "tools/measure.h"

namespace streamcvd::cli {
namespace {

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

void print_cleaning(std::FILE* out, const StoreBuildReport& b, const char* indent) {
  const TopologyCleaning& c = b.cleaning;
  const TopologyStats& m = c.cleaned;
  auto u = [](uint64_t x) { return (unsigned long long)x; };
  if (!c.rebuilt) {
    if (c.misoriented_edges_left > 0)  // lone edges inside a surface: no flip or cut mends them
      std::fprintf(out, "%scleaning            none possible: %llu misoriented edges left (not orientable there)\n",
                   indent, u(c.misoriented_edges_left));
    else
      std::fprintf(out, "%scleaning            none needed\n", indent);
    return;
  }
  std::fprintf(out, "%scleaning            %llu duplicate (%llu in double layers) + %llu degenerate faces dropped, %llu "
               "non-manifold edges cut (%llu faces left unpaired), %llu vertices split into %llu copies, %llu unpaired "
               "faces dropped, %llu faces flipped, %llu misoriented edges cut open (%llu left) (%u rounds)\n",
               indent, u(c.duplicate_faces_dropped), u(c.double_layer_faces_dropped), u(c.degenerate_faces_dropped),
               u(c.nonmanifold_edges_cut), u(c.unpaired_edge_faces), u(c.vertices_split), u(c.vertex_copies),
               u(c.unpaired_faces_dropped), u(c.faces_flipped), u(c.misoriented_edges_cut), u(c.misoriented_edges_left),
               c.rounds);
  std::fprintf(out, "%scleaned             %llu vertices, %llu faces, %llu boundary loops, %llu components (%lld sheets "
               "made), non-manifold e/v %llu / %llu\n",
               indent, u(m.vertices), u(m.faces), u(m.boundary_loops), u(m.components),
               (long long)c.sheets_made(b.input_topology), u(m.nonmanifold_edges), u(m.nonmanifold_vertices));
}

// A command that reads one mesh file or store and prints figures of it: the input, --json and
// the job options (memory, work folder, threads: limited while `run` runs).
struct FiguresArgs {
  std::string path;
  bool json = false;
  JobOptions job;
};

void add_figures_command(CLI::App& app, const char* name, const char* help,
                         std::function<void(const FiguresArgs&)> run) {
  auto* cmd = app.add_subcommand(name, help);
  auto args = std::make_shared<FiguresArgs>();
  cmd->add_option("input", args->path, "Mesh file (PLY/OBJ/OFF/STL, optionally .zst) or store directory")->required();
  cmd->add_flag("--json", args->json, "Print JSON instead of text");
  add_job_options(cmd, args->job);
  cmd->callback([args, run] {
    auto threads = thread_limit(args->job);
    run(*args);
  });
}

void add_info_command(CLI::App& app) {
  add_figures_command(app, "info", "Counts, bounding box and topology of a mesh file or store", [](const FiguresArgs& a) {
    StoreBuildOptions options;
    options.memory_limit = memory_limit(a.job);
    options.work_directory = a.job.work_dir;
    ProgressLine progress("info", a.job);
    const StoreBuildReport build = inspect_mesh(a.path, options, [&](const StageProgress& p) { progress.update(p); });
    progress.finish();
    if (a.json) {
      print_json(info_json(a.path, build));
    } else {
      print_topology(a.path, build.input_topology);
      if (build.topology_checked) print_cleaning(stdout, build, "  ");
    }
  });
}

void add_quality_command(CLI::App& app) {
  add_figures_command(app, "quality", "Triangle quality figures (Q, angles, valence, edge lengths)", [](const FiguresArgs& a) {
    LoadedMesh mesh = load_mesh_or_store(a.path, memory_limit(a.job));
    QualityStats q = compute_quality(mesh.view());
    if (a.json) {
      nlohmann::json j = quality_json(q);
      j["file"] = a.path;
      print_json(j);
    } else {
      std::printf("%s\n", a.path.c_str());
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
    const nlohmann::json j = ingest_report(*in, *dir, store, report, total);
    const MemoryPeak peak{j["peak_bytes"].get<uint64_t>(), j["peak_source"] == "cgroup" ? PeakSource::Cgroup : PeakSource::Rss};
    const uint64_t in_bytes = report.input_bytes;
    const StoreHeader& h = store.header();
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
