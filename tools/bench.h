// Reports of `streamcvd bench`: the Markdown results table and hand-written SVG plots, all built
// from the per-run JSON records (see cmd_bench.cpp for the record fields).
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace streamcvd::cli {

/// Markdown table, one row per record: case, algorithm, N, output V/F, load and algorithm
/// seconds, peak MB, Qmin, Qav, % angles < 30°, Hausdorff and mean distance (% of the input's
/// bbox diagonal). Skipped and failed runs get a row saying so.
std::string bench_markdown(const nlohmann::json& records);

/// SVG: clustering energy against time, one polyline per CVD or Lloyd run (dashed), log-log;
/// energies divided by the lowest final energy of the runs of the same case (so the curves of a
/// case compare, paper Fig. 9), time cumulative over the passes.
std::string energy_svg(const nlohmann::json& records);

/// SVG: histograms of triangle quality Q (20 bins over [0,1]) and of the smallest angle (12 bins
/// of 5° over [0,60°]) of the records of one case, as percentages, bars side by side per
/// algorithm. `rows` is a JSON array of records with a "quality" object.
std::string histogram_svg(const std::string& title, const nlohmann::json& rows);

}  // namespace streamcvd::cli
