// `streamcvd bench SUITE.json`: runs every (case, algorithm) of a suite in its own forked child
// (so that peak memory is per run and a crash or timeout costs one row), collects one JSON record
// per run, and writes results.json, a Markdown table, SVG plots and wireframe PNG renders.
//
// Suite file (paths relative to the suite file):
//   {"name": "...", "defaults": {"seed": 1, "threads": 0, "metric": "I",
//                                 "algorithms": ["cvd", "openmesh-qem"], "distance_samples": 1000000,
//                                 "render_size": "640x640", "view": [30, 20], "timeout_seconds": 3600,
//                                 "qem_prevent_flips": true},
//    "cases": [{"name": "bunny_5k", "mesh": "../data/bun_zipper.ply", "N": 5000, ...any default...},
//              {"mesh": "a.ply", "N": 100, "algorithm": "cvd"}]}   ("algorithm": one of "algorithms")
// Algorithms: "cvd" (remesh_path, Algorithm 1 under the case's metric), "lloyd" (remesh_path with
// the Lloyd relaxation baseline of paper §VII, metrics I and IQ) and "openmesh-qem" (OpenMesh
// quadric decimater, to the vertex count of the case's CVD output when CVD ran first, else to N).
// Optional per case: "lloyd_max_iterations" (default 100), "lloyd_time_limit" (seconds, 0 = none).
#include <sys/resource.h>
#include <sys/wait.h>
#include <tbb/global_control.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <csignal>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <set>
#include <thread>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/measure/qem_decimate.h"
#include "streamcvd/core/measure/raster.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/io/output_file.h"
#include "streamcvd/streaming/io/png_writer.h"
#include "streamcvd/streaming/remesh_pipeline.h"
#include "streamcvd/streaming/run_reports.h"
#include "tools/bench.h"
#include "tools/commands.h"
#include "tools/measure.h"

namespace streamcvd::cli {


namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

const std::set<std::string> kAlgorithms = {"cvd", "lloyd", "openmesh-qem"};

struct BenchCase {
  std::string name, mesh, mesh_path;
  uint32_t vertices = 0;
  uint64_t seed = 1;
  uint32_t threads = 0;  // 0: every core
  std::string metric = "I";
  std::vector<std::string> algorithms = {"cvd", "openmesh-qem"};
  uint64_t distance_samples = 1'000'000;
  RenderOptions render;
  unsigned timeout_seconds = 3600;
  bool qem_prevent_flips = true;  // openmesh-qem: add ModNormalFlippingT
  uint32_t lloyd_max_iterations = LloydOptions{}.max_iterations;
  double lloyd_time_limit = LloydOptions{}.time_limit_seconds;
};

// Characters safe in file names; anything else becomes '_'.
std::string file_safe(const std::string& s) {
  std::string out;
  for (char c : s) out += (std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' || c == '.') ? c : '_';
  return out.empty() ? "case" : out;
}

template <class T>
T field(const json& c, const json& defaults, const char* key, T fallback) {
  if (c.contains(key)) return c[key].get<T>();
  if (defaults.contains(key)) return defaults[key].get<T>();
  return fallback;
}

std::vector<BenchCase> parse_suite(const std::string& suite_path, json& suite) {
  std::ifstream in(suite_path);
  if (!in) throw InputError(error_at(suite_path, "cannot open the suite file"));
  std::vector<BenchCase> cases;
  std::string where = "";
  try {
    suite = json::parse(in);
    const json defaults = suite.value("defaults", json::object());
    if (!suite.contains("cases") || !suite["cases"].is_array() || suite["cases"].empty())
      throw InputError("expected a non-empty \"cases\" array");
    const fs::path base = fs::path(suite_path).parent_path();
    std::set<std::string> names;
    for (size_t i = 0; i < suite["cases"].size(); ++i) {
      const json& c = suite["cases"][i];
      where = "case " + std::to_string(i) + ": ";
      BenchCase bc;
      if (!c.contains("mesh") || !c.contains("N")) throw InputError("needs \"mesh\" and \"N\"");
      bc.mesh = c["mesh"].get<std::string>();
      bc.mesh_path = fs::path(bc.mesh).is_absolute() ? bc.mesh : (base / bc.mesh).lexically_normal().string();
      const int64_t n = c["N"].get<int64_t>();
      if (n < 1 || n > 2'000'000'000) throw InputError("N must be within 1..2000000000");
      bc.vertices = uint32_t(n);
      bc.name = file_safe(field<std::string>(c, json::object(), "name",
                                             fs::path(bc.mesh).stem().string() + "_" + std::to_string(n)));
      if (!names.insert(bc.name).second) throw InputError("duplicate case name '" + bc.name + "'");
      bc.seed = field<uint64_t>(c, defaults, "seed", bc.seed);
      const int64_t threads = field<int64_t>(c, defaults, "threads", 0);
      if (threads < 0 || threads > 4096) throw InputError("threads must be within 0..4096 (0: all cores)");
      bc.threads = uint32_t(threads);
      bc.metric = field<std::string>(c, defaults, "metric", bc.metric);
      Metric metric;
      if (!parse_metric(bc.metric, metric)) throw InputError("unknown metric '" + bc.metric + "' (I, IQ, A, AQ)");
      bc.algorithms = field<std::vector<std::string>>(c, defaults, "algorithms", bc.algorithms);
      if (c.contains("algorithm")) bc.algorithms = {c["algorithm"].get<std::string>()};  // one row only
      if (bc.algorithms.empty()) throw InputError("\"algorithms\" is empty");
      for (const std::string& a : bc.algorithms)
        if (!kAlgorithms.count(a)) throw InputError("unknown algorithm '" + a + "' (cvd, lloyd, openmesh-qem)");
        else if (a == "lloyd" && is_anisotropic(metric)) throw InputError("lloyd: only the metrics I and IQ");
      bc.distance_samples = field<uint64_t>(c, defaults, "distance_samples", bc.distance_samples);
      if (bc.distance_samples > kMaxDistanceSamples) throw InputError("distance_samples above 100000000");
      parse_size(field<std::string>(c, defaults, "render_size", "640x640"), bc.render);
      const auto view = field<std::vector<double>>(c, defaults, "view", {30, 20});
      if (view.size() != 2) throw InputError("view must be [azimuth, elevation]");
      parse_view(std::to_string(view[0]) + "," + std::to_string(view[1]), bc.render);
      bc.render.wireframe = true;
      bc.timeout_seconds = field<unsigned>(c, defaults, "timeout_seconds", bc.timeout_seconds);
      bc.qem_prevent_flips = field<bool>(c, defaults, "qem_prevent_flips", bc.qem_prevent_flips);
      bc.lloyd_max_iterations = field<uint32_t>(c, defaults, "lloyd_max_iterations", bc.lloyd_max_iterations);
      bc.lloyd_time_limit = field<double>(c, defaults, "lloyd_time_limit", bc.lloyd_time_limit);
      cases.push_back(std::move(bc));
    }
  } catch (const json::exception& e) {
    throw InputError(error_at(suite_path, where + e.what()));
  } catch (const InputError& e) {
    throw InputError(error_at(suite_path, where + e.what()));
  }
  return cases;
}

// Loop energies and cumulative times: every pass of minimize_clustering restarts its clock (I
// then QEM sites for IQ, then the constrained pass), so a pass's times are offset by the end of
// the previous one, detected as a clock that went backwards. Lloyd is one pass. The loops that
// remesh() appends after a repair (a relaxation of the repaired clusters) are left out: the
// series is the clustering algorithm's own (paper Fig. 9), ending at cr.final_energy.
void loop_series(const ClusteringReport& cr, json& record) {
  const size_t loops = std::min(cr.seconds_per_loop.size(), size_t(cr.unconstrained_loops) + cr.constrained_loops);
  std::vector<double> t(cr.seconds_per_loop.begin(), cr.seconds_per_loop.begin() + loops);
  double offset = 0;
  for (size_t i = 1; i < t.size(); ++i) {
    if (cr.seconds_per_loop[i] < cr.seconds_per_loop[i - 1]) offset = t[i - 1];
    t[i] += offset;
  }
  record["energy_per_loop"] = std::vector<double>(cr.energy_per_loop.begin(), cr.energy_per_loop.begin() + loops);
  record["seconds_per_loop"] = t;
  record["clustering_energy"] = cr.final_energy;  // before the repair; Lloyd: its best iterate
}

struct RowPaths {
  std::string mesh_out, render_out;  // relative to the output folder
};

// Runs one algorithm on one case; everything that happens inside the forked child.
json run_row(const BenchCase& c, const std::string& algorithm, uint32_t target, const fs::path& out_dir,
             const RowPaths& paths) {
  json r;
  MeshBuffers output;
  double t0 = now_seconds();
  if (algorithm == "cvd" || algorithm == "lloyd") {
    PipelineOptions options;
    options.remesh.vertices = c.vertices;
    options.remesh.seed = c.seed;
    parse_metric(c.metric, options.remesh.clustering.metric);  // validated by parse_suite
    if (algorithm == "lloyd") options.remesh.clustering.algorithm = ClusteringOptions::Algorithm::Lloyd;
    options.remesh.clustering.lloyd.max_iterations = c.lloyd_max_iterations;
    options.remesh.clustering.lloyd.time_limit_seconds = c.lloyd_time_limit;
    // The clustering on one thread, as the bench has always timed it (TBB is limited to
    // c.threads for the rest of the job).
    options.remesh.clustering.loops.threads = 1;
    const IoCounters io0 = read_io_counters();
    PipelineResult p = remesh_path(c.mesh_path, options);
    const double total = now_seconds() - t0;
    // The record of `streamcvd remesh --report` (one writer for both commands: stage times,
    // loops, repair, checks...), beside the figures every algorithm of the table has.
    r["report"] = remesh_report(p, options, {c.mesh_path, paths.mesh_out, 0, total, io0, nullptr});
    r["seconds"] = {{"load", p.load_seconds}, {"algorithm", total - p.load_seconds}, {"total", total}};
    loop_series(p.remesh.clustering, r);
    output = std::move(p.remesh.mesh);
  } else {  // "openmesh-qem"
    LoadedMesh input = load_mesh_or_store(c.mesh_path);
    const double load = now_seconds() - t0;
    QemReport q;
    output = decimate_quadric(input.view(), target, &q, c.qem_prevent_flips);
    const double total = now_seconds() - t0;
    r["input"] = {{"vertices", input.view().vertex_count()}, {"faces", input.view().face_count()}};
    r["target_vertices"] = target;
    r["seconds"] = {{"load", load},
                    {"build", q.build_seconds},
                    {"decimate", q.decimate_seconds},
                    {"algorithm", total - load},
                    {"total", total}};
    r["qem"] = {{"faces_skipped", q.faces_skipped}, {"collapses", q.collapses}, {"prevent_flips", c.qem_prevent_flips}};
  }
  // Peak of the run itself, before the measuring below allocates its BVHs and samples.
  r["peak_rss_bytes"] = peak_rss_bytes();
  const TopologyStats topo = compute_topology_stats(output.view());
  r["output"] = {{"vertices", topo.vertices},
                 {"faces", topo.faces},
                 {"boundary_edges", topo.boundary_edges},
                 {"components", topo.components},
                 {"closed_manifold", topo.closed_manifold},
                 {"nonmanifold_edges", topo.nonmanifold_edges},
                 {"mesh", paths.mesh_out}};
  r["quality"] = quality_json(compute_quality(output.view()));
  write_mesh((out_dir / paths.mesh_out).string(), output.view());
  const double td = now_seconds();
  {
    LoadedMesh input = load_mesh_or_store(c.mesh_path);
    DistanceReport d = measure_distance(c.mesh_path, input.view(), (out_dir / paths.mesh_out).string(),
                                        output.view(), c.distance_samples, c.seed);
    r["distance"] = distance_json(d);
  }
  r["distance"]["samples_per_side"] = c.distance_samples;
  r["distance"]["seed"] = c.seed;
  r["distance"]["seconds"] = now_seconds() - td;
  write_png((out_dir / paths.render_out).string(), render_mesh(output.view(), c.render));
  r["render"] = paths.render_out;
  return r;
}

void write_all(int fd, const std::string& s) {
  size_t done = 0;
  while (done < s.size()) {
    ssize_t n = ::write(fd, s.data() + done, s.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return;
    done += size_t(n);
  }
}

// Forks, runs the row in the child (thread limit, timeout), and returns the child's record
// completed with its exit status and resource usage.
json run_forked(const BenchCase& c, const std::string& algorithm, uint32_t target, const fs::path& out_dir,
                const RowPaths& paths) {
  int fds[2];
  if (::pipe(fds) != 0) throw std::runtime_error(std::string("pipe: ") + std::strerror(errno));
  std::fflush(stdout);
  std::fflush(stderr);
  const pid_t pid = ::fork();
  if (pid < 0) throw std::runtime_error(std::string("fork: ") + std::strerror(errno));
  if (pid == 0) {
    ::close(fds[0]);
    json r;
    int code = 0;
    try {
      ::alarm(c.timeout_seconds);
      std::unique_ptr<tbb::global_control> limit;
      if (c.threads > 0)
        limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, c.threads);
      r = run_row(c, algorithm, target, out_dir, paths);
      r["status"] = "ok";
    } catch (const std::bad_alloc&) {
      r = {{"status", "error"}, {"error", "out of memory"}};
      code = 1;
    } catch (const std::exception& e) {
      r = {{"status", "error"}, {"error", e.what()}};
      code = 1;
    }
    write_all(fds[1], r.dump());
    ::close(fds[1]);
    std::fflush(stderr);
    ::_exit(code);  // no atexit handlers, no unwinding into the parent's frames
  }
  ::close(fds[1]);
  std::string text;
  char buf[65536];
  for (;;) {
    ssize_t n = ::read(fds[0], buf, sizeof buf);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    text.append(buf, size_t(n));
  }
  ::close(fds[0]);
  int status = 0;
  rusage usage{};
  while (::wait4(pid, &status, 0, &usage) < 0 && errno == EINTR) {
  }
  json r = json::parse(text, nullptr, false);
  if (r.is_discarded() || !r.is_object()) {
    std::string why = "child exited with status " + std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1);
    if (WIFSIGNALED(status)) {
      why = "child killed by signal " + std::to_string(WTERMSIG(status));
      if (WTERMSIG(status) == SIGALRM) why += " (timeout after " + std::to_string(c.timeout_seconds) + " s)";
    }
    r = {{"status", "error"}, {"error", why}};
  }
  r["peak_rss_bytes_process"] = uint64_t(usage.ru_maxrss) * 1024;  // the whole child, measuring included
  r["cpu_seconds"] = double(usage.ru_utime.tv_sec + usage.ru_stime.tv_sec) +
                     1e-6 * double(usage.ru_utime.tv_usec + usage.ru_stime.tv_usec);
  return r;
}

json machine_json() {
  double load[3] = {0, 0, 0};
  if (::getloadavg(load, 3) != 3) load[0] = load[1] = load[2] = -1;
  return {{"hardware_threads", std::thread::hardware_concurrency()}, {"load_average", {load[0], load[1], load[2]}}};
}

void make_dir(const fs::path& p) {
  std::error_code ec;
  fs::create_directories(p, ec);
  if (ec || !fs::is_directory(p)) throw OutputError(error_at(p.string(), "cannot create the folder: " + ec.message()));
}

}  // namespace

void add_bench_command(CLI::App& app) {
  struct Args {
    std::string suite, out = "bench_out", markdown;
    int64_t samples = -1;
  };
  auto args = std::make_shared<Args>();
  auto* cmd = app.add_subcommand("bench", "Run a benchmark suite: CVD and baselines, timings, memory, quality, distances");
  cmd->add_option("suite", args->suite, "Suite JSON file (mesh paths relative to it)")->required();
  cmd->add_option("--out", args->out, "Output folder: results.json, results.md, plots/, renders/, meshes/")
      ->capture_default_str();
  cmd->add_option("--markdown", args->markdown, "Also write the results table to this Markdown file");
  cmd->add_option("--samples", args->samples, "Distance samples per side for every case (overrides the suite)");
  cmd->callback([args] {
    json suite;
    std::vector<BenchCase> cases = parse_suite(args->suite, suite);
    if (args->samples >= 0) {
      if (uint64_t(args->samples) > kMaxDistanceSamples) throw InputError("--samples: above the limit of 100000000");
      for (BenchCase& c : cases) c.distance_samples = uint64_t(args->samples);
    }
    const fs::path out(args->out);
    for (const char* sub : {"", "meshes", "renders", "plots"}) make_dir(out / sub);
    install_signal_cleanup();
    json results = {{"suite", args->suite}, {"suite_name", suite.value("name", std::string())},
                    {"machine_at_start", machine_json()}, {"records", json::array()}};
    json& records = results["records"];
    size_t failures = 0, runs = 0, total_runs = 0;
    std::string first_failure;
    for (const BenchCase& c : cases) total_runs += c.algorithms.size();
    for (const BenchCase& c : cases) {
      uint32_t cvd_vertices = 0;
      for (const std::string& algorithm : c.algorithms) {
        ++runs;
        const uint32_t target = cvd_vertices ? cvd_vertices : c.vertices;
        const std::string stem = c.name + "_" + file_safe(algorithm);
        json r;
        if (!fs::exists(c.mesh_path)) {
          r = {{"status", "skipped"}, {"error", "mesh not found: " + c.mesh_path}};
        } else {
          std::fprintf(stderr, "bench: [%zu/%zu] %s %s (N=%u) ...\n", runs, total_runs, c.name.c_str(),
                       algorithm.c_str(), c.vertices);
          r = run_forked(c, algorithm, target, out, {"meshes/" + stem + ".ply", "renders/" + stem + ".png"});
        }
        r["case"] = c.name;
        r["algorithm"] = algorithm;
        r["mesh"] = c.mesh;
        r["N"] = c.vertices;
        r["metric"] = c.metric;
        r["threads"] = c.threads;
        r["seed"] = c.seed;
        const std::string status = r["status"];
        if (status == "ok") {
          if (algorithm == "cvd") cvd_vertices = r["output"]["vertices"].get<uint32_t>();
          std::fprintf(stderr, "  %s: %.2f s, peak %.0f MB, Qav %.3f, angles<30 %.2f%%, Hausdorff %.3f%% of diag\n",
                       status.c_str(), r["seconds"]["algorithm"].get<double>(),
                       r["peak_rss_bytes"].get<double>() / 1e6, r["quality"]["q_avg"].get<double>(),
                       r["quality"]["percent_angles_below_30"].get<double>(),
                       100 * r["distance"]["hausdorff_relative"].get<double>());
        } else {
          std::fprintf(stderr, "  %s: %s\n", status.c_str(), r.value("error", std::string()).c_str());
          if (status == "error" && failures++ == 0) first_failure = c.name + "/" + algorithm + ": " + r.value("error", "");
        }
        records.push_back(std::move(r));
        write_file_atomic((out / "results.json").string(), results.dump(2) + "\n");  // progress survives a kill
      }
    }
    results["machine_at_end"] = machine_json();
    write_file_atomic((out / "results.json").string(), results.dump(2) + "\n");
    const std::string table = bench_markdown(records);
    write_file_atomic((out / "results.md").string(), table);
    if (!args->markdown.empty()) write_file_atomic(args->markdown, table);
    write_file_atomic((out / "plots" / "energy.svg").string(), energy_svg(records));
    for (const BenchCase& c : cases) {
      json rows = json::array();
      for (const json& r : records)
        if (r["case"] == c.name && r["status"] == "ok") rows.push_back(r);
      // Energy against time of the case's clustering algorithms side by side (paper Fig. 9).
      if (std::count(c.algorithms.begin(), c.algorithms.end(), "cvd") +
              std::count(c.algorithms.begin(), c.algorithms.end(), "lloyd") >= 2)
        write_file_atomic((out / "plots" / (c.name + "_energy.svg")).string(), energy_svg(rows));
      if (!rows.empty())
        write_file_atomic((out / "plots" / (c.name + "_histograms.svg")).string(),
                          histogram_svg(c.name + ": triangle quality and smallest angle", rows));
    }
    std::fprintf(stderr, "bench: %zu runs, %zu failed; results in %s\n", runs, failures, out.string().c_str());
    if (failures) throw InputError("bench: " + std::to_string(failures) + " run(s) failed, first: " + first_failure);
  });
}

}  // namespace streamcvd::cli
