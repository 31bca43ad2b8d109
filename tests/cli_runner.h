// Runs the streamcvd CLI (STREAMCVD_CLI) in a child process for the end-to-end suites: stdin
// closed, stdout/stderr captured, optional resource limits, and a watchdog that kills a child
// that hangs (reported as timed_out instead of blocking the suite). Header-only because the
// test build compiles only *_test.cpp and test_util.cpp.
#pragma once

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <thread>
#include <vector>

#include "tests/test_util.h"

namespace streamcvd::test {

#if defined(__SANITIZE_ADDRESS__)
constexpr bool kAddressSanitizer = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
constexpr bool kAddressSanitizer = true;
#else
constexpr bool kAddressSanitizer = false;
#endif
#else
constexpr bool kAddressSanitizer = false;
#endif

struct CliLimits {
  /// RLIMIT_AS in MiB (0 = none). Under AddressSanitizer (which reserves terabytes of shadow
  /// memory) ASan's own max_allocation_size_mb is set instead: either way an allocation sized
  /// from an absurd header count makes the run fail.
  uint64_t address_space_mb = 0;
  uint64_t file_size_bytes = 0;  ///< RLIMIT_FSIZE (0 = none): writes past it fail with EFBIG
  double watchdog_seconds = 120; ///< SIGKILL after this long (a hang, not a timing test)
  std::string stdin_path;        ///< file fed to stdin ("" = stdin closed)
  bool stdin_pipe = false;       ///< feed stdin_path through a pipe (as `cat f | streamcvd ...`)
};

struct CliResult {
  int exit_code = -1;      ///< exit status, or -1 when killed by a signal
  int signal = 0;          ///< terminating signal, 0 when it exited
  bool timed_out = false;  ///< killed by the watchdog
  pid_t pid = 0;
  std::string out, err;
  std::string describe() const {
    return "exit " + std::to_string(exit_code) + (signal ? " signal " + std::to_string(signal) : "") +
           (timed_out ? " (watchdog)" : "") + "\nstderr: " + err;
  }
};

inline bool cli_available() { return std::string(STREAMCVD_CLI).size() > 0; }

inline std::string slurp(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

/// Starts the CLI with `args`; `on_start(pid)` runs in the parent right after the fork (for
/// tests that signal the child). Returns when the child ended or the watchdog killed it.
template <class OnStart>
CliResult run_cli(const std::vector<std::string>& args, const CliLimits& limits, OnStart on_start) {
  static int counter = 0;
  const std::filesystem::path dir = temp_dir("cli_run" + std::to_string(counter++));
  const std::string out_path = (dir / "stdout").string(), err_path = (dir / "stderr").string();
  std::vector<std::string> argv_s = {STREAMCVD_CLI};
  argv_s.insert(argv_s.end(), args.begin(), args.end());
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::string asan = "ASAN_OPTIONS=";
  if (const char* old = std::getenv("ASAN_OPTIONS")) asan += std::string(old) + ":";
  asan += "max_allocation_size_mb=" + std::to_string(limits.address_space_mb ? limits.address_space_mb : 1 << 20);

  int pipe_fds[2] = {-1, -1};
  if (limits.stdin_pipe && ::pipe2(pipe_fds, O_CLOEXEC) != 0) pipe_fds[0] = pipe_fds[1] = -1;
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(0);  // no stdin at all unless asked: nothing may wait for input
    if (pipe_fds[0] >= 0) {
      ::dup2(pipe_fds[0], 0);
    } else if (!limits.stdin_path.empty()) {
      const int in = ::open(limits.stdin_path.c_str(), O_RDONLY);
      if (in < 0) ::_exit(121);
      if (in != 0) ::dup2(in, 0), ::close(in);
    }
    int o = ::open(out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    int e = ::open(err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (o < 0 || e < 0) ::_exit(120);
    ::dup2(o, 1);
    ::dup2(e, 2);
    if (limits.address_space_mb && !kAddressSanitizer) {
      rlimit r{limits.address_space_mb << 20, limits.address_space_mb << 20};
      ::setrlimit(RLIMIT_AS, &r);
    }
    if (kAddressSanitizer) ::putenv(asan.data());
    if (limits.file_size_bytes) {
      rlimit r{limits.file_size_bytes, limits.file_size_bytes};
      ::setrlimit(RLIMIT_FSIZE, &r);
    }
    ::signal(SIGINT, SIG_DFL);
    ::signal(SIGTERM, SIG_DFL);
    ::execv(argv[0], argv.data());
    ::_exit(127);
  }
  std::thread feeder;
  if (pipe_fds[0] >= 0) {
    ::close(pipe_fds[0]);
    ::signal(SIGPIPE, SIG_IGN);  // a reader that stops early gives EPIPE, not the test's death
    feeder = std::thread([fd = pipe_fds[1], path = limits.stdin_path] {
      std::ifstream in(path, std::ios::binary);
      std::vector<char> buf(1 << 16);
      while (in.read(buf.data(), std::streamsize(buf.size())) || in.gcount() > 0) {
        const char* p = buf.data();
        size_t n = size_t(in.gcount());
        while (n > 0) {
          const ssize_t w = ::write(fd, p, n);
          if (w <= 0) {  // the reader stopped (exited or failed): stop feeding
            ::close(fd);
            return;
          }
          p += w, n -= size_t(w);
        }
      }
      ::close(fd);
    });
  }
  on_start(pid);
  CliResult r;
  r.pid = pid;
  int status = 0;
  const auto t0 = std::chrono::steady_clock::now();
  for (;;) {
    pid_t w = ::waitpid(pid, &status, WNOHANG);
    if (w == pid) break;
    if (std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() > limits.watchdog_seconds) {
      ::kill(pid, SIGKILL);
      ::waitpid(pid, &status, 0);
      r.timed_out = true;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  if (feeder.joinable()) feeder.join();
  if (WIFEXITED(status)) r.exit_code = WEXITSTATUS(status);
  if (WIFSIGNALED(status)) r.signal = WTERMSIG(status);
  r.out = slurp(out_path);
  r.err = slurp(err_path);
  std::error_code ec;
  std::filesystem::remove_all(dir, ec);
  return r;
}

/// True once the child `pid` of run_cli has ended, leaving it to be reaped by the runner (for
/// an on_start that waits for something the child may end without doing). waitid, because
/// waitpid rejects WNOWAIT with EINVAL.
inline bool child_ended(pid_t pid) {
  siginfo_t info{};
  return ::waitid(P_PID, id_t(pid), &info, WEXITED | WNOHANG | WNOWAIT) == 0 && info.si_pid == pid;
}

inline CliResult run_cli(const std::vector<std::string>& args, const CliLimits& limits = {}) {
  return run_cli(args, limits, [](pid_t) {});
}

/// Names of every entry of `dir`, hidden files (temporaries) included.
inline std::vector<std::string> entries(const std::filesystem::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : std::filesystem::directory_iterator(dir)) names.push_back(e.path().filename().string());
  return names;
}

/// The CLI's error contract: one line on stderr, naming `path` when given.
inline void expect_one_line_error(const CliResult& r, const std::string& path) {
  ASSERT_FALSE(r.err.empty());
  EXPECT_EQ(r.err.back(), '\n') << r.err;
  EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
  EXPECT_EQ(r.err.rfind("streamcvd: error: ", 0), 0u) << r.err;
  if (!path.empty()) {
    EXPECT_NE(r.err.find(path), std::string::npos) << "stderr does not name " << path << ": " << r.err;
  }
}

/// Files under `dir` that process `pid` holds: open descriptors and, with `mappings`, mapped
/// files. Anonymous work and output files (O_TMPFILE, unlinked) show only there (Linux /proc).
inline int files_held_under(pid_t pid, const std::filesystem::path& dir, bool mappings) {
  const std::string prefix = dir.string() + "/";
  int n = 0;
  std::error_code ec;
  for (const auto& fd : std::filesystem::directory_iterator("/proc/" + std::to_string(pid) + "/fd", ec)) {
    const std::string target = std::filesystem::read_symlink(fd.path(), ec).string();
    n += !ec && target.rfind(prefix, 0) == 0;
  }
  if (mappings) {
    std::ifstream maps("/proc/" + std::to_string(pid) + "/maps");
    for (std::string line; std::getline(maps, line);) n += line.find(" " + prefix) != std::string::npos;
  }
  return n;
}

/// Writes a torus of rings × segments vertices to `path` with the CLI's generator (binary PLY).
inline void generate_torus(const std::string& path, int rings, int segments) {
  CliResult r = run_cli({"generate", "torus", "--rings", std::to_string(rings), "--segments", std::to_string(segments), "-o", path});
  ASSERT_EQ(r.exit_code, 0) << r.describe();
}

/// Base of the CLI suites that share one big generated mesh file: Derived::write_suite_mesh
/// writes it once per suite (SetUpTestSuite) into a temp folder removed after the suite, and
/// every test gets a fresh out_ folder, or is skipped when the CLI is not built.
/// Derived names its folders with kSuiteName.
template <class Derived>
class SuiteWithMesh : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!cli_available()) return;
    dir_ = new std::filesystem::path(temp_dir(Derived::kSuiteName));
    mesh_ = new std::string((*dir_ / "torus.ply").string());
    Derived::write_suite_mesh(*mesh_);
  }
  static void TearDownTestSuite() {
    if (dir_) std::filesystem::remove_all(*dir_);
    delete dir_;
    delete mesh_;
    dir_ = nullptr;
    mesh_ = nullptr;
  }
  void SetUp() override {
    if (!cli_available()) GTEST_SKIP() << "STREAMCVD_CLI not built";
    out_ = temp_dir(std::string(Derived::kSuiteName) + "_out");
  }
  void TearDown() override { std::filesystem::remove_all(out_); }

  static inline std::filesystem::path* dir_ = nullptr;  ///< the suite's folder
  static inline std::string* mesh_ = nullptr;           ///< the suite's mesh file
  std::filesystem::path out_;                           ///< this test's output folder
};

}  // namespace streamcvd::test
