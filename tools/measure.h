// Helpers shared by the measuring subcommands (`distance`, `render`, `bench`): loading a mesh
// file or store as a soup, Metro distances with errors that name the files (their JSON:
// streaming/run_reports.h), and parsing of "az,el" / "WxH" arguments.
#pragma once

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "streamcvd/core/mesh/mesh_buffers.h"
#include "streamcvd/core/measure/raster.h"
#include "streamcvd/core/measure/surface_distance.h"
#include "streamcvd/streaming/store/store.h"

namespace streamcvd::cli {

/// A mesh file read into RAM, or a store directory mapped: either way a soup view.
struct LoadedMesh {
  std::optional<MeshBuffers> buffers;
  std::optional<MeshStore> store;
  TriangleSoupView view() const { return buffers ? buffers->view() : store->view().soup(); }
};

/// Reads a mesh file (its soup in RAM, in file order, refused past --memory) or maps a store
/// directory (every chunk validated). Throws InputError naming the path.
LoadedMesh load_mesh_or_store(const std::string& path, uint64_t memory_limit = 0);

/// surface_distance(a, b) with A the reference, errors rephrased to name the file they concern:
/// "<file>: surface distance: <problem>". Throws InputError.
DistanceReport measure_distance(const std::string& a_name, const TriangleSoupView& a, const std::string& b_name,
                                const TriangleSoupView& b, uint64_t samples_per_side, uint64_t seed);

/// Parses "az,el" (degrees) into options.azimuth_deg / elevation_deg. Throws InputError.
void parse_view(const std::string& text, RenderOptions& options);
/// Parses "WxH" (pixels, each 1..16384) into options.width / height. Throws InputError.
void parse_size(const std::string& text, RenderOptions& options);

}  // namespace streamcvd::cli
