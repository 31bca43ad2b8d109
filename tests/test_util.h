// Helpers shared by the test suites: data paths, temp dirs, procedural meshes.
#pragma once

#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "streamcvd/core/clustering/clustering.h"
#include "streamcvd/core/mesh/large_array.h"

#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/store/store.h"

namespace streamcvd::test {

/// Path of a bundled mesh under tests/data.
std::string data_path(const std::string& name);
/// Path of a mesh under ../shared/data, or nullopt when that folder is absent.
std::optional<std::string> shared_data_path(const std::string& name);
/// A copy of a LargeArray as a vector (for EXPECT_EQ and the APIs that take vectors).
template <typename T>
std::vector<T> to_vector(const LargeArray<T>& a) {
  return std::vector<T>(a.begin(), a.end());
}
/// Pieces of every cluster by a plain BFS over same-label edges (labels −1 skipped): the
/// reference the chunked connectivity code is checked against. O(V + E).
std::vector<uint32_t> pieces_per_cluster(const MeshView& mesh, std::span<const int32_t> labels, uint32_t K);
/// Metric I with the clustering on one thread: what most suites were calibrated on (the
/// library's defaults are the CLI's, IQ on all cores), reproducible from run to run.
inline ClusteringOptions metric_i_one_thread() {
  ClusteringOptions o;
  o.metric = Metric::I;
  o.loops.threads = 1;
  return o;
}
/// Appends `piece` to `soup`, moved by (dx, dy, dz): a soup of several components.
void append_shifted(MeshBuffers& soup, const MeshBuffers& piece, float dx, float dy, float dz = 0);
/// A fresh empty directory under the system temp dir, unique per call; removed with its contents
/// when the test process exits.
std::filesystem::path temp_dir(const std::string& tag);

/// Expects two stores to hold the same header and the same bytes in every array (positions,
/// triangles, both CSRs, flags, chunks, original ids): the byte-identity tests' comparison.
void expect_same_arrays(const MeshStore& a, const MeshStore& b);

/// A store built in RAM from a soup, and its view (the view points into the store).
struct StoredMesh {
  MeshStore store;
  MeshView view;
  explicit StoredMesh(const MeshBuffers& soup) : store(MeshStore::build(soup.view())), view(store.view()) {}
};

}  // namespace streamcvd::test
