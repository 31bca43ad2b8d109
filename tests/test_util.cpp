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

}  // namespace streamcvd::test
