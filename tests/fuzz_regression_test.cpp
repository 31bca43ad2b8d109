// Replays every input kept in tests/data/fuzz_regressions/<target>/ through the same code as
// the libFuzzer target that found it (fuzz/fuzz_common.h): each must read, or fail with
// InputError, and never crash, hang or trip a sanitizer. Targets: ply, obj, off, stl (mesh
// readers; first byte = mode, see write_mesh_input) and store (MeshStore::open).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "fuzz/fuzz_common.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

namespace fs = std::filesystem;

std::vector<fs::path> inputs_of(const std::string& target) {
  std::vector<fs::path> files;
  const fs::path dir = fs::path(test::data_path("fuzz_regressions")) / target;
  if (fs::is_directory(dir))
    for (const auto& e : fs::directory_iterator(dir))
      if (e.is_regular_file()) files.push_back(e.path());
  std::sort(files.begin(), files.end());
  return files;
}

std::string bytes_of(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

TEST(FuzzRegressions, EveryKeptInputReadsOrFailsCleanly) {
  size_t replayed = 0;
  for (const std::string target : {"ply", "obj", "off", "stl", "store"}) {
    const std::string extension = std::string(1, '.').append(target);
    for (const fs::path& p : inputs_of(target)) {
      SCOPED_TRACE(p.string());
      const std::string data = bytes_of(p);
      const auto* bytes = reinterpret_cast<const uint8_t*>(data.data());
      // Anything but InputError escaping (or a crash) fails the test.
      EXPECT_NO_THROW({
        if (target == "store") fuzz::run_store_input(bytes, data.size());
        else fuzz::run_mesh_input(bytes, data.size(), extension.c_str());
      });
      ++replayed;
    }
  }
  EXPECT_GT(replayed, 0u) << "tests/data/fuzz_regressions is empty";
}

TEST(FuzzRegressions, ZeroFaceSoupStillBuildsAStore) {
  // ply/zero_faces_adjacency_null_offset.bin found a null offset in the adjacency of a soup
  // without faces. The readers now reject such files ("no faces"), so the soup is built here.
  MeshBuffers soup;
  soup.positions = {0, 0, 0, 1, 0, 0, 1, 1, 0, 0, 1, 5};
  StoreBuildOptions options;
  options.faces_per_chunk = 4;
  MeshStore store = MeshStore::build(soup.view(), options);
  EXPECT_EQ(store.view().vertex_count(), 4u);
  EXPECT_EQ(store.view().face_count(), 0u);
}

}  // namespace
}  // namespace streamcvd
