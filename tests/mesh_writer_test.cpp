// Tests for streaming/io/output_file.h (atomic output, signal cleanup) and write_mesh: exact round
// trips through every format, byte layouts, and failures that must leave no file behind.
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <bit>
#include <csignal>
#include <cstring>
#include <fstream>
#include <sstream>
#include <vector>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/measure/shapes.h"
#include "streamcvd/streaming/io/input_stream.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/io/output_file.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

namespace fs = std::filesystem;

/// Removes a test folder at the end of the test (the outputs run to tens of MB).
struct RemoveOnExit {
  fs::path dir;
  ~RemoveOnExit() {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

std::vector<std::string> entries(const fs::path& dir) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

std::string pattern(size_t n, uint32_t seed) {
  std::string s(n, '\0');
  uint32_t x = seed;
  for (char& c : s) {
    x = x * 1664525u + 1013904223u;
    c = char(x >> 24);
  }
  return s;
}

/// Decompressed (if zstd) content through InputStream.
std::string read_all(const fs::path& p) {
  InputStream in(p.string());
  std::string s, chunk(1 << 16, '\0');
  while (size_t got = in.read(chunk.data(), chunk.size())) s.append(chunk.data(), got);
  return s;
}

/// Runs `body` in a forked child; returns the raw wait status.
template <class Body>
int in_child(Body body) {
  fflush(nullptr);
  pid_t pid = fork();
  if (pid == 0) {
    int code = 99;
    try {
      code = body();
    } catch (...) {
      code = 98;
    }
    _exit(code);
  }
  int status = 0;
  waitpid(pid, &status, 0);
  return status;
}

/// Icosphere renumbered in order of first appearance in the faces (what an STL reader
/// reconstructs), with coordinates perturbed to awkward float32 values: every round trip,
/// STL included, must then reproduce positions and triangles exactly. The STL reader folds
/// -0.0 onto +0.0 when it merges equal coordinates, so -0.0 only appears on request.
MeshBuffers awkward_mesh(int level = 2, bool negative_zero = false) {
  MeshBuffers m = make_icosphere(level, 1.2345678f);
  std::vector<uint32_t> order(m.vertex_count(), UINT32_MAX);
  uint32_t next = 0;
  for (uint32_t& i : m.triangles) {
    if (order[i] == UINT32_MAX) order[i] = next++;
    i = order[i];
  }
  std::vector<float> pos(m.positions.size());
  for (uint32_t v = 0; v < m.vertex_count(); ++v)
    for (int k = 0; k < 3; ++k) pos[3 * order[v] + k] = m.positions[3 * v + k] * (1.0f + 1e-7f * float(v));
  pos[0] = 1e-45f;            // smallest denormal
  pos[4] = -1.17549435e-38f;  // smallest normal
  pos[8] = 3.0e38f;
  pos[9] = negative_zero ? -0.0f : 0.0f;
  pos[10] = 0.1f;
  pos[11] = 16777217.0f;  // rounds to 2^24
  m.positions = std::move(pos);
  return m;
}

void expect_same_mesh(const MeshBuffers& expected, const MeshBuffers& got, const std::string& what) {
  ASSERT_EQ(expected.vertex_count(), got.vertex_count()) << what;
  ASSERT_EQ(expected.face_count(), got.face_count()) << what;
  for (size_t i = 0; i < expected.positions.size(); ++i)
    ASSERT_EQ(std::bit_cast<uint32_t>(expected.positions[i]), std::bit_cast<uint32_t>(got.positions[i]))
        << what << ": coordinate " << i << " " << expected.positions[i] << " vs " << got.positions[i];
  EXPECT_EQ(expected.triangles, got.triangles) << what;
}

// ---- AtomicOutputFile ------------------------------------------------------------------------

// Makes new files named temporaries (the path of file systems without O_TMPFILE) in its scope.
struct NamedTemporaries {
  NamedTemporaries() { set_anonymous_temp_files(false); }
  ~NamedTemporaries() { set_anonymous_temp_files(true); }
};

// The default path: the file being written has no name at all, before commit nothing is in the
// folder, and a process killed by SIGKILL mid-write leaves nothing behind.
TEST(AtomicOutputFile, AnonymousFileIsInvisibleUntilCommitAndSurvivesNoKill) {
  auto dir = test::temp_dir("aof_anonymous");
  RemoveOnExit cleanup{dir};
  {
    AtomicOutputFile out((dir / "out.bin").string());
    EXPECT_TRUE(out.temp_path().empty());
    out.write(pattern(6 << 20, 4));
    EXPECT_TRUE(entries(dir).empty());
    std::string back(16, '\0');
    out.read_back(1000, back.data(), back.size());
    EXPECT_EQ(back, pattern(6 << 20, 4).substr(1000, 16));
    out.commit();
  }
  EXPECT_EQ(entries(dir), std::vector<std::string>{"out.bin"});
  EXPECT_EQ(slurp(dir / "out.bin"), pattern(6 << 20, 4));
  { AtomicOutputFile abandoned((dir / "gone.bin").string()); abandoned.write("x"); }
  EXPECT_EQ(entries(dir), std::vector<std::string>{"out.bin"});
  int status = in_child([&] {
    AtomicOutputFile out((dir / "killed.bin").string());
    out.write(pattern(3 << 20, 5));
    raise(SIGKILL);
    return 4;
  });
  ASSERT_TRUE(WIFSIGNALED(status));
  EXPECT_EQ(entries(dir), std::vector<std::string>{"out.bin"});
}

TEST(AtomicOutputFile, WritesBufferedAndLargeBlocksThenCommits) {
  NamedTemporaries named;  // the fallback path: a named temporary from the start
  auto dir = test::temp_dir("aof_write");
  RemoveOnExit cleanup{dir};
  std::string small = pattern(1000, 1), big = pattern(9 << 20, 2), tail = pattern(5 << 20, 3);
  {
    AtomicOutputFile out((dir / "out.bin").string());
    std::string tmp = fs::path(out.temp_path()).filename().string();
    EXPECT_EQ(tmp.rfind(".out.bin.tmp." + std::to_string(getpid()) + ".", 0), 0u) << tmp;
    EXPECT_TRUE(fs::exists(out.temp_path()));
    out.write(small);
    out.write(big);  // crosses the 4 MiB buffer with data already buffered
    char* p = out.prepare(4);
    std::memcpy(p, "abcd", 4);
    out.advance(4);
    out.write(tail);
    EXPECT_EQ(out.bytes_written(), small.size() + big.size() + 4 + tail.size());
    EXPECT_FALSE(fs::exists(dir / "out.bin"));  // nothing visible before commit
    out.commit();
    EXPECT_TRUE(out.temp_path().empty());
  }
  EXPECT_EQ(entries(dir), std::vector<std::string>{"out.bin"});
  EXPECT_EQ(slurp(dir / "out.bin"), small + big + "abcd" + tail);
}

TEST(AtomicOutputFile, ReplacesAnExistingFile) {
  auto dir = test::temp_dir("aof_replace");
  RemoveOnExit cleanup{dir};
  write_file_atomic((dir / "r.json").string(), "old contents that are longer");
  write_file_atomic((dir / "r.json").string(), "{\"new\": 1}\n");
  EXPECT_EQ(slurp(dir / "r.json"), "{\"new\": 1}\n");
  EXPECT_EQ(entries(dir), std::vector<std::string>{"r.json"});
}

TEST(AtomicOutputFile, CompressedOutputDecompressesToTheSameBytes) {
  auto dir = test::temp_dir("aof_zstd");
  RemoveOnExit cleanup{dir};
  std::string text;
  for (int i = 0; i < 200000; ++i) text += "v " + std::to_string(i) + " 0.5 -1\n";
  std::string noise = pattern(6 << 20, 7);
  {
    AtomicOutputFile out((dir / "a.zst").string(), true, 5);
    EXPECT_TRUE(out.compressed());
    out.write(text);
    out.write(noise);
    out.commit();
  }
  EXPECT_EQ(read_all(dir / "a.zst"), text + noise);
  EXPECT_LT(fs::file_size(dir / "a.zst"), text.size() + noise.size());
}

TEST(AtomicOutputFile, PatchRewritesFlushedAndBufferedBytes) {
  auto dir = test::temp_dir("aof_patch");
  RemoveOnExit cleanup{dir};
  std::string data = pattern(6 << 20, 4) + pattern(100, 5);
  {
    AtomicOutputFile out((dir / "p.bin").string());
    out.write(data.data(), 6 << 20);  // goes straight to the file
    out.write(data.data() + (6 << 20), 100);  // stays in the buffer
    out.patch(10, "HEAD", 4);
    out.patch((6 << 20) - 4, "STRADDLE", 8);
    out.patch(data.size() - 3, "END", 3);
    EXPECT_THROW(out.patch(data.size() - 2, "XYZ", 3), std::logic_error);
    out.commit();
  }
  std::memcpy(data.data() + 10, "HEAD", 4);
  std::memcpy(data.data() + (6 << 20) - 4, "STRADDLE", 8);
  std::memcpy(data.data() + data.size() - 3, "END", 3);
  EXPECT_EQ(slurp(dir / "p.bin"), data);
}

TEST(AtomicOutputFile, MisuseIsALogicError) {
  auto dir = test::temp_dir("aof_misuse");
  RemoveOnExit cleanup{dir};
  AtomicOutputFile z((dir / "z.zst").string(), true);
  z.write("abc");
  EXPECT_THROW(z.patch(0, "x", 1), std::logic_error);
  AtomicOutputFile out((dir / "o.txt").string());
  out.write("abc");
  out.commit();
  EXPECT_THROW(out.write("more"), std::logic_error);
  EXPECT_THROW(out.prepare(1), std::logic_error);
  EXPECT_THROW(out.commit(), std::logic_error);
  EXPECT_EQ(slurp(dir / "o.txt"), "abc");
}

TEST(AtomicOutputFile, DestroyWithoutCommitLeavesNothing) {
  NamedTemporaries named;  // the fallback path: a named temporary from the start
  auto dir = test::temp_dir("aof_abort");
  RemoveOnExit cleanup{dir};
  std::string tmp;
  try {
    AtomicOutputFile out((dir / "half.ply").string());
    tmp = out.temp_path();
    out.write(pattern(5 << 20, 6));
    ASSERT_TRUE(fs::exists(tmp));
    throw std::runtime_error("simulated failure mid-write");
  } catch (const std::runtime_error&) {
  }
  EXPECT_FALSE(tmp.empty());
  EXPECT_FALSE(fs::exists(tmp));
  EXPECT_TRUE(entries(dir).empty());
}

TEST(AtomicOutputFile, MissingFolderThrowsOutputErrorNamingThePath) {
  auto dir = test::temp_dir("aof_missing");
  RemoveOnExit cleanup{dir};
  std::string path = (dir / "no_such_folder" / "x.ply").string();
  try {
    AtomicOutputFile out(path);
    FAIL() << "expected OutputError";
  } catch (const OutputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(path + ": ", 0), 0u) << e.what();
    EXPECT_NE(std::string(e.what()).find("No such file"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(entries(dir).empty());
}

TEST(AtomicOutputFile, FileWhereTheFolderShouldBe) {
  auto dir = test::temp_dir("aof_notdir");
  RemoveOnExit cleanup{dir};
  write_file_atomic((dir / "plain").string(), "x");
  EXPECT_THROW(AtomicOutputFile((dir / "plain" / "x.ply").string()), OutputError);
  EXPECT_EQ(entries(dir), std::vector<std::string>{"plain"});
}

TEST(AtomicOutputFile, PathNamingAFolderIsRefused) {
  auto dir = test::temp_dir("aof_isdir");
  RemoveOnExit cleanup{dir};
  fs::create_directory(dir / "sub");
  EXPECT_THROW(AtomicOutputFile((dir / "sub").string()), OutputError);
  EXPECT_THROW(AtomicOutputFile((dir / "sub/").string()), OutputError);
  EXPECT_EQ(entries(dir), std::vector<std::string>{"sub"});
  EXPECT_TRUE(entries(dir / "sub").empty());
}

TEST(AtomicOutputFile, UnwritableFolderEvenForRoot) {
  // Root ignores permission bits, but nobody can create files in /proc.
  EXPECT_THROW(write_file_atomic("/proc/streamcvd_test_report.json", "{}"), OutputError);
  EXPECT_FALSE(fs::exists("/proc/streamcvd_test_report.json"));
}

TEST(AtomicOutputFile, ReadOnlyFolder) {
  if (geteuid() == 0) GTEST_SKIP() << "running as root: permission bits are not enforced";
  auto dir = test::temp_dir("aof_readonly");
  RemoveOnExit cleanup{dir};
  fs::create_directory(dir / "ro");
  fs::permissions(dir / "ro", fs::perms::owner_read | fs::perms::owner_exec);
  EXPECT_THROW(write_file_atomic((dir / "ro" / "r.json").string(), "{}"), OutputError);
  fs::permissions(dir / "ro", fs::perms::owner_all);
  EXPECT_TRUE(entries(dir / "ro").empty());
}

TEST(AtomicOutputFile, FileSizeLimitIsAnOutputErrorNotSIGXFSZ) {
  auto dir = test::temp_dir("aof_fsize");
  RemoveOnExit cleanup{dir};
  std::string path = (dir / "big.bin").string();
  int status = in_child([&] {
    rlimit lim{64 << 10, 64 << 10};
    if (setrlimit(RLIMIT_FSIZE, &lim) != 0) return 10;
    try {
      AtomicOutputFile out(path);
      std::string data = pattern(1 << 20, 8);
      for (int i = 0; i < 8; ++i) out.write(data);
      out.commit();
    } catch (const OutputError& e) {
      std::string msg = e.what();
      return msg.rfind(path + ": ", 0) == 0 && msg.find("File too large") != std::string::npos ? 0 : 11;
    }
    return 12;
  });
  ASSERT_TRUE(WIFEXITED(status)) << "child killed by signal " << (WIFSIGNALED(status) ? WTERMSIG(status) : 0);
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_TRUE(entries(dir).empty());
}

void expect_signal_removes_temp_file(int sig) {
  NamedTemporaries named;  // an anonymous file needs no cleanup: the named fallback does
  auto dir = test::temp_dir("aof_signal");
  RemoveOnExit cleanup{dir};
  std::string path = (dir / "out.ply").string();
  int status = in_child([&] {
    install_signal_cleanup();
    AtomicOutputFile kept((dir / "other.bin").string());  // two live files, both must go
    AtomicOutputFile out(path);
    out.write(pattern(6 << 20, 9));
    if (!fs::exists(out.temp_path()) || !fs::exists(kept.temp_path())) return 3;
    raise(sig);
    return 4;  // not reached: the default action terminates the process
  });
  ASSERT_TRUE(WIFSIGNALED(status)) << "child exited with " << WEXITSTATUS(status);
  EXPECT_EQ(WTERMSIG(status), sig);
  EXPECT_TRUE(entries(dir).empty());
}

TEST(AtomicOutputFile, SigtermRemovesTemporaryFiles) { expect_signal_removes_temp_file(SIGTERM); }
TEST(AtomicOutputFile, SigintRemovesTemporaryFiles) { expect_signal_removes_temp_file(SIGINT); }

TEST(AtomicOutputFile, CleanupSparesOtherFilesAndCommittedOutput) {
  NamedTemporaries named;  // the fallback path: a named temporary from the start
  auto dir = test::temp_dir("aof_spare");
  RemoveOnExit cleanup{dir};
  write_file_atomic((dir / "done.txt").string(), "kept");
  AtomicOutputFile live((dir / "live.bin").string());
  // A forked child shares the registry but must not delete its parent's files.
  int status = in_child([] {
    remove_temp_files_now();
    return 0;
  });
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_TRUE(fs::exists(live.temp_path()));
  remove_temp_files_now();
  EXPECT_EQ(entries(dir), std::vector<std::string>{"done.txt"});
}

// ---- write_mesh ----------------------------------------------------------------------------

struct FormatCase {
  const char* name;
  bool ascii;
};

class MeshWriterRoundTrip : public ::testing::TestWithParam<FormatCase> {};

TEST_P(MeshWriterRoundTrip, ReadsBackBitExact) {
  auto dir = test::temp_dir("mw_rt");
  RemoveOnExit cleanup{dir};
  for (int level : {1, 5}) {  // level 5: 10242 vertices; plus the parallel path below
    std::string path = (dir / GetParam().name).string();
    MeshBuffers mesh = awkward_mesh(level, path.find(".stl") == std::string::npos);
    WriteOptions options;
    options.ascii = GetParam().ascii;
    options.comment = "round trip\nsecond line";
    write_mesh(path, mesh.view(), options);
    EXPECT_EQ(entries(dir), std::vector<std::string>{GetParam().name});
    expect_same_mesh(mesh, read_mesh(path), path);
  }
}

INSTANTIATE_TEST_SUITE_P(Formats, MeshWriterRoundTrip,
                         ::testing::Values(FormatCase{"m.ply", false}, FormatCase{"m_ascii.ply", true},
                                           FormatCase{"m.obj", false}, FormatCase{"m.off", false},
                                           FormatCase{"m.stl", false}, FormatCase{"m.ply.zst", false},
                                           FormatCase{"m_ascii.ply.zst", true}, FormatCase{"m.obj.zst", false},
                                           FormatCase{"m.OFF.ZST", false}, FormatCase{"m.stl.zst", false}),
                         [](const auto& info) {
                           std::string s = info.param.name;
                           for (char& c : s)
                             if (c == '.') c = '_';
                           return s;
                         });

TEST(MeshWriter, ChainThroughEveryFormatKeepsEveryBit) {
  auto dir = test::temp_dir("mw_chain");
  RemoveOnExit cleanup{dir};
  const MeshBuffers original = awkward_mesh(3);
  MeshBuffers current = original;
  for (const char* name : {"a.ply", "b.obj", "c.off", "d.stl", "e.ply.zst"}) {
    std::string path = (dir / name).string();
    write_mesh(path, current.view());
    current = read_mesh(path);
    expect_same_mesh(original, current, path);
  }
  EXPECT_EQ(entries(dir).size(), 5u);
}

TEST(MeshWriter, LargeMeshGoesThroughTheParallelPipelineInOrder) {
  auto dir = test::temp_dir("mw_large");
  RemoveOnExit cleanup{dir};
  MeshBuffers mesh = make_grid(500, 400, 3.7f, 1.3f);  // 200k vertices, > one 4 MiB block of lines
  for (const char* name : {"g.obj", "g.ply", "g.off.zst"}) {
    write_mesh((dir / name).string(), mesh.view());
    expect_same_mesh(mesh, read_mesh((dir / name).string()), name);
  }
}

TEST(MeshWriter, BinaryPlyLayout) {
  auto dir = test::temp_dir("mw_ply");
  RemoveOnExit cleanup{dir};
  MeshBuffers m;
  m.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0.5f, 0.5f, 2};
  m.triangles = {0, 1, 2, 2, 1, 3};
  WriteOptions options;
  options.comment = "made by a test";
  write_mesh((dir / "t.ply").string(), m.view(), options);
  std::string bytes = slurp(dir / "t.ply");
  const std::string header =
      "ply\nformat binary_little_endian 1.0\ncomment made by a test\nelement vertex 4\n"
      "property float x\nproperty float y\nproperty float z\nelement face 2\n"
      "property list uchar int vertex_indices\nend_header\n";
  ASSERT_EQ(bytes.size(), header.size() + 4 * 12 + 2 * 13);
  EXPECT_EQ(bytes.substr(0, header.size()), header);
  EXPECT_EQ(std::memcmp(bytes.data() + header.size(), m.positions.data(), 48), 0);
  const char* face = bytes.data() + header.size() + 48 + 13;
  uint32_t idx[3];
  std::memcpy(idx, face + 1, 12);
  EXPECT_EQ(face[0], 3);
  EXPECT_EQ(idx[0], 2u);
  EXPECT_EQ(idx[1], 1u);
  EXPECT_EQ(idx[2], 3u);
}

TEST(MeshWriter, AsciiFormatsUseShortestFloatsAndOneBasedObjIndices) {
  auto dir = test::temp_dir("mw_ascii");
  RemoveOnExit cleanup{dir};
  MeshBuffers m;
  m.positions = {0.1f, -2, 1e-45f, 1, 0, 0, 0, 1, 0};
  m.triangles = {0, 1, 2};
  write_mesh((dir / "t.obj").string(), m.view());
  EXPECT_EQ(slurp(dir / "t.obj"), "v 0.1 -2 1e-45\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  write_mesh((dir / "t.off").string(), m.view());
  EXPECT_EQ(slurp(dir / "t.off"), "OFF\n3 1 0\n0.1 -2 1e-45\n1 0 0\n0 1 0\n3 0 1 2\n");
  WriteOptions ascii;
  ascii.ascii = true;
  write_mesh((dir / "t.ply").string(), m.view(), ascii);
  EXPECT_NE(slurp(dir / "t.ply").find("end_header\n0.1 -2 1e-45\n1 0 0\n0 1 0\n3 0 1 2\n"), std::string::npos);
}

TEST(MeshWriter, StlFacetsCarryUnitNormalsAndZeroForDegenerate) {
  auto dir = test::temp_dir("mw_stl");
  RemoveOnExit cleanup{dir};
  MeshBuffers m;
  m.positions = {0, 0, 0, 2, 0, 0, 0, 2, 0, 4, 0, 0};
  m.triangles = {0, 1, 2, 0, 1, 3};  // second face is degenerate (collinear)
  WriteOptions options;
  options.comment = "solid looking comment";
  write_mesh((dir / "t.stl").string(), m.view(), options);
  std::string bytes = slurp(dir / "t.stl");
  ASSERT_EQ(bytes.size(), 84u + 2 * 50);
  EXPECT_NE(bytes.substr(0, 5), "solid");  // would make readers take it for ascii
  uint32_t count;
  std::memcpy(&count, bytes.data() + 80, 4);
  EXPECT_EQ(count, 2u);
  float f0[12], f1[12];
  std::memcpy(f0, bytes.data() + 84, 48);
  std::memcpy(f1, bytes.data() + 134, 48);
  EXPECT_EQ(f0[0], 0.0f);
  EXPECT_EQ(f0[1], 0.0f);
  EXPECT_EQ(f0[2], 1.0f);
  EXPECT_EQ(f0[3 + 3], 2.0f);  // second corner x
  for (int k = 0; k < 3; ++k) EXPECT_EQ(f1[k], 0.0f);
}

/// The vertices a read hands out, even when the read then fails (a point set: "no faces").
struct VertexRecorder final : MeshSink {
  std::vector<float> positions;
  void begin(const MeshHeaderInfo&) override {}
  void vertices(std::span<const float> xyz, std::span<const float>) override {
    positions.insert(positions.end(), xyz.begin(), xyz.end());
  }
  void triangles(std::span<const uint32_t>) override {}
  void end(const ReadStats&) override {}
};

TEST(MeshWriter, PointSetWithoutFacesIsWrittenExceptToStl) {
  auto dir = test::temp_dir("mw_points");
  RemoveOnExit cleanup{dir};
  MeshBuffers m;
  m.positions = {1, 2, 3, 4, 5, 6};
  for (const char* name : {"p.ply", "p.obj", "p.off"}) {
    write_mesh((dir / name).string(), m.view());
    // The readers reject a mesh without faces (useless to every command) after its vertices.
    VertexRecorder back;
    try {
      read_mesh_stream((dir / name).string(), back);
      ADD_FAILURE() << name << " read without error";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("no faces"), std::string::npos) << e.what();
    }
    EXPECT_EQ(back.positions, m.positions) << name;
  }
  EXPECT_THROW(write_mesh((dir / "p.stl").string(), m.view()), OutputError);
  EXPECT_FALSE(fs::exists(dir / "p.stl"));
  EXPECT_EQ(entries(dir).size(), 3u);
}

TEST(MeshWriter, InvalidMeshesAreRefusedBeforeAnyFileExists) {
  auto dir = test::temp_dir("mw_invalid");
  RemoveOnExit cleanup{dir};
  MeshBuffers empty;
  EXPECT_THROW(write_mesh((dir / "e.ply").string(), empty.view()), OutputError);
  MeshBuffers bad_index;
  bad_index.positions = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  bad_index.triangles = {0, 1, 2, 0, 1, 3};
  try {
    write_mesh((dir / "i.obj").string(), bad_index.view());
    FAIL() << "expected invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("face 1 uses vertex 3 of 3"), std::string::npos) << e.what();
  }
  MeshBuffers nan = bad_index;
  nan.triangles = {0, 1, 2};
  nan.positions[4] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_THROW(write_mesh((dir / "n.ply").string(), nan.view()), std::invalid_argument);
  EXPECT_THROW(write_mesh((dir / "x.vrml").string(), nan.view()), OutputError);
  EXPECT_TRUE(entries(dir).empty());
}

TEST(MeshWriter, FailuresLeaveNoFileBehind) {
  auto dir = test::temp_dir("mw_fail");
  RemoveOnExit cleanup{dir};
  MeshBuffers mesh = awkward_mesh(1);
  EXPECT_THROW(write_mesh((dir / "missing" / "m.ply").string(), mesh.view()), OutputError);
  write_file_atomic((dir / "file").string(), "x");
  EXPECT_THROW(write_mesh((dir / "file" / "m.obj").string(), mesh.view()), OutputError);
  fs::create_directory(dir / "m.off");
  EXPECT_THROW(write_mesh((dir / "m.off").string(), mesh.view()), OutputError);
  EXPECT_THROW(write_mesh("/proc/streamcvd_test_mesh.stl", mesh.view()), OutputError);
  EXPECT_EQ(entries(dir), (std::vector<std::string>{"file", "m.off"}));
  EXPECT_TRUE(entries(dir / "m.off").empty());
}

TEST(MeshWriter, FileSizeLimitInTheMiddleOfAMesh) {
  auto dir = test::temp_dir("mw_fsize");
  RemoveOnExit cleanup{dir};
  MeshBuffers mesh = make_grid(300, 300);  // ~2.7 MB as binary PLY: the 32 KiB limit hits mid-way
  for (const char* name : {"g.ply", "g.obj", "g.stl.zst"}) {
    std::string path = (dir / name).string();
    int status = in_child([&] {
      rlimit lim{32 << 10, 32 << 10};
      if (setrlimit(RLIMIT_FSIZE, &lim) != 0) return 10;
      try {
        write_mesh(path, mesh.view());
      } catch (const OutputError& e) {
        return std::string(e.what()).rfind(path + ": ", 0) == 0 ? 0 : 11;
      }
      return 12;
    });
    ASSERT_TRUE(WIFEXITED(status)) << name << ": killed by signal " << WTERMSIG(status);
    EXPECT_EQ(WEXITSTATUS(status), 0) << name;
    EXPECT_TRUE(entries(dir).empty()) << name;
  }
}

}  // namespace
}  // namespace streamcvd
