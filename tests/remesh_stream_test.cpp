// remesh_stream (streaming/remesh_pipeline.h): a mesh streamed from arrays in RAM goes through the
// same temporary store and cleaning as a file input, so its output and report figures are those
// of remesh_path on the same mesh written to a file (what the Python binding's remesh() relies on).
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/remesh_pipeline.h"
#include "streamcvd/streaming/run_reports.h"
#include "streamcvd/streaming/store/store_build.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

TEST(RemeshStream, ArraysGiveTheOutputOfTheSameMeshReadFromAFile) {
  MeshBuffers torus = make_torus(80, 30);
  torus.triangles.insert(torus.triangles.end(), torus.triangles.begin(), torus.triangles.begin() + 9);  // 3 duplicates
  const std::string path = (std::filesystem::path(::testing::TempDir()) / "remesh_stream_torus.ply").string();
  write_mesh(path, torus.view());
  PipelineOptions options;
  options.remesh.clustering = test::metric_i_one_thread();
  options.remesh.vertices = 300;
  const PipelineResult from_file = remesh_path(path, options);
  for (uint32_t block : {1u << 16, 97u}) {
    const PipelineResult streamed = remesh_stream([&](MeshSink& sink) { stream_soup(torus.view(), sink, block); }, "<arrays>", options);
    EXPECT_EQ(streamed.remesh.mesh.positions, from_file.remesh.mesh.positions) << block;
    EXPECT_EQ(streamed.remesh.mesh.triangles, from_file.remesh.mesh.triangles) << block;
    EXPECT_EQ(streamed.input_build.cleaning.duplicate_faces_dropped, 3u);
    EXPECT_EQ(cleaning_json(streamed.input_build), cleaning_json(from_file.input_build));
  }
  std::filesystem::remove(path);
  EXPECT_THROW(remesh_stream([&](MeshSink& sink) { stream_soup(TriangleSoupView{}, sink, 16); }, "<arrays>", options),
               InputError);
}

}  // namespace
}  // namespace streamcvd
