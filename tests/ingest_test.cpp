// `streamcvd ingest` end to end (issue: out-of-core ingest): standard input, memory limits that
// force the external-memory paths with byte-identical stores, the JSON report, the progress
// line, and faults late in a big input — a truncated face block, an index out of range in the
// last face, a full disk, SIGINT and SIGKILL mid-build — each ending with the right exit code or
// signal, a one-line error naming the file and the position, no valid-looking store and no
// temporary file.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <signal.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/cli_runner.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

namespace fs = std::filesystem;
using test::CliLimits;
using test::CliResult;
using test::run_cli;

// Every array file of two store directories has the same bytes.
void expect_same_store_files(const fs::path& a, const fs::path& b) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(a)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names.size(), test::entries(b).size());
  for (const std::string& n : names) EXPECT_TRUE(test::slurp((a / n).string()) == test::slurp((b / n).string())) << n;
}

// No file in `dir` (recursively) has a temporary name, and it holds no valid store.
// A failed build leaves no store: not even its folder, unless the process was killed (SIGKILL
// runs no cleanup; the files, anonymous, are gone with it, the empty folder stays).
void expect_no_store_no_temporaries(const fs::path& dir, bool killed = false) {
  EXPECT_TRUE(killed || !fs::exists(dir)) << dir << " was left behind";
  if (!fs::exists(dir)) return;
  EXPECT_FALSE(is_store_directory(dir.string())) << dir;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
}

// True once process `pid` has a file open in `dir` (anonymous O_TMPFILE files included).
bool writes_in(pid_t pid, const fs::path& dir) {
  std::error_code ec;
  for (const auto& fd : fs::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec)) {
    const std::string target = fs::read_symlink(fd.path(), ec).string();
    if (!ec && target.rfind(dir.string() + "/", 0) == 0) return true;
  }
  return false;
}

class Ingest : public test::SuiteWithMesh<Ingest> {
 public:
  static constexpr const char* kSuiteName = "ingest_suite";
  /// A 1.5M-face binary PLY torus (~28 MB): long enough to interrupt, small enough for CI.
  static void write_suite_mesh(const std::string& path) { write_mesh(path, make_torus(1000, 750).view()); }
};

TEST_F(Ingest, PipeAndMemoryLimitsGiveByteIdenticalStores) {
  const fs::path a = out_ / "a.store", b = out_ / "b.store", c = out_ / "c.store";
  CliResult r = run_cli({"ingest", *mesh_, a.string(), "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["faces"], 1500000);
  EXPECT_GT(j["memory_limit_bytes"].get<uint64_t>(), 0u);
  EXPECT_GT(j["peak_bytes"].get<uint64_t>(), 0u);
  EXPECT_GT(j["input_bytes"].get<uint64_t>(), 20000000u);
  // From a pipe, as `cat torus.ply | streamcvd ingest - b.store`.
  CliLimits pipe;
  pipe.stdin_path = *mesh_;
  pipe.stdin_pipe = true;
  r = run_cli({"ingest", "-", b.string()}, pipe);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  expect_same_store_files(a, b);
  // A limit small enough for key buckets, many vertex ranges and spilled blocks.
  r = run_cli({"ingest", *mesh_, c.string(), "--memory", "48M", "--json"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const nlohmann::json k = nlohmann::json::parse(r.out);
  EXPECT_GT(k["key_buckets"].get<uint32_t>(), 1u);
  EXPECT_GT(k["vertex_ranges"].get<uint32_t>(), 1u);
  EXPECT_GT(k["spilled_bytes"].get<uint64_t>(), 0u);
  EXPECT_EQ(k["memory_limit_bytes"], 48 << 20);
  expect_same_store_files(a, c);
}

TEST_F(Ingest, MemoryBelowTheMinimumIsRefusedNamingIt) {
  CliResult r = run_cli({"ingest", *mesh_, (out_ / "s").string(), "--memory", "20M"});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  test::expect_one_line_error(r, "");
  EXPECT_NE(r.err.find("at least"), std::string::npos) << r.err;
  expect_no_store_no_temporaries(out_ / "s");
  r = run_cli({"ingest", *mesh_, (out_ / "s").string(), "--memory", "lots"});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
}

// Every command that reads a mesh takes --memory: a soup that does not fit is refused with a
// one-line error naming the limit (exit 2, never an OOM kill); info streams into a temporary
// store in anonymous work files instead, and gives the same figures.
TEST_F(Ingest, CommandsThatReadAMeshHonourTheMemoryLimit) {
  for (const char* command : {"quality", "render", "distance"}) {
    SCOPED_TRACE(command);
    std::vector<std::string> args = {command, *mesh_};
    if (std::string(command) == "distance") args.push_back(*mesh_);
    if (std::string(command) == "render") args.insert(args.end(), {"-o", (out_ / "x.png").string()});
    args.insert(args.end(), {"--memory", "4M"});
    CliResult r = run_cli(args);
    EXPECT_EQ(r.exit_code, 2) << r.describe();
    test::expect_one_line_error(r, *mesh_);
    EXPECT_NE(r.err.find("needs more than --memory "), std::string::npos) << r.err;
  }
  CliResult small = run_cli({"info", *mesh_, "--json", "--memory", "48M", "--work-dir", out_.string()});
  CliResult large = run_cli({"info", *mesh_, "--json"});
  ASSERT_EQ(small.exit_code, 0) << small.describe();
  ASSERT_EQ(large.exit_code, 0) << large.describe();
  EXPECT_EQ(small.out, large.out);
  EXPECT_TRUE(test::entries(out_).empty());  // the work files were anonymous
}

TEST_F(Ingest, ProgressOnlyWhenAsked) {
  // stderr is a file here, not a terminal: no progress line unless --progress always.
  CliResult r = run_cli({"ingest", *mesh_, (out_ / "s").string()});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_EQ(r.err.find('\r'), std::string::npos) << r.err;
  r = run_cli({"ingest", *mesh_, (out_ / "t").string(), "--progress", "always"});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_NE(r.err.find("\ringest: "), std::string::npos) << r.err;
}

TEST_F(Ingest, TruncatedFaceBlockFailsNamingTheByte) {
  const std::string cut = (out_ / "cut.ply").string();
  fs::copy_file(*mesh_, cut);
  fs::resize_file(cut, fs::file_size(cut) * 9 / 10);  // inside the face block, after the vertices
  for (const char* memory : {"1G", "48M"}) {
    const fs::path store = out_ / (std::string("s") + memory);
    CliResult r = run_cli({"ingest", cut, store.string(), "--memory", memory});
    EXPECT_EQ(r.exit_code, 2) << r.describe();
    test::expect_one_line_error(r, cut);
    EXPECT_NE(r.err.find("byte "), std::string::npos) << r.err;
    expect_no_store_no_temporaries(store);
  }
}

TEST_F(Ingest, IndexOutOfRangeInTheLastFaceFailsNamingIt) {
  const std::string bad = (out_ / "bad.ply").string();
  fs::copy_file(*mesh_, bad);
  {  // the last face's last index → 4000000000
    std::fstream f(bad, std::ios::in | std::ios::out | std::ios::binary);
    f.seekp(std::streamoff(fs::file_size(bad) - 4));
    const uint32_t v = 4000000000u;
    f.write(reinterpret_cast<const char*>(&v), 4);
  }
  const fs::path store = out_ / "s";
  CliResult r = run_cli({"ingest", bad, store.string()});
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  test::expect_one_line_error(r, bad);
  EXPECT_NE(r.err.find("1499999"), std::string::npos) << "names the face: " << r.err;
  expect_no_store_no_temporaries(store);
}

TEST_F(Ingest, FullDiskFailsWithExitThreeAndLeavesNothing) {
  CliLimits limits;
  limits.file_size_bytes = 12 << 20;  // positions (9 MB) fit, the face arrays (18 MB) do not
  for (const char* memory : {"1G", "48M"}) {
    const fs::path store = out_ / (std::string("s") + memory);
    CliResult r = run_cli({"ingest", *mesh_, store.string(), "--memory", memory}, limits);
    EXPECT_EQ(r.exit_code, 3) << r.describe();
    test::expect_one_line_error(r, "");
    EXPECT_NE(r.err.find("File too large"), std::string::npos) << r.err;
    expect_no_store_no_temporaries(store);
  }
}

TEST_F(Ingest, SignalsMidBuildLeaveNoStoreAndNoTemporaries) {
  for (int sig : {SIGINT, SIGKILL}) {
    SCOPED_TRACE(sig);
    const fs::path store = out_ / ("s" + std::to_string(sig));
    // Wait until the build writes files (anonymous ones: only its descriptors show them), then
    // signal it in the middle of the build.
    CliResult r = run_cli({"ingest", *mesh_, store.string(), "--memory", "48M"}, {}, [&](pid_t pid) {
      const auto t0 = std::chrono::steady_clock::now();
      while (!writes_in(pid, store) && std::chrono::steady_clock::now() - t0 < std::chrono::seconds(60))
        std::this_thread::sleep_for(std::chrono::microseconds(200));
      ::kill(pid, sig);
    });
    if (r.exit_code == 0) GTEST_SKIP() << "the ingest ended before the signal (machine too fast)";
    EXPECT_EQ(r.signal, sig) << r.describe();
    expect_no_store_no_temporaries(store, sig == SIGKILL);
  }
}

}  // namespace
}  // namespace streamcvd
