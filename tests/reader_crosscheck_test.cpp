// Our readers against OpenMesh's on every bundled mesh and, when ../shared/data exists, on every
// mesh there; and our counts against MANIFEST.tsv.
//
// What is compared, and why not more: OpenMesh builds a halfedge mesh, not a soup, so
//  - it drops faces that repeat a vertex ("Face has equal vertices"), and
//  - it re-adds faces that would make the mesh non-manifold (non-manifold edges, duplicate faces)
//    on fresh copies of their corners, appended after the file's vertices.
// So: the first V OpenMesh vertices must equal ours bit for bit (OpenMesh keeps unreferenced
// vertices, in file order); OpenMesh's faces, in order, must be a subsequence of ours (same
// corners up to rotation: same index, or the same coordinates for an appended copy), and every
// face of ours it skipped must repeat a vertex. TriMesh fan-triangulates polygons as we do.
// STL: OpenMesh merges corners whose coordinates differ by at most FLT_MIN, i.e. also 0 and -0;
// our reader merges exactly identical values, so the counts may differ only when a file has
// both zeros (not the case for the meshes here, so the comparison is exact).
#include <gtest/gtest.h>

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>

#include <bit>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/io/input_stream.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

using OmMesh = OpenMesh::TriMesh_ArrayKernelT<>;

// A decompressed copy of `path` (same name without ".zst") for OpenMesh, which reads no zstd.
std::string plain_copy(const std::string& path) {
  if (!has_zst_extension(path)) return path;
  std::filesystem::path name = std::filesystem::path(path).filename();
  std::string out = (test::temp_dir("crosscheck") / name.replace_extension("")).string();
  InputStream in(path);
  std::ofstream os(out, std::ios::binary);
  std::vector<char> buf(1 << 20);
  while (size_t n = in.read(buf.data(), buf.size())) os.write(buf.data(), std::streamsize(n));
  return out;
}

bool same_bits(float a, float b) { return std::bit_cast<uint32_t>(a) == std::bit_cast<uint32_t>(b); }

void crosscheck(const std::string& path) {
  SCOPED_TRACE(path);
  const MeshBuffers ours = read_mesh(path);
  OmMesh om;
  OpenMesh::IO::Options options;
  omerr().disable();  // one line per non-manifold face otherwise
  const bool ok = OpenMesh::IO::read_mesh(om, plain_copy(path), options);
  omerr().enable();
  ASSERT_TRUE(ok) << "OpenMesh cannot read " << path;

  const uint32_t nv = ours.vertex_count();
  ASSERT_GE(om.n_vertices(), nv);
  for (uint32_t v = 0; v < nv; ++v) {
    const auto& p = om.point(OpenMesh::VertexHandle(int(v)));
    for (int c = 0; c < 3; ++c)
      ASSERT_TRUE(same_bits(p[c], ours.positions[3 * v + c]))
          << "vertex " << v << " coordinate " << c << ": OpenMesh " << p[c] << ", ours " << ours.positions[3 * v + c];
  }
  // Appended copies must hold coordinates of some vertex of ours: checked through the faces.
  auto corner_matches = [&](int om_vertex, uint32_t our_vertex) {
    if (om_vertex < int(nv)) return uint32_t(om_vertex) == our_vertex;
    const auto& p = om.point(OpenMesh::VertexHandle(om_vertex));
    const float* q = &ours.positions[3 * size_t(our_vertex)];
    return same_bits(p[0], q[0]) && same_bits(p[1], q[1]) && same_bits(p[2], q[2]);
  };
  auto same_face = [&](const int (&c)[3], uint64_t f) {
    const uint32_t* t = &ours.triangles[3 * f];
    for (int r = 0; r < 3; ++r)
      if (corner_matches(c[0], t[r]) && corner_matches(c[1], t[(r + 1) % 3]) && corner_matches(c[2], t[(r + 2) % 3]))
        return true;
    return false;
  };
  auto repeats_vertex = [&](uint64_t f) {
    const uint32_t* t = &ours.triangles[3 * f];
    return t[0] == t[1] || t[1] == t[2] || t[0] == t[2];
  };

  uint64_t f = 0, skipped = 0, copied = 0;
  const uint64_t nf = ours.face_count();
  for (const auto& fh : om.faces()) {
    int c[3], k = 0;
    for (const auto& vh : om.fv_range(fh)) {
      if (k < 3) c[k] = vh.idx();
      ++k;
    }
    ASSERT_EQ(k, 3);
    copied += c[0] >= int(nv) || c[1] >= int(nv) || c[2] >= int(nv);
    while (f < nf && !same_face(c, f)) {
      ASSERT_TRUE(repeats_vertex(f)) << "OpenMesh face " << fh.idx() << " (" << c[0] << " " << c[1] << " " << c[2]
                                     << ") does not match our face " << f << " and OpenMesh has no reason to skip ours";
      ++skipped;
      ++f;
    }
    ASSERT_LT(f, nf) << "OpenMesh face " << fh.idx() << " matches none of ours";
    ++f;
  }
  for (; f < nf; ++f, ++skipped) ASSERT_TRUE(repeats_vertex(f)) << "our face " << f << " missing in OpenMesh";
  EXPECT_EQ(om.n_faces() + skipped, nf);
  // Each re-added face brings 3 fresh vertices.
  EXPECT_EQ(om.n_vertices() - nv, 3 * copied);
  std::cout << "  " << std::filesystem::path(path).filename().string() << ": V " << nv << ", F " << nf
            << "; OpenMesh skipped " << skipped << " faces with a repeated vertex, re-added " << copied
            << " non-manifold faces on copied vertices\n";
}

bool is_mesh_file(const std::filesystem::path& p) {
  try {
    format_from_path(p.string());
    return true;
  } catch (const InputError&) {
    return false;
  }
}

TEST(ReaderCrosscheck, BundledMeshesMatchOpenMesh) {
  int checked = 0;
  for (const auto& entry : std::filesystem::directory_iterator(test::data_path("")))
    if (entry.is_regular_file() && is_mesh_file(entry.path())) {
      crosscheck(entry.path().string());
      ++checked;
    }
  EXPECT_GE(checked, 7);  // tests/data/SOURCES.md lists 7 meshes
}

TEST(ReaderCrosscheck, SharedMeshesMatchOpenMesh) {
  auto manifest = test::shared_data_path("MANIFEST.tsv");
  if (!manifest) GTEST_SKIP() << "../shared/data is absent";
  int checked = 0;
  for (const auto& entry : std::filesystem::directory_iterator(std::filesystem::path(*manifest).parent_path()))
    if (entry.is_regular_file() && is_mesh_file(entry.path())) {
      crosscheck(entry.path().string());
      ++checked;
    }
  EXPECT_GE(checked, 1);
}

TEST(ReaderCrosscheck, SharedMeshCountsMatchManifest) {
  auto manifest = test::shared_data_path("MANIFEST.tsv");
  if (!manifest) GTEST_SKIP() << "../shared/data is absent";
  std::ifstream in(*manifest);
  std::string line;
  ASSERT_TRUE(std::getline(in, line));
  std::vector<std::string> columns;
  auto split = [](const std::string& s) {
    std::vector<std::string> out;
    std::stringstream ss(s);
    for (std::string cell; std::getline(ss, cell, '\t');) out.push_back(cell);
    return out;
  };
  columns = split(line);
  auto column = [&](const std::string& name) {
    for (size_t i = 0; i < columns.size(); ++i)
      if (columns[i] == name) return i;
    ADD_FAILURE() << "MANIFEST.tsv has no column " << name;
    return size_t(0);
  };
  const size_t file = column("file"), vertices = column("vertices"), faces = column("faces");
  int rows = 0;
  while (std::getline(in, line)) {
    if (line.empty()) continue;
    auto cells = split(line);
    ASSERT_GT(cells.size(), std::max({file, vertices, faces}));
    auto path = test::shared_data_path(cells[file]);
    ASSERT_TRUE(path) << cells[file] << " listed in MANIFEST.tsv but missing";
    SCOPED_TRACE(*path);
    MeshBuffers m = read_mesh(*path);
    EXPECT_EQ(std::to_string(m.vertex_count()), cells[vertices]);
    EXPECT_EQ(std::to_string(m.face_count()), cells[faces]);
    ++rows;
  }
  EXPECT_GE(rows, 1);
}

}  // namespace
}  // namespace streamcvd
