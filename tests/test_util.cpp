#include "tests/test_util.h"

#include <array>
#include <atomic>
#include <cmath>
#include <map>
#include <unistd.h>

namespace streamcvd::test {

std::string data_path(const std::string& name) { return std::string(STREAMCVD_TEST_DATA) + "/" + name; }

std::optional<std::string> shared_data_path(const std::string& name) {
  std::string p = std::string(STREAMCVD_SHARED_DATA) + "/" + name;
  if (std::filesystem::exists(p)) return p;
  return std::nullopt;
}

std::filesystem::path temp_dir(const std::string& tag) {
  static std::atomic<int> counter{0};
  auto p = std::filesystem::temp_directory_path() /
           ("streamcvd_test_" + tag + "_" + std::to_string(::getpid()) + "_" + std::to_string(counter++));
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
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

}  // namespace streamcvd::test
