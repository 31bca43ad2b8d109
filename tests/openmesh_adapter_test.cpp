#include <gtest/gtest.h>

#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/openmesh_adapter.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

TEST(OpenMeshAdapter, SoupRoundTripKeepsCountsAndCoordinates) {
  MeshBuffers sphere = make_icosphere(3);
  OpenMeshTriMesh mesh = openmesh_from_soup(sphere.view());
  ASSERT_EQ(mesh.n_vertices(), sphere.vertex_count());
  ASSERT_EQ(mesh.n_faces(), sphere.face_count());
  MeshBuffers back = soup_from_openmesh(mesh);
  EXPECT_EQ(back.positions, sphere.positions);
  EXPECT_EQ(back.triangles, sphere.triangles);
}

TEST(OpenMeshAdapter, RemeshesTriMeshToClosedMeshWithNVertices) {
  MeshBuffers sphere = make_icosphere(4);
  OpenMeshTriMesh input = openmesh_from_soup(sphere.view());
  PipelineOptions options;
  options.remesh.clustering = test::metric_i_one_thread();
  options.remesh.vertices = 300;
  PipelineResult result;
  OpenMeshTriMesh output = remesh_openmesh(input, options, &result);
  EXPECT_EQ(output.n_vertices(), 300u);
  EXPECT_EQ(output.n_faces(), result.remesh.mesh.face_count());
  EXPECT_EQ(output.n_faces(), 2u * 300u - 4u);  // closed genus 0: F = 2V - 4
  for (auto h : output.halfedges()) EXPECT_FALSE(output.is_boundary(h));
}

}  // namespace
}  // namespace streamcvd
