// AtomicOutputFile's page-cache bypass (write_direct) and split sync/commit. The basic
// write/commit/patch behaviour is covered by the AtomicOutputFile suite in mesh_writer_test.cpp.
#include "streamcvd/streaming/io/output_file.h"

#include <gtest/gtest.h>
#include <unistd.h>
#include <zstd.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <vector>

#include "streamcvd/core/mesh/default_init_vector.h"
#include "streamcvd/core/mesh/errors.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

namespace fs = std::filesystem;

std::vector<char> slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

// Deterministic non-repeating bytes, so a misplaced block would show.
std::vector<char> pattern(size_t n, uint32_t seed) {
  std::vector<char> v(n);
  uint32_t x = seed * 2654435761u + 1;
  for (char& c : v) {
    x = x * 1664525u + 1013904223u;
    c = char(x >> 24);
  }
  return v;
}

size_t temp_files_in(const fs::path& dir) {
  size_t n = 0;
  for (const auto& e : fs::directory_iterator(dir)) n += e.path().filename().string().find(".tmp.") != std::string::npos;
  return n;
}

// Sizes around the 2 MiB bounce block and the 4 KiB alignment, from an unaligned source pointer,
// mixed with ordinary writes before (misaligned offset: fallback) and after (offset past a
// truncated padded tail).
TEST(AtomicOutputFileDirect, LargeUnalignedBlocksMixedWithBufferedWrites) {
  const fs::path dir = test::temp_dir("direct_mixed");
  for (size_t big : {size_t(1) << 20, (size_t(2) << 20) + 4097, (size_t(5) << 20) + 5}) {
    SCOPED_TRACE(big);
    const std::vector<char> a = pattern(big + 1, 1), b = pattern(big, 2), c = pattern(100, 3);
    std::vector<char> expect;
    {
      AtomicOutputFile out((dir / "d.bin").string());
      out.write_direct(a.data() + 1, big);  // offset 0, source not 4 KiB aligned
      expect.insert(expect.end(), a.begin() + 1, a.end());
      out.write(c.data(), c.size());  // after a padded, truncated tail
      expect.insert(expect.end(), c.begin(), c.end());
      out.write_direct(b.data(), b.size());  // misaligned offset: buffered fallback
      expect.insert(expect.end(), b.begin(), b.end());
      out.write_direct(c.data(), 10);  // small: buffered
      expect.insert(expect.end(), c.begin(), c.begin() + 10);
      EXPECT_EQ(out.bytes_written(), expect.size());
      out.commit();
    }
    EXPECT_EQ(fs::file_size(dir / "d.bin"), expect.size());
    EXPECT_TRUE(slurp(dir / "d.bin") == expect);
  }
  EXPECT_EQ(temp_files_in(dir), 0u);
  fs::remove_all(dir);
}

// A page-aligned source (the store's big arrays) is written in place, block by block, except
// the tail, which is padded in the bounce buffer and truncated: same bytes either way.
TEST(AtomicOutputFileDirect, AlignedSourceWrittenInPlace) {
  const fs::path dir = test::temp_dir("direct_aligned");
  for (size_t big : {size_t(4) << 20, (size_t(4) << 20) + 4096, (size_t(3) << 20) + 123}) {
    SCOPED_TRACE(big);
    const std::vector<char> a = pattern(big, 5);
    DefaultInitVector<char> aligned(big);  // ≥ 1 MiB: page-aligned
    ASSERT_EQ(reinterpret_cast<uintptr_t>(aligned.data()) % 4096, 0u);
    std::memcpy(aligned.data(), a.data(), big);
    {
      AtomicOutputFile out((dir / "a.bin").string());
      out.write_direct(aligned.data(), big);
      out.write_direct(aligned.data(), big);  // offset past a padded tail when big % 4096 != 0
      EXPECT_EQ(out.bytes_written(), 2 * big);
      out.commit();
    }
    std::vector<char> expect = a;
    expect.insert(expect.end(), a.begin(), a.end());
    EXPECT_TRUE(slurp(dir / "a.bin") == expect);
  }
  EXPECT_EQ(temp_files_in(dir), 0u);
  fs::remove_all(dir);
}

// tmpfs may refuse O_DIRECT: the bytes must arrive either way.
TEST(AtomicOutputFileDirect, WorksWhereODirectMayBeRefused) {
  if (!fs::is_directory("/dev/shm")) GTEST_SKIP() << "no /dev/shm";
  const fs::path dir = fs::path("/dev/shm") / ("streamcvd_direct_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::vector<char> a = pattern((size_t(3) << 20) + 77, 4);
  {
    AtomicOutputFile out((dir / "s.bin").string());
    out.write_direct(a.data(), a.size());
    out.commit();
  }
  EXPECT_TRUE(slurp(dir / "s.bin") == a);
  fs::remove_all(dir);
}

TEST(AtomicOutputFileDirect, SyncThenCommitAndPatchAfterSync) {
  const fs::path dir = test::temp_dir("direct_sync");
  const std::vector<char> a = pattern(size_t(2) << 20, 5);
  {
    AtomicOutputFile out((dir / "s.bin").string());
    out.write_direct(a.data(), a.size());
    out.sync();
    EXPECT_FALSE(fs::exists(dir / "s.bin"));  // synced, not yet renamed
    EXPECT_EQ(temp_files_in(dir), 0u);        // and anonymous until commit (O_TMPFILE)
    out.patch(5, "XY", 2);  // after sync: commit must still write it out
    out.commit(/*sync_folder=*/false);
  }
  sync_directory(dir.string());
  std::vector<char> expect = a;
  expect[5] = 'X', expect[6] = 'Y';
  EXPECT_TRUE(slurp(dir / "s.bin") == expect);
  {  // abandoned after sync: nothing left behind
    AtomicOutputFile out((dir / "gone.bin").string());
    out.write_direct(a.data(), a.size());
    out.sync();
  }
  EXPECT_FALSE(fs::exists(dir / "gone.bin"));
  EXPECT_EQ(temp_files_in(dir), 0u);
  {  // compressed: sync, then commit still completes the frame
    AtomicOutputFile out((dir / "z.zst").string(), true);
    out.write_direct(a.data(), a.size());
    out.sync();
    out.commit();
  }
  const std::vector<char> z = slurp(dir / "z.zst");
  std::vector<char> back(a.size() + 1);
  const size_t got = ZSTD_decompress(back.data(), back.size(), z.data(), z.size());
  ASSERT_FALSE(ZSTD_isError(got)) << ZSTD_getErrorName(got);
  back.resize(got);
  EXPECT_TRUE(back == a);
  EXPECT_THROW(sync_directory((dir / "missing").string()), OutputError);
  fs::remove_all(dir);
}

// ---- CreatedDirectory: the store folder a failed job must not leave -------------------------

TEST(CreatedDirectory, MadeLevelsGoAgainUnlessKept) {
  const fs::path root = test::temp_dir("created_dir");
  { CreatedDirectory made((root / "a" / "b" / "c").string()); EXPECT_TRUE(fs::is_directory(root / "a" / "b" / "c")); }
  EXPECT_FALSE(fs::exists(root / "a"));  // every level it made, innermost first
  {
    CreatedDirectory made((root / "kept" / "store").string());
    made.keep();
  }
  EXPECT_TRUE(fs::is_directory(root / "kept" / "store"));
  fs::remove_all(root);
}

TEST(CreatedDirectory, LeavesExistingAndNonEmptyFoldersAlone) {
  const fs::path root = test::temp_dir("created_dir_existing");
  fs::create_directories(root / "old");
  { CreatedDirectory existing((root / "old").string()); }
  EXPECT_TRUE(fs::is_directory(root / "old"));
  {
    CreatedDirectory made((root / "new" / "store").string());
    std::ofstream(root / "new" / "file") << "x";  // written beside the store: "new" is not empty
  }
  EXPECT_FALSE(fs::exists(root / "new" / "store"));
  EXPECT_TRUE(fs::exists(root / "new" / "file"));
  fs::remove_all(root);
}

TEST(CreatedDirectory, AFileInTheWayIsAnOutputError) {
  const fs::path root = test::temp_dir("created_dir_file");
  std::ofstream(root / "plain") << "x";
  EXPECT_THROW(CreatedDirectory((root / "plain").string()), OutputError);
  EXPECT_THROW(CreatedDirectory((root / "plain" / "store").string()), OutputError);
  EXPECT_TRUE(fs::is_regular_file(root / "plain"));
  fs::remove_all(root);
}

}  // namespace
}  // namespace streamcvd
