#include "tests/test_util.h"

#include <gtest/gtest.h>
#include <cstring>

#include <array>
#include <atomic>
#include <cmath>
#include <map>
#include <mutex>
#include <vector>
#include <unistd.h>

namespace streamcvd::test {

std::string data_path(const std::string& name) { return std::string(STREAMCVD_TEST_DATA) + "/" + name; }

std::optional<std::string> shared_data_path(const std::string& name) {
  std::string p = std::string(STREAMCVD_SHARED_DATA) + "/" + name;
  if (std::filesystem::exists(p)) return p;
  return std::nullopt;
}

void append_shifted(MeshBuffers& soup, const MeshBuffers& piece, float dx, float dy, float dz) {
  const uint32_t offset = soup.vertex_count();
  for (size_t i = 0; i < piece.positions.size(); i += 3)
    soup.positions.insert(soup.positions.end(), {piece.positions[i] + dx, piece.positions[i + 1] + dy, piece.positions[i + 2] + dz});
  for (uint32_t i : piece.triangles) soup.triangles.push_back(i + offset);
}

namespace {

// The directories temp_dir made, removed when the test process exits: a suite run leaves
// nothing in TMPDIR (a crashed test leaves its own, named by its pid).
struct TempDirs {
  std::mutex mutex;
  std::vector<std::filesystem::path> made;
  ~TempDirs() {
    std::error_code ignored;
    for (const auto& p : made) std::filesystem::remove_all(p, ignored);
  }
};

TempDirs& temp_dirs() {
  static TempDirs dirs;
  return dirs;
}

}  // namespace

std::filesystem::path temp_dir(const std::string& tag) {
  static std::atomic<int> counter{0};
  auto p = std::filesystem::temp_directory_path() /
           ("streamcvd_test_" + tag + "_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  TempDirs& dirs = temp_dirs();
  std::lock_guard lock(dirs.mutex);
  dirs.made.push_back(p);
  return p;
}

std::vector<uint32_t> pieces_per_cluster(const MeshView& mesh, std::span<const int32_t> labels, uint32_t K) {
  std::vector<uint8_t> seen(mesh.vertex_count(), 0);
  std::vector<uint32_t> pieces(K, 0);
  std::vector<uint32_t> stack;
  for (uint32_t s = 0; s < mesh.vertex_count(); ++s) {
    if (labels[s] < 0 || seen[s]) continue;
    ++pieces[labels[s]];
    stack.assign(1, s);
    seen[s] = 1;
    while (!stack.empty()) {
      const uint32_t u = stack.back();
      stack.pop_back();
      for (uint32_t n : mesh.neighbours(u))
        if (!seen[n] && labels[n] == labels[s]) seen[n] = 1, stack.push_back(n);
    }
  }
  return pieces;
}

void expect_same_arrays(const MeshStore& a, const MeshStore& b) {
  ASSERT_EQ(std::memcmp(&a.header(), &b.header(), sizeof(StoreHeader)), 0);
  const MeshView x = a.view(), y = b.view();
  auto same = [](auto s, auto t) {
    return s.size() == t.size() && (s.empty() || std::memcmp(s.data(), t.data(), s.size_bytes()) == 0);
  };
  EXPECT_TRUE(same(x.positions, y.positions));
  EXPECT_TRUE(same(x.triangles, y.triangles));
  EXPECT_TRUE(same(x.vertex_vertex_offsets, y.vertex_vertex_offsets));
  EXPECT_TRUE(same(x.vertex_vertex, y.vertex_vertex));
  EXPECT_TRUE(same(x.vertex_face_offsets, y.vertex_face_offsets));
  EXPECT_TRUE(same(x.vertex_face, y.vertex_face));
  EXPECT_TRUE(same(x.vertex_flags, y.vertex_flags));
  EXPECT_TRUE(same(x.chunks, y.chunks));
  EXPECT_TRUE(same(a.original_vertex_ids(), b.original_vertex_ids()));
}

}  // namespace streamcvd::test
