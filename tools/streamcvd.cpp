// streamcvd command-line tool: parses arguments, runs one subcommand, maps errors to exit codes.
// Exit codes: 0 success, 1 internal error, 2 bad input or usage, 3 output could not be written,
// 4 output written but a check failed, 130/143 interrupted by SIGINT/SIGTERM.
#include <sys/resource.h>

#include <chrono>
#include <cstdio>
#include <iostream>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/output_file.h"
#include "tools/commands.h"

namespace streamcvd::cli {

void print_json(const nlohmann::json& j) { std::cout << j.dump(2) << "\n"; }

uint64_t peak_rss_bytes() {
  rusage usage{};
  getrusage(RUSAGE_SELF, &usage);
  return uint64_t(usage.ru_maxrss) * 1024;
}

double now_seconds() {
  using clock = std::chrono::steady_clock;
  return std::chrono::duration<double>(clock::now().time_since_epoch()).count();
}

}  // namespace streamcvd::cli

int main(int argc, char** argv) {
  using namespace streamcvd;
  CLI::App app{"streamcvd: discrete centroidal Voronoi remeshing of large triangle meshes"};
  app.footer(
      "Exit codes: 0 success; 1 internal error; 2 bad input or usage; 3 output or work file could not be written\n"
      "(disk full, permissions); 4 output written but a guarantee check failed (stderr names it, the report's\n"
      "\"checks\" lists them all); 130/143 interrupted by SIGINT/SIGTERM (no output left behind).");
  app.require_subcommand(1);
  app.set_version_flag("--version", "streamcvd 0.1.0");
  cli::add_info_command(app);
  cli::add_quality_command(app);
  cli::add_convert_command(app);
  cli::add_ingest_command(app);
  cli::add_remesh_command(app);
  cli::add_generate_command(app);
  cli::add_distance_command(app);
  cli::add_render_command(app);
  cli::add_bench_command(app);
  cli::add_curvature_command(app);
  // Every subcommand that writes goes through AtomicOutputFile: on SIGINT/SIGTERM/SIGHUP its
  // temporary files must be removed whichever command runs (not only remesh).
  install_signal_cleanup();
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "streamcvd: error: %s (see --help)\n", e.what());
    return 2;
  } catch (const InputError& e) {
    std::fprintf(stderr, "streamcvd: error: %s\n", e.what());
    return 2;
  } catch (const OutputError& e) {
    std::fprintf(stderr, "streamcvd: error: %s\n", e.what());
    return 3;
  } catch (const CheckFailed& e) {
    std::fprintf(stderr, "streamcvd: check failed: %s\n", e.what());
    return 4;
  } catch (const std::bad_alloc&) {
    std::fprintf(stderr, "streamcvd: error: out of memory\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "streamcvd: internal error: %s\n", e.what());
    return 1;
  }
  return 0;
}
