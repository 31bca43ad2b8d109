// End-to-end tests of the measuring subcommands `distance`, `render` and `bench` (suite Bench),
// run through the CLI binary (STREAMCVD_CLI).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/io/png_writer.h"
#include "tests/cli_runner.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

namespace fs = std::filesystem;
using json = nlohmann::json;

std::string write_sphere(const fs::path& dir, const std::string& name, int level, float radius) {
  const std::string path = (dir / name).string();
  write_mesh(path, make_icosphere(level, radius).view());
  return path;
}

json run_json(const std::vector<std::string>& args) {
  const test::CliResult r = test::run_cli(args);
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  json j = json::parse(r.out, nullptr, false);
  EXPECT_FALSE(j.is_discarded()) << r.out;
  return j;
}

TEST(Bench, DistanceSphereVsScaledSphereIsOnePercentOfRadius) {
  ASSERT_TRUE(test::cli_available()) << "STREAMCVD_CLI not built";
  const fs::path dir = test::temp_dir("bench_dist");
  const float r = 2.0f;
  const std::string a = write_sphere(dir, "a.ply", 5, r), b = write_sphere(dir, "b.ply", 5, 1.01f * r);
  const json j = run_json({"distance", a, b, "--samples", "200000", "--seed", "3", "--json"});
  const double h = j["hausdorff"].get<double>(), expected = 0.01 * r;
  EXPECT_NEAR(h, expected, 0.02 * expected);
  // Relative figures are against A's bbox diagonal (2r·√3 for a sphere).
  EXPECT_NEAR(j["diagonal"].get<double>(), 2 * r * std::sqrt(3.0), 1e-3);
  EXPECT_NEAR(j["hausdorff_relative"].get<double>(), h / j["diagonal"].get<double>(), 1e-12);
  // Both directions see the same 1% gap on average, and the counts include the vertices.
  for (const char* side : {"a_to_b", "b_to_a"}) {
    EXPECT_NEAR(j[side]["mean"].get<double>(), expected, 0.03 * expected) << side;
    EXPECT_EQ(j[side]["samples"].get<uint64_t>(), 200000u + 10242u) << side;
  }
  // Same seed, same figures.
  const json again = run_json({"distance", a, b, "--samples", "200000", "--seed", "3", "--json"});
  EXPECT_EQ(again["a_to_b"], j["a_to_b"]);
  EXPECT_EQ(again["b_to_a"], j["b_to_a"]);
  fs::remove_all(dir);
}

TEST(Bench, DistanceOfAMeshToItselfIsZero) {
  ASSERT_TRUE(test::cli_available()) << "STREAMCVD_CLI not built";
  const fs::path dir = test::temp_dir("bench_self");
  const std::string a = write_sphere(dir, "a.ply", 4, 1.0f);
  const json j = run_json({"distance", a, a, "--samples", "50000", "--json"});
  // Face samples are rounded to float, so "zero" is within float rounding of the unit sphere.
  EXPECT_LT(j["hausdorff"].get<double>(), 1e-6);
  EXPECT_LT(j["a_to_b"]["mean"].get<double>(), 1e-7);
  // The text form prints the Hausdorff line too.
  const test::CliResult text = test::run_cli({"distance", a, a, "--samples", "1000"});
  EXPECT_EQ(text.exit_code, 0) << text.describe();
  EXPECT_NE(text.out.find("Hausdorff"), std::string::npos) << text.out;
  fs::remove_all(dir);
}

TEST(Bench, DistanceErrorsNameTheFileAndCapSamples) {
  ASSERT_TRUE(test::cli_available()) << "STREAMCVD_CLI not built";
  const fs::path dir = test::temp_dir("bench_dist_err");
  const std::string a = write_sphere(dir, "a.ply", 1, 1.0f);
  const std::string faceless = (dir / "points.off").string();
  std::ofstream(faceless) << "OFF\n3 0 0\n0 0 0\n1 0 0\n0 1 0\n";
  // A mesh without faces is rejected by the reader already, naming the file.
  test::CliResult r = test::run_cli({"distance", a, faceless, "--samples", "10"});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_NE(r.err.find("points.off: no faces"), std::string::npos) << r.err;
  r = test::run_cli({"distance", faceless, a, "--samples", "10"});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_NE(r.err.find("points.off: no faces"), std::string::npos) << r.err;
  r = test::run_cli({"distance", a, a, "--samples", "100000001"});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_NE(r.err.find("100000000"), std::string::npos) << r.err;
  r = test::run_cli({"distance", a, (dir / "missing.ply").string()});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_NE(r.err.find("missing.ply"), std::string::npos) << r.err;
  fs::remove_all(dir);
}

TEST(Bench, RenderWritesAPngOfTheRequestedSize) {
  ASSERT_TRUE(test::cli_available()) << "STREAMCVD_CLI not built";
  const fs::path dir = test::temp_dir("bench_render");
  const std::string a = write_sphere(dir, "a.ply", 2, 1.0f);
  const std::string png = (dir / "a.png").string();
  test::CliResult r = test::run_cli({"render", a, "-o", png, "--wireframe", "--view", "45,30", "--size", "120x80"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const RgbImage im = read_png(png);
  EXPECT_EQ(im.width, 120u);
  EXPECT_EQ(im.height, 80u);
  uint64_t foreground = 0, dark = 0;
  for (size_t i = 0; i < im.pixels.size(); i += 3) {
    foreground += im.pixels[i] != 255 || im.pixels[i + 1] != 255 || im.pixels[i + 2] != 255;
    dark += im.pixels[i] < 80 && im.pixels[i + 1] < 80 && im.pixels[i + 2] < 80;
  }
  EXPECT_GT(foreground, 120u * 80 / 4);  // the sphere fills a good part of the frame
  EXPECT_LT(foreground, 120u * 80);      // but not the margins
  EXPECT_GT(dark, 100u);                 // wireframe lines
  for (const char* bad : {"--size=0x10", "--size=12", "--view=10", "--view=0,95"}) {
    r = test::run_cli({"render", a, "-o", (dir / "b.png").string(), bad});
    EXPECT_EQ(r.exit_code, 2) << bad << ": " << r.describe();
    EXPECT_FALSE(fs::exists(dir / "b.png"));
  }
  fs::remove_all(dir);
}

// Runs the tiny suite into `out` and returns results.json.
json run_tiny_suite(const fs::path& suite, const fs::path& out) {
  const test::CliResult r = test::run_cli({"bench", suite.string(), "--out", out.string(), "--markdown",
                                           (out.string() + "_table.md")},
                                          {.watchdog_seconds = 300});
  EXPECT_EQ(r.exit_code, 0) << r.describe();
  std::ifstream f(out / "results.json");
  json j = json::parse(f, nullptr, false);
  EXPECT_FALSE(j.is_discarded());
  return j;
}

TEST(Bench, TinySuiteRunsEndToEndAndRepeats) {
  ASSERT_TRUE(test::cli_available()) << "STREAMCVD_CLI not built";
  const fs::path dir = test::temp_dir("bench_suite");
  fs::create_directories(dir / "suite" / "meshes");
  write_sphere(dir / "suite" / "meshes", "sphere.ply", 3, 1.0f);
  const fs::path suite = dir / "suite" / "tiny.json";
  std::ofstream(suite) << R"({"name": "tiny",
    "defaults": {"seed": 11, "threads": 1, "metric": "I", "distance_samples": 20000, "render_size": "160x120"},
    "cases": [{"name": "sphere_200", "mesh": "meshes/sphere.ply", "N": 200,
               "algorithms": ["cvd", "openmesh-qem"]},
              {"name": "absent", "mesh": "meshes/absent.ply", "N": 50, "algorithm": "cvd"}]})";
  const json first = run_tiny_suite(suite, dir / "out1");
  ASSERT_TRUE(first.contains("records"));
  const json& records = first["records"];
  ASSERT_EQ(records.size(), 3u);
  for (int i = 0; i < 2; ++i) {
    const json& r = records[i];
    SCOPED_TRACE(r.dump().substr(0, 400));
    ASSERT_EQ(r["status"], "ok");
    EXPECT_EQ(r["case"], "sphere_200");
    EXPECT_EQ(r["algorithm"], i == 0 ? "cvd" : "openmesh-qem");
    EXPECT_EQ(r["N"], 200);
    EXPECT_EQ(r["seed"], 11);
    EXPECT_EQ(r["threads"], 1);
    EXPECT_EQ(r["output"]["vertices"], 200);  // closed sphere: exactly N, and QEM matches CVD's count
    EXPECT_TRUE(r["output"]["closed_manifold"].get<bool>());
    for (const char* key : {"load", "algorithm", "total"}) EXPECT_GE(r["seconds"][key].get<double>(), 0.0) << key;
    EXPECT_GT(r["peak_rss_bytes"].get<double>(), 1e6);
    EXPECT_GE(r["peak_rss_bytes_process"].get<double>(), r["peak_rss_bytes"].get<double>());
    EXPECT_GT(r["quality"]["q_avg"].get<double>(), 0.5);
    EXPECT_EQ(r["quality"]["q_histogram"].size(), 20u);
    EXPECT_EQ(r["quality"]["min_angle_histogram"].size(), 12u);
    const double h = r["distance"]["hausdorff_relative"].get<double>();
    EXPECT_GT(h, 0.0);
    EXPECT_LT(h, 0.05);
    EXPECT_EQ(r["distance"]["a_to_b"]["samples"].get<uint64_t>(), 20000u + 642u);  // face samples + input vertices
    EXPECT_TRUE(fs::exists(dir / "out1" / r["output"]["mesh"].get<std::string>()));
    const RgbImage png = read_png((dir / "out1" / r["render"].get<std::string>()).string());
    EXPECT_EQ(png.width, 160u);
    EXPECT_EQ(png.height, 120u);
  }
  const json& cvd = records[0];
  EXPECT_GT(cvd["report"]["clustering"]["unconstrained_loops"].get<int>(), 0);
  EXPECT_EQ(cvd["report"]["output"]["vertices"], 200);  // the remesh report, as `remesh --report` writes it
  EXPECT_TRUE(cvd["report"]["checks"]["all_ok"].get<bool>());
  EXPECT_GT(cvd["report"]["seconds"]["clustering"].get<double>(), 0.0);
  EXPECT_TRUE(cvd["report"]["seconds"].contains("optimize"));
  EXPECT_TRUE(cvd["report"]["seconds"].contains("clustering_cpu"));
  EXPECT_EQ(cvd["energy_per_loop"].size(), cvd["seconds_per_loop"].size());
  EXPECT_GT(cvd["energy_per_loop"].size(), 0u);
  EXPECT_GT(cvd["report"]["clustering"]["final_energy"].get<double>(), 0.0);
  EXPECT_EQ(records[1]["target_vertices"], 200);
  EXPECT_EQ(records[2]["status"], "skipped");

  for (const char* file : {"results.md", "plots/energy.svg", "plots/sphere_200_histograms.svg"})
    EXPECT_TRUE(fs::exists(dir / "out1" / file)) << file;
  const std::string table = test::slurp((dir / "out1_table.md").string());
  EXPECT_NE(table.find("| sphere_200 | cvd | 200 | 200 |"), std::string::npos) << table;
  EXPECT_NE(table.find("| sphere_200 | openmesh-qem | 200 | 200 |"), std::string::npos) << table;
  EXPECT_NE(test::slurp((dir / "out1" / "plots" / "energy.svg").string()).find("<polyline"), std::string::npos);

  // Same seeds, same quality and distance figures.
  const json second = run_tiny_suite(suite, dir / "out2");
  ASSERT_EQ(second["records"].size(), 3u);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(second["records"][i]["quality"], records[i]["quality"]) << i;
    EXPECT_EQ(second["records"][i]["distance"]["hausdorff"], records[i]["distance"]["hausdorff"]) << i;
  }
  EXPECT_EQ(second["records"][0]["report"]["clustering"]["final_energy"], cvd["report"]["clustering"]["final_energy"]);
  EXPECT_EQ(second["records"][1]["qem"], records[1]["qem"]);
  fs::remove_all(dir);
}

TEST(Bench, LloydBaselineRunsBesideCvdAndIsPlotted) {
  ASSERT_TRUE(test::cli_available()) << "STREAMCVD_CLI not built";
  const fs::path dir = test::temp_dir("bench_lloyd");
  fs::create_directories(dir / "meshes");
  write_sphere(dir / "meshes", "sphere.ply", 3, 1.0f);
  const fs::path suite = dir / "lloyd.json";
  std::ofstream(suite) << R"({"defaults": {"seed": 3, "threads": 1, "distance_samples": 2000, "render_size": "80x60",
                                          "algorithms": ["cvd", "lloyd"]},
    "cases": [{"name": "sphere_I", "mesh": "meshes/sphere.ply", "N": 100, "metric": "I"},
              {"name": "sphere_IQ", "mesh": "meshes/sphere.ply", "N": 100, "metric": "IQ", "lloyd_max_iterations": 7}]})";
  const json results = run_tiny_suite(suite, dir / "out");
  ASSERT_TRUE(results.contains("records"));
  const json& records = results["records"];
  ASSERT_EQ(records.size(), 4u);
  for (size_t i = 0; i < 4; ++i) {
    const json& r = records[i];
    SCOPED_TRACE(r.dump().substr(0, 400));
    ASSERT_EQ(r["status"], "ok");
    EXPECT_EQ(r["algorithm"], i % 2 == 0 ? "cvd" : "lloyd");
    EXPECT_EQ(r["metric"], i < 2 ? "I" : "IQ");
    EXPECT_EQ(r["output"]["vertices"], 100);
    EXPECT_TRUE(r["output"]["closed_manifold"].get<bool>());
    ASSERT_GT(r["energy_per_loop"].size(), 0u);
    EXPECT_EQ(r["energy_per_loop"].size(), r["seconds_per_loop"].size());
    const auto& t = r["seconds_per_loop"];
    for (size_t k = 1; k < t.size(); ++k) EXPECT_GE(t[k].get<double>(), t[k - 1].get<double>()) << "time is cumulative";
  }
  EXPECT_EQ(records[1]["report"]["clustering"]["constrained_loops"], 0);
  for (size_t i = 0; i < 4; ++i)
    EXPECT_EQ(records[i]["energy_per_loop"].size(),
              records[i]["report"]["clustering"]["unconstrained_loops"].get<size_t>() +
                  records[i]["report"]["clustering"]["constrained_loops"].get<size_t>());
  EXPECT_LE(records[3]["report"]["clustering"]["unconstrained_loops"].get<int>(), 7);
  // Paper §VII: Algorithm 1 ends at least as low as Lloyd (1% slack for a different local minimum).
  for (size_t i : {0, 2})
    EXPECT_GE(records[i + 1]["clustering_energy"].get<double>(), 0.99 * records[i]["clustering_energy"].get<double>()) << i;
  for (const char* name : {"sphere_I_energy.svg", "sphere_IQ_energy.svg"}) {
    const std::string svg = test::slurp((dir / "out" / "plots" / name).string());
    size_t lines = 0;
    for (size_t at = svg.find("<polyline"); at != std::string::npos; at = svg.find("<polyline", at + 1)) ++lines;
    EXPECT_EQ(lines, 2u) << name;
    EXPECT_NE(svg.find("stroke-dasharray"), std::string::npos) << name << ": the Lloyd curve is dashed";
  }
  fs::remove_all(dir);
}

TEST(Bench, BadSuitesAreRejectedNamingTheFile) {
  ASSERT_TRUE(test::cli_available()) << "STREAMCVD_CLI not built";
  const fs::path dir = test::temp_dir("bench_bad_suite");
  const std::vector<std::pair<std::string, std::string>> suites = {
      {"syntax.json", "{\"cases\": [ {\"mesh\": \"a.ply\", "},
      {"nocases.json", "{\"cases\": []}"},
      {"metric.json", R"({"cases": [{"mesh": "a.ply", "N": 10, "metric": "K"}]})"},
      {"algorithm.json", R"({"cases": [{"mesh": "a.ply", "N": 10, "algorithms": ["kmeans"]}]})"},
      {"lloyd_aniso.json", R"({"cases": [{"mesh": "a.ply", "N": 10, "metric": "AQ", "algorithms": ["lloyd"]}]})"},
      {"zero.json", R"({"cases": [{"mesh": "a.ply", "N": 0}]})"},
  };
  for (const auto& [name, text] : suites) {
    std::ofstream(dir / name) << text;
    const test::CliResult r = test::run_cli({"bench", (dir / name).string(), "--out", (dir / "out").string()});
    EXPECT_EQ(r.exit_code, 2) << name << ": " << r.describe();
    EXPECT_NE(r.err.find(name), std::string::npos) << r.err;
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace streamcvd
