// The JSON records of a job: what `streamcvd remesh --report`, `info --json`, `quality --json`
// and `distance --json` print, built once here for the CLI (tools/) and the Python binding
// (python/), so that both hand out the same keys and values.
#pragma once

#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/mesh/progress.h"
#include "streamcvd/core/measure/surface_distance.h"
#include "streamcvd/streaming/schedule/memory_budget.h"
#include "streamcvd/streaming/remesh_pipeline.h"
#include "streamcvd/streaming/store/store.h"
#include "streamcvd/streaming/store/store_build.h"

namespace streamcvd {

/// Counts, bounding box and topology figures of `info --json` (without "file").
nlohmann::json topology_json(const TopologyStats& s);
/// Q, angle, valence and edge-length figures of `quality --json` and of the remesh report.
nlohmann::json quality_json(const QualityStats& q);
/// What the store build's topology cleaning did (streaming/store/store_clean.h): the input's defects as
/// read, what was dropped and cut, the figures of the cleaned mesh.
nlohmann::json cleaning_json(const StoreBuildReport& build);
/// {"a_to_b": {max, mean, rms, samples, *_relative}, "b_to_a": ..., "hausdorff",
/// "hausdorff_relative", "two_sided_rms", "two_sided_rms_relative", "diagonal"}; relative
/// figures are fractions of A's bbox diagonal.
nlohmann::json distance_json(const DistanceReport& d);

/// What `streamcvd info` looks at, for the mesh `produce` streams: build.input_topology holds the
/// input's figures as read and, when build.topology_checked, build.cleaning what the cleaning did.
/// Streams into a temporary store under `options` (bounded memory). Throws InputError.
StoreBuildReport inspect_mesh(const std::function<void(MeshSink&)>& produce, const StoreBuildOptions& options,
                              const ProgressCallback& progress = {});
/// Same for a mesh file ("-": standard input) or a store directory (mapped, every chunk checked).
StoreBuildReport inspect_mesh(const std::string& path, const StoreBuildOptions& options,
                              const ProgressCallback& progress = {});
/// The record of `streamcvd info --json`: topology_json of the input as read, "file": `name`, and
/// "cleaning" when the build checked it.
nlohmann::json info_json(const std::string& name, const StoreBuildReport& build);

/// The record of `streamcvd ingest --json`: `store` built from `input` in `total_seconds`.
nlohmann::json ingest_report(const std::string& input, const std::string& directory, const MeshStore& store,
                             const StoreBuildReport& report, double total_seconds);

/// Disk bytes read and written per stage (the remesh report's io.stages): fed every progress
/// report, it reads the counters when a stage's final report arrives, so a stage gets what
/// happened since the previous one ended. Out of core this tells which stage pays for the paging.
class StageIoLog {
 public:
  /// Call from the job's progress callback (one caller at a time).
  void see(const StageProgress& p);
  /// Starts the counting (before the job).
  void start();
  /// {stage: {read_bytes, write_bytes}} in the order the stages ended.
  nlohmann::json json() const;

 private:
  IoCounters last_;
  std::vector<std::pair<std::string, IoCounters>> stages_;
};

/// The output guarantees of a remesh run (closed manifold in → closed, oriented manifold out;
/// components, holes, genus, exact N). Sets `all_ok`.
nlohmann::json guarantee_checks(const PipelineResult& r, uint32_t requested, bool& all_ok);
/// The failed guarantees of `checks`, with their figures, on one line ("" when none failed).
std::string failed_checks(const nlohmann::json& checks);

/// What the remesh report needs besides the result and the options: names and times of the job.
struct RemeshJobRecord {
  std::string input, output;    ///< as given (output: its format decides the attributes written)
  double write_seconds = 0, total_seconds = 0;
  IoCounters io_start;          ///< read_io_counters() before the job
  const StageIoLog* stage_io = nullptr;  ///< io.stages (empty when null)
};

/// The whole report of `streamcvd remesh --report` for `r`, run with `options`: input, cleaning,
/// options, seconds, clustering, quality pass, strips, components, output, attributes, quality,
/// checks, memory, io, chunk visits. Reads the peak memory and I/O counters when called.
nlohmann::json remesh_report(const PipelineResult& r, const PipelineOptions& options, const RemeshJobRecord& job);

/// The comment write_mesh puts in the header of a remesh output: "streamcvd remesh -n N --seed S".
std::string remesh_output_comment(const PipelineOptions& options);

}  // namespace streamcvd
