// The chunk scheduler (streaming/schedule/chunk_scheduler.h): visits counted per stage, chunks read
// ahead once while resident and released past the budget, scattered-reads brackets, and the
// remesh of a mapped store visited through it identical to the remesh of the same store in RAM;
// the page advice under it (streaming/store/page_advice.h) reading a whole range ahead, and the
// anonymous blocks (core/mesh/anonymous_pages.h) left without huge-page advice, and malloc's
// freed memory kept for reuse.
#include "streamcvd/streaming/schedule/chunk_scheduler.h"

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/mman.h>
#include <sys/resource.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "streamcvd/core/mesh/anonymous_pages.h"
#include "streamcvd/core/remesh.h"
#include "streamcvd/streaming/io/mesh_io.h"
#include "streamcvd/streaming/remesh_pipeline.h"
#include "streamcvd/streaming/store/page_advice.h"
#include "streamcvd/streaming/store/store.h"
#include "tests/test_util.h"

namespace streamcvd {
namespace {

namespace fs = std::filesystem;

struct MappedElephant {
  fs::path dir;
  MeshStore in_ram, mapped;
  MappedElephant() {
    dir = fs::temp_directory_path() / ("streamcvd_scheduler_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    const MeshBuffers elephant = read_mesh(test::data_path("cgal_elephant.off"));
    in_ram = MeshStore::build(elephant.view(), {.faces_per_chunk = 500});
    in_ram.write(dir.string());
    mapped = MeshStore::open(dir.string());
  }
  ~MappedElephant() { fs::remove_all(dir); }
};

const StageVisits* find_stage(const SchedulerReport& r, const std::string& name) {
  for (const StageVisits& s : r.stages)
    if (s.stage == name) return &s;
  return nullptr;
}

TEST(ChunkScheduler, CountsVisitsAndReleasesPastTheBudget) {
  MappedElephant m;
  const MeshView view = m.mapped.view();
  ASSERT_EQ(m.mapped.ram_bytes(), 0u);
  const uint32_t chunks = uint32_t(view.chunks.size());
  ASSERT_GE(chunks, 6u);
  ChunkScheduler roomy(m.mapped, nullptr, ~uint64_t(0));
  ChunkScheduler tight(m.mapped, nullptr, 1);  // any left chunk is past the budget
  // Two passes of one stage, then one of another: a stage's own chunks stay (its rounds come
  // back to them), the next stage releases what the first left, least recent first.
  for (const char* stage : {"first", "first", "second"})
    for (const Chunk& c : view.chunks)
      for (ChunkScheduler* s : {&roomy, &tight}) {
        s->enter(stage, {c.vertex_begin, c.vertex_end}, kReadsNeighbours);
        s->leave(stage, {c.vertex_begin, c.vertex_end});
      }
  const SchedulerReport r = roomy.report(), t = tight.report();
  ASSERT_EQ(r.stages.size(), 2u);
  EXPECT_EQ(r.stages[0].visits, 2u * chunks);
  EXPECT_EQ(r.stages[0].vertices, 2u * view.vertex_count());
  EXPECT_EQ(r.stages[0].chunks_fetched, chunks);  // resident after the first pass
  EXPECT_EQ(r.stages[1].chunks_fetched, 0u);
  EXPECT_EQ(r.chunks_released, 0u);
  EXPECT_EQ(t.stages[0].chunks_fetched, chunks);   // not released within the stage
  // The second stage finds chunk 0 resident, then releases each chunk the first stage left as
  // it leaves its own: chunk i > 0 is gone when it gets there.
  EXPECT_EQ(t.stages[1].chunks_fetched, chunks - 1);
  EXPECT_GE(t.chunks_released, chunks - 1);
  // A range over several chunks holds them all while entered: none is released meanwhile.
  ChunkScheduler nested(m.mapped, nullptr, 1);
  nested.enter("outer", {0, view.vertex_count()}, kReadsAllArrays);
  nested.enter("inner", {view.chunks[1].vertex_begin, view.chunks[1].vertex_end}, kReadsNeighbours);
  nested.leave("inner", {view.chunks[1].vertex_begin, view.chunks[1].vertex_end});
  EXPECT_EQ(nested.report().chunks_released, 0u);
  nested.leave("outer", {0, view.vertex_count()});
  EXPECT_EQ(nested.report().chunks_released, 0u);  // "inner" left nothing: all are the outer's
  nested.enter("later", {0, 1}, kReadsNeighbours);
  nested.leave("later", {0, 1});
  EXPECT_EQ(nested.report().chunks_released, chunks - 1);  // the outer stage's chunks but chunk 0
  EXPECT_EQ(find_stage(nested.report(), "inner")->chunks_fetched, 0u);
}

// The VmFlags of the mapping holding `address` (/proc/self/smaps): "rr" is MADV_RANDOM.
std::string mapping_flags(const void* address) {
  std::ifstream smaps("/proc/self/smaps");
  const auto a = reinterpret_cast<uintptr_t>(address);
  bool inside = false;
  for (std::string line; std::getline(smaps, line);) {
    uintptr_t lo = 0, hi = 0;
    if (std::sscanf(line.c_str(), "%lx-%lx ", &lo, &hi) == 2 && line.find('-') < line.find(' ')) inside = a >= lo && a < hi;
    else if (inside && line.rfind("VmFlags:", 0) == 0) return line;
  }
  return "";
}

// Large anonymous blocks carry no MADV_HUGEPAGE ("hg"): with defrag=madvise each first touch
// of an advised 2 MiB region compacts memory synchronously (dragon -> 20k: up to 1 s of system
// time; the 105M-face ingest inside 2 GiB: 18-24 s instead of 13 s).
TEST(AnonymousPages, LargeBlocksAreNotAdvisedHugePages) {
  const size_t bytes = 4 * kLargeBlockBytes;
  void* block = map_anonymous_pages(bytes);
  ASSERT_NE(block, nullptr);
  static_cast<volatile char*>(block)[0] = 1;
  const std::string flags = mapping_flags(block);
  unmap_anonymous_pages(block, bytes);
  if (flags.empty()) GTEST_SKIP() << "no /proc/self/smaps";
  EXPECT_EQ(flags.find(" hg"), std::string::npos) << flags;
}

// Page faults of this thread so far.
long thread_minor_faults() {
  rusage usage{};
  ::getrusage(RUSAGE_THREAD, &usage);
  return usage.ru_minflt;
}

// With freed heap memory kept, an 8 MiB block freed and allocated again comes back without page
// faults; with none kept (glibc's default thresholds) it is mapped afresh, a fault per page.
TEST(AnonymousPages, KeptHeapMemoryIsReusedWithoutFaults) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__) || !defined(__GLIBC__)
  GTEST_SKIP() << "malloc is not glibc's here";
#endif
  constexpr size_t kBytes = size_t(8) << 20;
  auto touch = [](size_t bytes, int value) {
    char* p = static_cast<char*>(std::malloc(bytes));
    std::memset(p, value, bytes);
    asm volatile("" : : "g"(p) : "memory");  // the block and its writes must happen
    return p;
  };
  auto faults_of_reuse = [&] {
    std::free(touch(kBytes, 1));
    const long before = thread_minor_faults();
    std::free(touch(kBytes, 2));
    return thread_minor_faults() - before;
  };
  keep_freed_heap_memory(size_t(64) << 20);
  const long kept = faults_of_reuse();
  keep_freed_heap_memory(0);
  const long returned = faults_of_reuse();
  EXPECT_LT(kept, 64);
  EXPECT_GT(returned, 1000) << "8 MiB of fresh 4 KiB pages";
}

// Pages of [p, p + bytes) in RAM (mincore), without touching them.
size_t resident_pages(void* p, size_t bytes) {
  const size_t page = size_t(::sysconf(_SC_PAGESIZE));
  std::vector<unsigned char> in_core((bytes + page - 1) / page);
  if (::mincore(p, bytes, in_core.data()) != 0) return 0;
  size_t n = 0;
  for (unsigned char c : in_core) n += c & 1;
  return n;
}

// Inside an InCoreMemory scope a fresh 8 MiB block is all resident before its first touch (one
// mmap call populated it); outside, none of it is. Scopes nest: the inner one's end changes
// nothing.
TEST(AnonymousPages, BlocksArePopulatedInsideAnInCoreScopeOnly) {
  constexpr size_t kBytes = size_t(8) << 20;
  auto resident_when_mapped = [&] {
    void* block = map_anonymous_pages(kBytes);
    const size_t pages = resident_pages(block, kBytes);
    unmap_anonymous_pages(block, kBytes);
    return pages;
  };
  const size_t all = kBytes / size_t(::sysconf(_SC_PAGESIZE));
  EXPECT_EQ(resident_when_mapped(), 0u);
  {
    const InCoreMemory outer(size_t(1) << 30);
    { const InCoreMemory inner(size_t(1) << 30); }
    EXPECT_EQ(resident_when_mapped(), all);
  }
  EXPECT_EQ(resident_when_mapped(), 0u);
}

// Inside a scattered-reads bracket the store is advised random (no read-around on a fault) and
// a visit that reads arrays reads its chunks ahead again, since the kernel may have evicted
// them; a visit that reads none (a sparse clustering round) does not. Nested brackets count.
TEST(ChunkScheduler, ScatteredReadsAdviseRandomAndReadVisitsAheadAgain) {
  MappedElephant m;
  const MeshView view = m.mapped.view();
  const uint32_t chunks = uint32_t(view.chunks.size());
  ChunkScheduler s(m.mapped, nullptr, ~uint64_t(0));
  auto pass = [&](const char* stage, uint8_t arrays) {
    for (const Chunk& c : view.chunks) {
      s.enter(stage, {c.vertex_begin, c.vertex_end}, arrays);
      s.leave(stage, {c.vertex_begin, c.vertex_end});
    }
  };
  const void* lists = view.vertex_vertex.data();
  const bool smaps = !mapping_flags(lists).empty();
  pass("before", kReadsNeighbours);
  if (smaps) EXPECT_EQ(mapping_flags(lists).find(" rr"), std::string::npos);
  s.scattered_reads(true);
  s.scattered_reads(true);
  if (smaps) EXPECT_NE(mapping_flags(lists).find(" rr"), std::string::npos) << mapping_flags(lists);
  pass("dense", kReadsNeighbours);
  pass("sparse", 0);
  s.scattered_reads(false);
  if (smaps) EXPECT_NE(mapping_flags(lists).find(" rr"), std::string::npos);  // the outer bracket holds
  s.scattered_reads(false);
  if (smaps) EXPECT_EQ(mapping_flags(lists).find(" rr"), std::string::npos);
  pass("after", kReadsNeighbours);
  const SchedulerReport r = s.report();
  EXPECT_EQ(find_stage(r, "before")->chunks_fetched, chunks);
  EXPECT_EQ(find_stage(r, "dense")->chunks_refetched, chunks);
  EXPECT_EQ(find_stage(r, "sparse")->chunks_refetched, 0u);
  EXPECT_EQ(find_stage(r, "after")->chunks_refetched, 0u);
  EXPECT_EQ(find_stage(r, "after")->chunks_fetched, 0u);
}

TEST(ChunkScheduler, MappedStoreRemeshesAsInRam) {
  MappedElephant m;
  PipelineOptions o;
  o.remesh.vertices = 1200;
  o.remesh.clustering = test::metric_i_one_thread();
  o.subdivide = 0;
  o.memory_limit = 64ull << 20;  // a resident budget of 64 MiB; the tight case is tested above
  const PipelineResult mapped = remesh_store(m.mapped, o);
  const PipelineResult in_ram = remesh_store(m.in_ram, o);
  ASSERT_GT(mapped.remesh.mesh.triangles.size(), 0u);
  EXPECT_TRUE(mapped.remesh.mesh.positions == in_ram.remesh.mesh.positions);
  EXPECT_TRUE(mapped.remesh.mesh.triangles == in_ram.remesh.mesh.triangles);
  EXPECT_TRUE(in_ram.schedule.stages.empty());  // a store in RAM is resident as a whole
  for (const char* stage : {"items", "sampling", "clustering", "cleaning", "dual", "placement"}) {
    const StageVisits* s = find_stage(mapped.schedule, stage);
    ASSERT_NE(s, nullptr) << stage;
    EXPECT_GT(s->visits, 0u) << stage;
  }
  const StageVisits* items = find_stage(mapped.schedule, "items");
  EXPECT_EQ(items->vertices, m.mapped.view().vertex_count());  // one pass over every vertex
}

// Linux reads at most its read-ahead window per MADV_WILLNEED call: one call over a large range
// left all but its first megabytes to page faults. advise_pages must read the whole range.
TEST(PageAdvice, WillNeedReadsTheWholeRange) {
  const fs::path file = fs::temp_directory_path() / ("streamcvd_advice_" + std::to_string(::getpid()));
  const size_t bytes = size_t(48) << 20, page = size_t(::sysconf(_SC_PAGESIZE));
  {
    const int fd = ::open(file.c_str(), O_CREAT | O_TRUNC | O_WRONLY, 0600);
    ASSERT_GE(fd, 0);
    const std::vector<char> block(1 << 20, 'x');
    for (size_t done = 0; done < bytes; done += block.size()) ASSERT_EQ(::write(fd, block.data(), block.size()), ssize_t(block.size()));
    ::fsync(fd);
    ::posix_fadvise(fd, 0, off_t(bytes), POSIX_FADV_DONTNEED);  // clean pages: dropped from the cache
    ::close(fd);
  }
  const int fd = ::open(file.c_str(), O_RDONLY);
  ASSERT_GE(fd, 0);
  void* data = ::mmap(nullptr, bytes, PROT_READ, MAP_SHARED, fd, 0);
  ::close(fd);
  ASSERT_NE(data, MAP_FAILED);
  std::vector<unsigned char> resident(bytes / page);
  auto resident_pages = [&] {
    ::mincore(data, bytes, resident.data());
    size_t n = 0;
    for (unsigned char r : resident) n += r & 1;
    return n;
  };
  if (resident_pages() > resident.size() / 2) {  // a file system that keeps files in RAM (tmpfs)
    ::munmap(data, bytes);
    fs::remove(file);
    GTEST_SKIP() << "the page cache cannot be dropped here";
  }
  advise_pages(data, bytes, MADV_WILLNEED, PageSpan::Covering);
  size_t n = 0;
  for (int i = 0; i < 200 && (n = resident_pages()) < resident.size(); ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  // Read-ahead is best effort: under memory pressure (CI runs tests side by side) the kernel may
  // skip or evict a piece, so a few pages may be missing. One call over the range reads only the
  // first window (at most a few MiB of the 48), which this bound still tells apart.
  EXPECT_GE(n, resident.size() * 9 / 10);
  ::munmap(data, bytes);
  fs::remove(file);
}

}  // namespace
}  // namespace streamcvd
