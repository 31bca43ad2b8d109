// The remeshing job from a file or store to an output mesh, in bounded memory (DESIGN.md §3, §7):
// map the store (or stream a file into a temporary store: in RAM when it fits the memory limit,
// else in anonymous work files), subdivide when the budget asks for it (§VI-F, streamed into the
// store builder), remesh with the per-vertex arrays in a WorkSpace (RAM within the limit, else
// mapped work files), check the output.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "streamcvd/core/measure/mesh_stats.h"
#include "streamcvd/core/remesh.h"
#include "streamcvd/streaming/schedule/chunk_scheduler.h"
#include "streamcvd/streaming/store/store.h"

namespace streamcvd {

struct PipelineOptions {
  RemeshOptions remesh;
  int subdivide = -1;  ///< −1 auto (fewer than ~10 input vertices per cluster), 0 none, K levels
  /// Bytes the job may use (0 = unlimited). Decides what stays in RAM (the store of a file
  /// input, the per-vertex arrays) and what goes to work files; never the result.
  uint64_t memory_limit = 0;
  /// Folder of the work files (anonymous: removed whatever ends the job); "" = the folder of a
  /// store input, else TMPDIR (else /tmp).
  std::string work_directory;
  /// A file input's store is written as a named store in the work folder and kept, so that a
  /// rerun can start from it (`remesh STORE`).
  bool keep_work = false;
  /// Progress (core/mesh/progress.h) of the store's opening or build ("open", "ingest" and the
  /// build's own stages), of "subdivide" and of the remesh stages. Empty = none.
  ProgressCallback progress;
  /// Vertex attributes carried to the output as area-weighted cluster means: all the input has
  /// (default), none (a file input's store then keeps none), or those of attribute_names, each of
  /// which the input must have (InputError listing the available ones otherwise).
  ReadOptions::Attributes attributes = ReadOptions::Attributes::All;
  std::vector<std::string> attribute_names;
};

struct InputSummary {
  uint64_t vertices = 0, faces = 0;
  uint64_t components = 0;
  uint64_t boundary_vertices = 0;
  bool closed = false;             ///< no boundary vertex, no non-manifold vertex
  int64_t euler_characteristic = 0;
};

struct PipelineResult {
  RemeshResult remesh;
  /// The attributes carried (names and input types): the columns of remesh.vertex_attributes.
  std::vector<VertexAttribute> attributes;
  InputSummary input;
  /// The build of a file input's store: input_build.topology_checked, then the input's figures
  /// as read (input_topology) and what the cleaning did (cleaning, whose `cleaned` figures are
  /// those of the store remeshed). A store input was cleaned when ingested: unchecked here.
  StoreBuildReport input_build;
  int subdivision_levels = 0;
  uint64_t remeshed_vertices = 0, remeshed_faces = 0;  ///< after subdivision
  double load_seconds = 0, subdivide_seconds = 0, store_seconds = 0;
  double summary_seconds = 0;  ///< input summary, output topology and quality figures
  TopologyStats output_topology;
  QualityStats output_quality;
  uint64_t memory_limit = 0;       ///< the limit planned with
  uint64_t work_ram_bytes = 0;     ///< budget of the per-vertex arrays in RAM
  uint64_t work_file_peak_bytes = 0;  ///< largest total of mapped work files at once
  /// Total bytes of the stores built in anonymous work files (a file input's temporary store,
  /// subdivided levels): a bound on what the work folder held besides the work files.
  uint64_t temporary_store_bytes = 0;
  std::string work_directory;      ///< the folder of the work files
  bool store_in_ram = true;        ///< the (temporary or subdivided) store was built in RAM
  std::string kept_store;          ///< keep_work: the store left in the work folder
  /// Chunk visits per stage and releases, when the remeshed store was mapped from files (a store
  /// in RAM is resident as a whole: no scheduler, empty stages).
  SchedulerReport schedule;
};

/// Summary figures of a store view in O(V) (Euler characteristic from CSR degrees).
InputSummary summarize_input(const MeshView& mesh, uint64_t components);

/// Remeshes a store (subdividing first when asked or needed). Throws InputError when the result
/// has no triangle (all components dropped, or thinner than a cluster).
PipelineResult remesh_store(const MeshStore& store, const PipelineOptions& options);

/// Loads `input` (mesh file, "-", or store directory) and remeshes it. Throws InputError naming
/// `input`, OutputError when a work file cannot be written (disk full).
PipelineResult remesh_path(const std::string& input, const PipelineOptions& options);

/// Same for a mesh that `produce` streams into the sink it is given (arrays in RAM, a reader...):
/// its temporary store is built and cleaned as a file input's. `name` stands for the input in
/// errors. Throws InputError (bad indices, no triangle left...), OutputError (work files).
PipelineResult remesh_stream(const std::function<void(MeshSink&)>& produce, const std::string& name,
                             const PipelineOptions& options);

}  // namespace streamcvd
