// `info`, `quality`, `convert`, `ingest`, `generate`: the commands that look at or move a mesh.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>

#include "core/errors.h"
#include "core/mesh_stats.h"
#include "core/shapes.h"
#include "streaming/mesh_io.h"
#include "streaming/store.h"
#include "tools/commands.h"

namespace streamcvd::cli {
namespace {

/// A mesh file read into RAM, or a store directory mapped: either way a soup view.
struct LoadedSoup {
  std::optional<MeshBuffers> buffers;
  std::optional<MeshStore> store;
  TriangleSoupView view() const { return buffers ? buffers->view() : store->view().soup(); }
};

LoadedSoup load_soup(const std::string& path) {
  LoadedSoup loaded;
  if (is_store_directory(path))
    loaded.store = MeshStore::open(path);
  else
    loaded.buffers = read_mesh(path);
  return loaded;
}

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
}

void add_info_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("info", "Counts, bounding box and topology of a mesh file or store");
  auto path = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  cmd->add_option("input", *path, "Mesh file (PLY/OBJ/OFF/STL, optionally .zst) or store directory")->required();
  cmd->add_flag("--json", *json, "Print JSON instead of text");
  cmd->callback([=] {
    LoadedSoup mesh = load_soup(*path);
    TopologyStats stats = compute_topology_stats(mesh.view());
    if (*json) {
      nlohmann::json j = topology_json(stats);
      j["file"] = *path;
      print_json(j);
    } else {
      print_topology(*path, stats);
    }
  });
}

void add_quality_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("quality", "Triangle quality figures (Q, angles, valence, edge lengths)");
  auto path = std::make_shared<std::string>();
  auto json = std::make_shared<bool>(false);
  cmd->add_option("input", *path, "Mesh file or store directory")->required();
  cmd->add_flag("--json", *json, "Print JSON instead of text");
  cmd->callback([=] {
    LoadedSoup mesh = load_soup(*path);
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
  cmd->callback([=] {
    double t0 = now_seconds();
    LoadedSoup mesh = load_soup(*in);
    WriteOptions options;
    options.ascii = *ascii;
    write_mesh(*out, mesh.view(), options);
    std::fprintf(stderr, "convert: %s -> %s: %u vertices, %llu faces in %.2f s\n", in->c_str(), out->c_str(),
                 mesh.view().vertex_count(), (unsigned long long)mesh.view().face_count(), now_seconds() - t0);
  });
}

void add_ingest_command(CLI::App& app) {
  auto* cmd = app.add_subcommand("ingest", "Build the compact store (memory-mappable arrays) of a mesh");
  auto in = std::make_shared<std::string>();
  auto dir = std::make_shared<std::string>();
  auto faces_per_chunk = std::make_shared<uint64_t>(uint64_t(1) << 20);
  auto json = std::make_shared<bool>(false);
  cmd->add_option("input", *in, "Mesh file")->required();
  cmd->add_option("store", *dir, "Store directory to create")->required();
  cmd->add_option("--faces-per-chunk", *faces_per_chunk, "Target owned faces per chunk")->capture_default_str();
  cmd->add_flag("--json", *json, "Print a JSON record of the ingest");
  cmd->callback([=] {
    double t0 = now_seconds();
    MeshBuffers soup = read_mesh(*in);
    double t_read = now_seconds();
    StoreBuildOptions options;
    options.faces_per_chunk = *faces_per_chunk;
    // Each array is written (direct I/O) as soon as it is final, overlapping the rest of the
    // build; write_seconds is what remains after the build (syncs, header, renames).
    MeshStore store = MeshStore::build_and_write(std::move(soup), *dir, options);
    double t_build = now_seconds();
    double t_write = t_build;
    uint64_t in_bytes = *in == "-" ? 0 : std::filesystem::file_size(*in);  // "-": standard input
    nlohmann::json j = {{"input", *in},
                        {"store", *dir},
                        {"input_bytes", in_bytes},
                        {"vertices", store.header().vertex_count},
                        {"faces", store.header().face_count},
                        {"chunks", store.header().chunk_count},
                        {"store_bytes", store.size_bytes()},
                        {"read_seconds", t_read - t0},
                        {"build_seconds", t_build - t_read},
                        {"write_seconds", t_write - t_build},
                        {"total_seconds", t_write - t0},
                        {"read_mb_per_s", double(in_bytes) / 1e6 / std::max(1e-9, t_read - t0)},
                        {"ingest_mb_per_s", double(in_bytes) / 1e6 / std::max(1e-9, t_write - t0)},
                        {"peak_rss_bytes", peak_rss_bytes()}};
    if (*json)
      print_json(j);
    else
      std::fprintf(stderr,
                   "ingest: %s -> %s: %llu vertices, %llu faces, %u chunks, store %.1f MB; read %.2f s (%.0f MB/s), "
                   "build %.2f s, write %.2f s; peak RSS %.0f MB\n",
                   in->c_str(), dir->c_str(), (unsigned long long)store.header().vertex_count,
                   (unsigned long long)store.header().face_count, store.header().chunk_count,
                   double(store.size_bytes()) / 1e6, t_read - t0, double(in_bytes) / 1e6 / std::max(1e-9, t_read - t0),
                   t_build - t_read, t_write - t_build, double(peak_rss_bytes()) / 1e6);
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
