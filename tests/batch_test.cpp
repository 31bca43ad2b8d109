// Batch and HPC behaviour of the out-of-core remesh (issue 12, item 6), end to end through the
// CLI on a generated 2M-face torus with --memory 48M, so that the file input becomes a temporary
// store in work files and the per-vertex arrays go to work files too: SIGINT, SIGTERM and SIGKILL
// in the ingest and in the clustering leave no output, no work file and no temporary store, and
// the same command then succeeds; a full work folder is exit 3 with a one-line error naming it;
// the progress shows one line per stage only when asked; the JSON report has the per-stage
// times, chunk visits, I/O, memory limit and peak.
#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <signal.h>
#include <sys/stat.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "streamcvd/streaming/store/store.h"
#include "tests/cli_runner.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

namespace fs = std::filesystem;
using test::CliLimits;
using test::CliResult;
using test::entries;
using test::run_cli;

// Work files of `dir` that process `pid` holds (anonymous: descriptors and mappings only).
int work_files_of(pid_t pid, const fs::path& dir) { return test::files_held_under(pid, dir, true); }

// What process `pid` has written to its stderr so far, once that is the runner's file: right
// after the fork it is still the test's own stderr, maybe a pipe whose read would block.
std::string stderr_of(pid_t pid) {
  const std::string fd = "/proc/" + std::to_string(pid) + "/fd/2";
  struct stat st {};
  return ::stat(fd.c_str(), &st) == 0 && S_ISREG(st.st_mode) ? test::slurp(fd) : std::string();
}

class Batch : public test::SuiteWithMesh<Batch> {
 public:
  static constexpr const char* kSuiteName = "batch";
  /// A 1M-vertex, 2M-face torus (~38 MB binary PLY), generated once for the suite: ~10 s of
  /// remesh inside 48M on two cores.
  static void write_suite_mesh(const std::string& path) { test::generate_torus(path, 1000, 1000); }

 protected:
  void SetUp() override {
    SuiteWithMesh::SetUp();
    if (!IsSkipped()) work_ = test::temp_dir("batch_work");
  }
  void TearDown() override {
    SuiteWithMesh::TearDown();
    fs::remove_all(work_);
  }

  /// The out-of-core remesh of `input`, with progress lines the tests wait on.
  std::vector<std::string> remesh_args(const std::string& input) const {
    return {"remesh",   input,           "-o", (out_ / "out.ply").string(), "-n", "10000", "--memory", "48M",
            "--work-dir", work_.string(), "--report", (out_ / "report.json").string(), "--progress", "always", "-q"};
  }

  /// Runs `args` and sends `sig` once stderr shows `stage` and the job holds work files in
  /// work_ (`seen` tells whether both happened before the job ended).
  CliResult run_and_signal_in(const std::vector<std::string>& args, const std::string& stage, int sig, bool& seen) {
    CliLimits limits;
    limits.watchdog_seconds = 120;
    seen = false;
    return run_cli(args, limits, [&](pid_t pid) {
      const auto t0 = std::chrono::steady_clock::now();
      while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(100)) {
        if (stderr_of(pid).find("\rremesh: " + stage) != std::string::npos && work_files_of(pid, work_) > 0) {
          seen = true;
          break;
        }
        if (test::child_ended(pid)) break;  // ended early: the runner reaps it
        std::this_thread::sleep_for(std::chrono::milliseconds(2));
      }
      ::kill(pid, sig);
    });
  }

  fs::path work_;
};

TEST_F(Batch, SignalsInAnOutOfCoreRemeshLeaveNothingAndTheRerunSucceeds) {
  const std::vector<std::string> args = remesh_args(*mesh_);
  struct Case {
    int sig;
    const char* stage;
  };
  // "ingest": the temporary store is being built in work files (the signal follows their first
  // sight by milliseconds, the ingest lasts ~0.5 s); "clustering": the store is mapped and the
  // per-vertex arrays are work files.
  for (const Case c : {Case{SIGKILL, "ingest"}, Case{SIGINT, "clustering"}, Case{SIGTERM, "clustering"},
                       Case{SIGKILL, "clustering"}}) {
    SCOPED_TRACE(std::to_string(c.sig) + " in " + c.stage);
    bool seen = false;
    CliResult r = run_and_signal_in(args, c.stage, c.sig, seen);
    EXPECT_TRUE(seen) << "the stage or the work files never showed\n" << r.describe();
    EXPECT_FALSE(r.timed_out);
    EXPECT_EQ(r.signal, c.sig) << r.describe();
    if (r.exit_code == 0) {  // ended before the signal (a failure above): its output is no leftover
      fs::remove_all(out_);
      fs::create_directories(out_);
      continue;
    }
    if (std::string(c.stage) == "ingest") {
      EXPECT_EQ(r.err.find("\rremesh: items"), std::string::npos) << "the signal came after the ingest";
    }
    EXPECT_TRUE(entries(out_).empty()) << "output, report or temporary left";
    EXPECT_TRUE(entries(work_).empty()) << "work file or temporary store left";
  }
  // The batch system requeues the job: the same command runs from scratch and succeeds.
  CliResult r = run_cli(args);
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  EXPECT_TRUE(fs::exists(out_ / "out.ply"));
  EXPECT_TRUE(entries(work_).empty()) << "work files outlived the job";
  // The run was out of core: its progress counted chunks, its report saw work files.
  EXPECT_NE(r.err.find("\rremesh: clustering loop "), std::string::npos) << r.err;
  EXPECT_NE(r.err.find(" chunks, "), std::string::npos) << r.err;
  const nlohmann::json j = nlohmann::json::parse(test::slurp((out_ / "report.json").string()));
  EXPECT_GT(j["memory"]["work_file_peak_bytes"].get<uint64_t>(), 0u);
  EXPECT_GT(j["memory"]["temporary_store_bytes"].get<uint64_t>(), 0u);
  EXPECT_FALSE(j["memory"]["store_in_ram"].get<bool>());
  EXPECT_EQ(j["memory"]["work_directory"], work_.string());
  EXPECT_EQ(j["memory"]["limit_bytes"], 48 << 20);
  EXPECT_TRUE(j["chunk_visits"]["scheduled"].get<bool>());
  for (const char* stage : {"items", "sampling", "clustering", "dual", "placement", "checks"})
    EXPECT_GT(j["chunk_visits"]["stages"][stage]["visits"].get<uint64_t>(), 0u) << stage;
}

TEST_F(Batch, FullWorkFolderIsExitThreeNamingItAndLeavesNothing) {
  // A store ingested beforehand: its remesh fails at the first work file, not in a store build.
  const fs::path store = *dir_ / "torus.store";
  if (!is_store_directory(store.string())) {
    CliResult r = run_cli({"ingest", *mesh_, store.string()});
    ASSERT_EQ(r.exit_code, 0) << r.describe();
  }
  CliLimits limits;
  limits.file_size_bytes = 2 << 20;  // the existing full-disk stand-in (ingest_test): EFBIG past 2 MiB
  for (const std::string& input : {*mesh_, store.string()}) {
    SCOPED_TRACE(input);
    std::vector<std::string> args = remesh_args(input);
    args.erase(args.end() - 3, args.end() - 1);  // no --progress always: stderr is the error alone
    CliResult r = run_cli(args, limits);
    EXPECT_EQ(r.exit_code, 3) << r.describe();
    test::expect_one_line_error(r, work_.string());
    EXPECT_NE(r.err.find("work file"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("--work-dir"), std::string::npos) << "the error says how to choose another folder: " << r.err;
    EXPECT_TRUE(entries(out_).empty());
    EXPECT_TRUE(entries(work_).empty());
  }
}

TEST_F(Batch, ProgressNamesEachStageOnlyWhenAsked) {
  const std::string small = (out_ / "small.ply").string();
  CliResult r = run_cli({"generate", "torus", "--rings", "120", "--segments", "80", "-o", small});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  const std::string out = (out_ / "o.ply").string(), report = (out_ / "r.json").string();
  // Forced on a file, -q or not (-q silences the summary, not a progress asked for).
  r = run_cli({"remesh", small, "-o", out, "-n", "400", "--progress", "always", "-q", "--report", report});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
  for (const char* stage :
       {"ingest", "items", "sampling", "clustering", "repair", "dual", "placement", "optimize", "checks", "write"}) {
    // Each stage ends with a line of its own: "\rremesh: <stage> ..., 0.1 s\n".
    const size_t at = r.err.find(std::string("\rremesh: ") + stage);
    ASSERT_NE(at, std::string::npos) << stage << ":\n" << r.err;
    const size_t end = r.err.find('\n', at);
    ASSERT_NE(end, std::string::npos) << stage;
    EXPECT_EQ(r.err.compare(end - 2, 2, " s"), 0) << stage << ": " << r.err.substr(at + 1, end - at - 1);
  }
  EXPECT_NE(r.err.find("\rremesh: clustering loop "), std::string::npos) << r.err;
  // A store in RAM: no chunk scheduler, yet the report has the same keys.
  const nlohmann::json j = nlohmann::json::parse(test::slurp(report));
  for (const char* stage : {"load", "store", "items", "sampling", "clustering", "repair", "dual", "placement", "optimize",
                            "checks", "write", "total"})
    EXPECT_TRUE(j["seconds"][stage].is_number()) << stage;
  EXPECT_FALSE(j["chunk_visits"]["scheduled"].get<bool>());
  EXPECT_TRUE(j["chunk_visits"]["stages"].is_object());
  for (const char* key : {"read_bytes", "write_bytes"}) EXPECT_TRUE(j["io"][key].is_number()) << key;
  for (const char* key : {"limit_bytes", "peak_bytes", "work_file_peak_bytes", "temporary_store_bytes"})
    EXPECT_TRUE(j["memory"][key].is_number()) << key;
  EXPECT_GT(j["memory"]["peak_bytes"].get<uint64_t>(), 0u);
  EXPECT_TRUE(j["memory"]["store_in_ram"].get<bool>());

  // Default (auto) on a pipe or file: no progress, with or without the summary; never: none.
  for (const std::vector<std::string>& extra : std::vector<std::vector<std::string>>{{}, {"-q"}, {"--progress", "never"}}) {
    std::vector<std::string> args = {"remesh", small, "-o", out, "-n", "400"};
    args.insert(args.end(), extra.begin(), extra.end());
    r = run_cli(args);
    ASSERT_EQ(r.exit_code, 0) << r.describe();
    EXPECT_EQ(r.err.find('\r'), std::string::npos) << r.err;
    EXPECT_EQ(r.err.find("remesh: items"), std::string::npos) << r.err;
  }
}

}  // namespace
}  // namespace streamcvd
