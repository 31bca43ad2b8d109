// Subcommands of the streamcvd CLI. Each add_*_command registers one subcommand on `app`;
// its callback does the work and throws InputError / OutputError on failure, which main()
// turns into a one-line message and an exit code.
#pragma once

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>
#include <string>

namespace streamcvd::cli {

void add_info_command(CLI::App& app);
void add_convert_command(CLI::App& app);
void add_quality_command(CLI::App& app);
void add_ingest_command(CLI::App& app);
void add_remesh_command(CLI::App& app);
void add_generate_command(CLI::App& app);
void add_distance_command(CLI::App& app);  // cmd_measure.cpp
void add_render_command(CLI::App& app);    // cmd_measure.cpp
void add_bench_command(CLI::App& app);     // cmd_bench.cpp
void add_curvature_command(CLI::App& app); // cmd_curvature.cpp

/// Prints `j` indented to stdout.
void print_json(const nlohmann::json& j);
/// Peak resident set size of this process so far, in bytes (from getrusage).
uint64_t peak_rss_bytes();
/// Seconds since an arbitrary fixed point (steady clock).
double now_seconds();

}  // namespace streamcvd::cli
