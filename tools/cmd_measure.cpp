// `distance` and `render`: measuring a result against its input, and looking at it.
#include <cmath>
#include <cstdio>
#include <memory>
#include <string_view>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/raster.h"
#include "streamcvd/core/measure/surface_distance.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/io/output_file.h"
#include "streamcvd/streaming/io/png_writer.h"
#include "tools/commands.h"
#include "tools/job_options.h"
#include "streamcvd/streaming/run_reports.h"
#include "tools/measure.h"

namespace streamcvd::cli {
namespace {

constexpr std::string_view kCorePrefix = "surface distance: ";

// Parses a whole string as a double; false on trailing garbage or a non-finite value.
bool parse_double(const std::string& s, double& out) {
  try {
    size_t used = 0;
    out = std::stod(s, &used);
    return used == s.size() && std::isfinite(out);
  } catch (const std::exception&) {
    return false;
  }
}

bool parse_u32(const std::string& s, uint32_t& out) {
  if (s.empty() || s.size() > 9 || s.find_first_not_of("0123456789") != std::string::npos) return false;
  out = uint32_t(std::stoul(s));
  return true;
}

void print_side(const char* label, const OneSidedDistance& s, const DistanceReport& d) {
  std::printf("  %-9s %12.6g (%7.4f%%) %12.6g (%7.4f%%) %12.6g (%7.4f%%)\n", label, s.max, 100 * d.relative(s.max),
              s.mean, 100 * d.relative(s.mean), s.rms, 100 * d.relative(s.rms));
}

}  // namespace

LoadedMesh load_mesh_or_store(const std::string& path, uint64_t memory_limit) {
  LoadedMesh loaded;
  if (is_store_directory(path)) {
    loaded.store = MeshStore::open(path), loaded.store->validate_all();
  } else {
    ReadOptions read;
    read.memory_limit = memory_limit;
    loaded.buffers = read_mesh(path, read);
  }
  return loaded;
}

DistanceReport measure_distance(const std::string& a_name, const TriangleSoupView& a, const std::string& b_name,
                                const TriangleSoupView& b, uint64_t samples_per_side, uint64_t seed) {
  // The core names the sides "A" and "B"; the user knows them by file name.
  if (a.face_count() == 0) throw InputError(error_at(a_name, "surface distance: the mesh has no faces"));
  if (b.face_count() == 0) throw InputError(error_at(b_name, "surface distance: the mesh has no faces"));
  if (samples_per_side > kMaxDistanceSamples)
    throw InputError("--samples: " + std::to_string(samples_per_side) + " is above the limit of " +
                     std::to_string(kMaxDistanceSamples) + " samples per side");
  try {
    return surface_distance(a, b, samples_per_side, seed);
  } catch (const InputError& e) {
    std::string what = e.what();
    std::string who = a_name + " vs " + b_name;
    if (what.find("mesh A") != std::string::npos) who = a_name;
    else if (what.find("mesh B") != std::string::npos) who = b_name;
    if (what.rfind(kCorePrefix, 0) != 0) what = std::string(kCorePrefix) + what;
    throw InputError(error_at(who, what));
  }
}

void parse_view(const std::string& text, RenderOptions& options) {
  const size_t comma = text.find(',');
  double az = 0, el = 0;
  if (comma == std::string::npos || !parse_double(text.substr(0, comma), az) ||
      !parse_double(text.substr(comma + 1), el) || std::abs(el) > 90 || std::abs(az) > 3600)
    throw InputError("--view: expected AZIMUTH,ELEVATION in degrees (elevation within ±90), got '" + text + "'");
  options.azimuth_deg = az;
  options.elevation_deg = el;
}

void parse_size(const std::string& text, RenderOptions& options) {
  const size_t x = text.find_first_of("xX");
  uint32_t w = 0, h = 0;
  if (x == std::string::npos || !parse_u32(text.substr(0, x), w) || !parse_u32(text.substr(x + 1), h) || w < 1 ||
      h < 1 || w > 16384 || h > 16384)
    throw InputError("--size: expected WIDTHxHEIGHT in pixels, each 1-16384, got '" + text + "'");
  options.width = w;
  options.height = h;
}

void add_distance_command(CLI::App& app) {
  struct Args {
    std::string a, b;
    uint64_t samples = 1'000'000, seed = 1;
    bool json = false;
    JobOptions job;
  };
  auto args = std::make_shared<Args>();
  auto* cmd = app.add_subcommand("distance", "Two-sided Metro distance between two surfaces (A is the reference)");
  cmd->add_option("a", args->a, "Reference mesh file or store directory (relative figures use its bbox diagonal)")
      ->required();
  cmd->add_option("b", args->b, "Compared mesh file or store directory")->required();
  cmd->add_option("--samples", args->samples, "Random face samples per side, added to the vertices (at most 100M)")
      ->capture_default_str();
  cmd->add_option("--seed", args->seed, "Seed of the face samples (same seed, same figures)")->capture_default_str();
  cmd->add_flag("--json", args->json, "Print JSON instead of text");
  add_job_options(cmd, args->job);
  cmd->callback([args] {
    auto threads = thread_limit(args->job);
    if (args->samples > kMaxDistanceSamples)
      throw InputError("--samples: " + std::to_string(args->samples) + " is above the limit of " +
                       std::to_string(kMaxDistanceSamples) + " samples per side (each costs ~28 bytes)");
    double t0 = now_seconds();
    LoadedMesh a = load_mesh_or_store(args->a, memory_limit(args->job) / 2);
    LoadedMesh b = load_mesh_or_store(args->b, memory_limit(args->job) / 2);
    double t1 = now_seconds();
    DistanceReport d = measure_distance(args->a, a.view(), args->b, b.view(), args->samples, args->seed);
    double t2 = now_seconds();
    if (args->json) {
      nlohmann::json j = distance_json(d);
      j["a"] = args->a;
      j["b"] = args->b;
      j["a_faces"] = a.view().face_count();
      j["b_faces"] = b.view().face_count();
      j["samples_per_side"] = args->samples;
      j["seed"] = args->seed;
      j["load_seconds"] = t1 - t0;
      j["distance_seconds"] = t2 - t1;
      j["peak_rss_bytes"] = peak_rss_bytes();
      print_json(j);
      return;
    }
    std::printf("distance: %s (reference, A) vs %s (B)\n", args->a.c_str(), args->b.c_str());
    std::printf("  samples   %llu per side + vertices, seed %llu; bbox diagonal of A %g\n",
                (unsigned long long)args->samples, (unsigned long long)args->seed, d.diagonal);
    std::printf("  %-9s %23s %23s %23s\n", "", "max (% diag)", "mean (% diag)", "RMS (% diag)");
    print_side("A -> B", d.a_to_b, d);
    print_side("B -> A", d.b_to_a, d);
    std::printf("  RMS both  %12.6g (%7.4f%% of the diagonal; both sides' samples pooled)\n", d.two_sided_rms(),
                100 * d.relative(d.two_sided_rms()));
    std::printf("  Hausdorff %12.6g (%7.4f%% of the diagonal)\n", d.hausdorff, 100 * d.relative_hausdorff());
    std::printf("  time      load %.2f s, distance %.2f s; peak %.0f MB\n", t1 - t0, t2 - t1,
                double(peak_rss_bytes()) / 1e6);
  });
}

void add_render_command(CLI::App& app) {
  struct Args {
    std::string input, output, view = "30,20", size = "800x800";
    bool wireframe = false;
    JobOptions job;
  };
  auto args = std::make_shared<Args>();
  auto* cmd = app.add_subcommand("render", "Render a mesh to a PNG (software z-buffer, flat shading, headlight)");
  cmd->add_option("input", args->input, "Mesh file or store directory")->required();
  cmd->add_option("-o,--output", args->output, "Output PNG file")->required();
  cmd->add_flag("--wireframe", args->wireframe, "Draw the visible edges as dark lines over the shading");
  add_job_options(cmd, args->job);
  cmd->add_option("--view", args->view, "Camera azimuth,elevation in degrees (about +y, above the xz plane)")
      ->capture_default_str();
  cmd->add_option("--size", args->size, "Image size WIDTHxHEIGHT in pixels")->capture_default_str();
  cmd->callback([args] {
    RenderOptions options;
    parse_view(args->view, options);
    parse_size(args->size, options);
    options.wireframe = args->wireframe;
    install_signal_cleanup();
    double t0 = now_seconds();
    auto threads = thread_limit(args->job);
    LoadedMesh mesh = load_mesh_or_store(args->input, memory_limit(args->job));
    RgbImage image;
    try {
      image = render_mesh(mesh.view(), options);
    } catch (const InputError& e) {
      throw InputError(error_at(args->input, e.what()));  // "render: face 3 uses vertex ..." names no file
    }
    write_png(args->output, image);
    std::fprintf(stderr, "render: %s -> %s (%ux%u, %llu faces) in %.2f s\n", args->input.c_str(),
                 args->output.c_str(), options.width, options.height, (unsigned long long)mesh.view().face_count(),
                 now_seconds() - t0);
  });
}

}  // namespace streamcvd::cli
