// SIGINT / SIGTERM / SIGKILL during CLI runs on a big mesh (issue 7): a signal stops the run
// at once, even inside the CPU-bound clustering loop, and leaves neither a partial output nor a
// temporary file; after SIGKILL (no cleanup possible) nothing is left either, because the file
// being written is anonymous (O_TMPFILE) until it is complete and renamed into place.
#include <gtest/gtest.h>
#include <signal.h>

#include <chrono>
#include <string>
#include <thread>
#include <vector>

#include "tests/cli_runner.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

namespace fs = std::filesystem;
using test::CliLimits;
using test::CliResult;
using test::entries;
using test::run_cli;

// True once process `pid` writes a file in `dir`: a named temporary there, or (the usual case)
// an anonymous O_TMPFILE file, which only shows as an open descriptor "/dir/#123 (deleted)".
bool has_temp_file(pid_t pid, const fs::path& dir) {
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename().string().find(".tmp.") != std::string::npos) return true;
  return test::files_held_under(pid, dir, false) > 0;
}

class Interrupt : public test::SuiteWithMesh<Interrupt> {
 public:
  static constexpr const char* kSuiteName = "interrupt";
  /// A 2.25M-vertex torus (4.5M faces, ~85 MB binary PLY), generated once for the suite.
  static void write_suite_mesh(const std::string& path) { test::generate_torus(path, 1500, 1500); }

 protected:

  /// Runs `args`, sends `sig` `delay` after the start; the watchdog (a SIGKILL, which the test
  /// then sees instead of `sig`) allows 120 s in all, far less than the uninterrupted job.
  CliResult run_and_signal(const std::vector<std::string>& args, int sig, std::chrono::milliseconds delay) {
    CliLimits limits;
    limits.watchdog_seconds = 120;
    return run_cli(args, limits, [&](pid_t pid) {
      std::this_thread::sleep_for(delay);
      ::kill(pid, sig);
    });
  }

  /// Runs `args` and sends `sig` as soon as a temporary output file appears in out_.
  CliResult run_and_signal_during_write(const std::vector<std::string>& args, int sig, bool& seen_temp) {
    CliLimits limits;
    limits.watchdog_seconds = 120;
    seen_temp = false;
    return run_cli(args, limits, [&](pid_t pid) {
      const auto t0 = std::chrono::steady_clock::now();
      while (std::chrono::steady_clock::now() - t0 < std::chrono::seconds(100)) {
        if (has_temp_file(pid, out_)) {
          seen_temp = true;
          break;
        }
        if (test::child_ended(pid)) break;  // ended early: leave it to the runner
        std::this_thread::sleep_for(std::chrono::microseconds(200));
      }
      ::kill(pid, sig);
    });
  }

  std::vector<std::string> remesh_args() const {
    return {"remesh", *mesh_, "-o", (out_ / "out.ply").string(), "-n", "300000", "-q"};
  }

};

TEST_F(Interrupt, SigintEarlyInRemeshStopsAtOnce) {
  CliResult r = run_and_signal(remesh_args(), SIGINT, std::chrono::milliseconds(500));
  EXPECT_FALSE(r.timed_out);
  EXPECT_EQ(r.signal, SIGINT) << r.describe();
  EXPECT_TRUE(entries(out_).empty());
}

TEST_F(Interrupt, SigtermDuringClusteringStopsAtOnce) {
  // After a few seconds the input is read and the store built: the run is in the CPU-bound loops.
  CliResult r = run_and_signal(remesh_args(), SIGTERM, std::chrono::milliseconds(4000));
  EXPECT_FALSE(r.timed_out);
  EXPECT_EQ(r.signal, SIGTERM) << r.describe();
  EXPECT_TRUE(entries(out_).empty());
}

TEST_F(Interrupt, SignalDuringWriteRemovesTheTemporaryFile) {
  for (int sig : {SIGINT, SIGTERM}) {
    SCOPED_TRACE(sig);
    bool seen_temp = false;
    // Compressing 85 MB at a high level keeps the temporary file open for a while.
    CliResult r = run_and_signal_during_write({"convert", *mesh_, (out_ / "out.ply.zst").string()}, sig, seen_temp);
    EXPECT_TRUE(seen_temp) << "the temporary file never appeared";
    EXPECT_FALSE(r.timed_out);
    EXPECT_EQ(r.signal, sig) << r.describe();
    EXPECT_TRUE(entries(out_).empty()) << "temporary or partial file left";
  }
}

TEST_F(Interrupt, SigkillNeverLeavesTheFinalName) {
  CliResult r = run_and_signal(remesh_args(), SIGKILL, std::chrono::milliseconds(1500));
  EXPECT_EQ(r.signal, SIGKILL) << r.describe();
  EXPECT_FALSE(fs::exists(out_ / "out.ply"));

  bool seen_temp = false;
  r = run_and_signal_during_write({"convert", *mesh_, (out_ / "out.ply").string()}, SIGKILL, seen_temp);
  EXPECT_EQ(r.signal, SIGKILL) << r.describe();
  EXPECT_FALSE(fs::exists(out_ / "out.ply")) << "a partial file under the final name";
  // The file being written was anonymous (O_TMPFILE): even SIGKILL leaves nothing behind.
  EXPECT_TRUE(entries(out_).empty());
}

}  // namespace
}  // namespace streamcvd
