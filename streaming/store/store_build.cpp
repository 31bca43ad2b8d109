// The store builder as a MeshSink: pass 1 (spill) runs inside the reader's callbacks, the later
// passes once their input is complete (streaming/store/store_build.h lists them).
#include "streamcvd/streaming/store/store_build.h"

#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <limits>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/schedule/memory_budget.h"
#include "streamcvd/streaming/store/store_build_state.h"

namespace streamcvd {

using namespace store_build;

namespace store_build {

void PositionSample::add(uint64_t first_id, std::span<const float> block) {
  const uint64_t n = block.size() / 3;
  for (uint64_t i = 0; i < n; ++i) {
    if (((first_id + i) & (stride - 1)) != 0) continue;  // stride is a power of two
    xyz.insert(xyz.end(), &block[3 * i], &block[3 * i] + 3);
    if (xyz.size() / 3 < kCapacity) continue;
    // Full: sample j has id j·stride; keep the even j (ids that are multiples of 2·stride).
    size_t kept = 0;
    for (size_t j = 0; j < xyz.size() / 3; j += 2, ++kept) std::copy_n(&xyz[3 * j], 3, &xyz[3 * kept]);
    xyz.resize(3 * kept);
    stride *= 2;
  }
}

ChunkCutter::ChunkCutter(uint64_t vertices, uint64_t faces, uint64_t target)
    : vertices_(vertices), faces_(faces), chunks_(std::max<uint64_t>(1, (faces + target / 2) / target)) {}

void ChunkCutter::visit(uint64_t e, uint64_t first_face, uint64_t previous_first_face, std::vector<uint64_t>& cuts) {
  // Goals k·F/C in order; the first vertex whose first owned face reaches a goal is its
  // lower bound (vertices are visited in order), then the nearer of it and its predecessor.
  while (k_ < chunks_) {
    const uint64_t goal = (k_ * faces_ + chunks_ / 2) / chunks_;
    if (first_face < goal) return;
    uint64_t end = e;
    if (e > 0 && goal - previous_first_face < first_face - goal) --end;
    ++k_;
    if (end <= begin_ || end >= vertices_) continue;  // a giant fan swallowed this cut
    cuts.push_back(end);
    begin_ = end;
  }
}

}  // namespace store_build

// ---- State ------------------------------------------------------------------------------------

StoreBuilder::State::State(StoreOutputs& o, const StoreBuildOptions& opt,
                           std::function<void(const BuildProgress&)> p)
    : outputs(o), options(opt), progress(std::move(p)), started(std::chrono::steady_clock::now()) {
  if (options.faces_per_chunk == 0) throw InputError("store build: faces_per_chunk must be positive");
  if (options.memory_limit > 0) {
    if (options.memory_limit < kFixedOverhead + kMinWork)
      throw InputError("--memory " + format_memory_size(options.memory_limit) + " is too small: the store build needs at least " +
                       format_memory_size(kFixedOverhead + kMinWork) + " plus 4 bytes per vertex");
    usable = options.memory_limit - kFixedOverhead;
    const uint64_t streams = uint64_t(kStreamCount) * stream_blocks_in_flight(options.memory_limit) << 20;
    usable = usable > streams + kMinWork ? usable - streams : kMinWork;
  }
  work_dir = options.work_directory;
  if (work_dir.empty()) {
    const char* tmp = std::getenv("TMPDIR");
    work_dir = tmp && *tmp ? tmp : "/tmp";
  }
  for (int k = 0; k < 3; ++k) lo[k] = std::numeric_limits<float>::infinity(), hi[k] = -lo[k];
  result.report.memory_limit = options.memory_limit;
  trace = std::getenv("STREAMCVD_BUILD_TRACE") != nullptr;
}

void StoreBuilder::State::note_memory(const char* stage) const {
  static std::string last;
  static uint64_t peak = 0;
  const uint64_t now = resident_anonymous_bytes();
  if (last != stage) {
    if (!last.empty())
      std::fprintf(stderr, "memory: %s peak %s (t = %.2f s)\n", last.c_str(), format_memory_size(peak).c_str(),
                   seconds_since(started));
    last = stage;
    peak = 0;
  }
  peak = std::max(peak, now);
}

void StoreBuilder::State::require(uint64_t need, const char* what) const {
  if (need <= usable) return;
  throw InputError("--memory " + format_memory_size(options.memory_limit) + " is too small for " + what +
                   ": it needs at least " + format_memory_size(need + (options.memory_limit - usable)));
}

void StoreBuilder::State::finish_result() {
  StoreBuildReport& r = result.report;
  r.input_bytes = read.bytes;
  r.input_vertices = options.original_vertex_count ? options.original_vertex_count : input_vertices;
  r.vertices = result.vertex_count;
  r.faces = result.face_count;
  r.chunks = result.chunks.size();
  r.polygons_split = read.polygons_split;
  r.strip_triangles_dropped = read.strip_triangles_dropped;
  for (int k = 0; k < 3; ++k) {
    const bool empty = !(lo[k] <= hi[k]);  // no finite coordinate on this axis
    result.bbox_min[k] = empty ? 0 : lo[k];
    result.bbox_max[k] = empty ? 0 : hi[k];
  }
}

// ---- The sink ---------------------------------------------------------------------------------

StoreBuilder::StoreBuilder(StoreOutputs& outputs, const StoreBuildOptions& options,
                           std::function<void(const BuildProgress&)> progress)
    : state_(std::make_unique<State>(outputs, options, std::move(progress))) {}

StoreBuilder::~StoreBuilder() = default;

StoreBuildResult& StoreBuilder::result() { return state_->result; }

void StoreBuilder::begin(const MeshHeaderInfo& header) {
  State& s = *state_;
  s.header = header;
  s.attribute_count = uint32_t(header.attributes.size());
  s.merge_corners = header.corners_by_value;
  s.result.attributes = header.attributes;
  const uint32_t record = 12 + 4 * s.attribute_count;
  if (header.has_bounds && !s.merge_corners && header.vertices != MeshHeaderInfo::kUnknown) {
    // The reader measured the vertices first: they go to the key buckets as they arrive.
    float box_lo[3], box_hi[3];
    for (int k = 0; k < 3; ++k) {
      const bool empty = !(header.bounds_lo[k] <= header.bounds_hi[k]);
      box_lo[k] = empty ? 0 : header.bounds_lo[k];
      box_hi[k] = empty ? 0 : header.bounds_hi[k];
    }
    s.plan_order(header.vertices, box_lo, box_hi, header.position_sample, header.sample_stride);
    return;
  }
  // Half the memory at most: pass 2 needs room for its buckets while these drain.
  s.vertex_records = std::make_unique<SpillBuckets>(s.work_dir, 1, record, s.usable / 2);
}

void StoreBuilder::vertices(std::span<const float> xyz, std::span<const float> attributes) {
  State& s = *state_;
  const uint64_t n = xyz.size() / 3;
  if (s.input_vertices + n > std::numeric_limits<uint32_t>::max())
    throw InputError("store build: more than 2^32-1 vertices" +
                     std::string(s.merge_corners ? " (STL corners before merging)" : ""));
  for (uint64_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) {
      const float c = xyz[3 * i + k];
      if (std::isfinite(c)) s.lo[k] = std::min(s.lo[k], c), s.hi[k] = std::max(s.hi[k], c);
    }
  // Records of xyz + attributes, to the key buckets (bounds known) or to the pass-1 spill.
  std::span<const std::byte> records = std::as_bytes(xyz);
  if (s.attribute_count > 0) {
    const uint32_t a = s.attribute_count;
    s.record_scratch.resize(n * (3 + a));
    for (uint64_t i = 0; i < n; ++i) {
      std::copy_n(&xyz[3 * i], 3, &s.record_scratch[(3 + a) * i]);
      std::copy_n(&attributes[a * i], a, &s.record_scratch[(3 + a) * i + 3]);
    }
    records = std::as_bytes(std::span<const float>(s.record_scratch));
  }
  if (s.key_records) {
    s.distribute_batched(records, false);
  } else {
    s.sample.add(s.input_vertices, xyz);
    s.vertex_records->append(0, records.data(), n);
  }
  s.input_vertices += n;
}

void StoreBuilder::triangles(std::span<const uint32_t> corners) {
  State& s = *state_;
  if (s.merge_corners) {  // STL faces are implicit: (3t, 3t+1, 3t+2)
    s.input_faces += corners.size() / 3;
    return;
  }
  // PLY and OFF announce their vertices and give them first: the order can be computed now and
  // the faces remapped as they stream by, instead of being spilled and read again.
  if (!s.ordered && !s.raw_faces && s.header.vertices != MeshHeaderInfo::kUnknown &&
      s.input_vertices == s.header.vertices) {
    s.order_vertices();
    s.begin_faces();
  }
  if (s.ordered) {
    s.add_faces(corners);
    return;
  }
  if (!s.raw_faces) {
    const uint64_t held = s.usable == ~uint64_t(0) ? 0 : s.input_vertices * (12 + 4 * s.attribute_count);
    s.raw_faces = std::make_unique<SpillBuckets>(s.work_dir, 1, 12, s.free_after(held));
  }
  s.raw_faces->append(0, corners.data(), corners.size() / 3);
  s.input_faces += corners.size() / 3;
}

void StoreBuilder::end(const ReadStats& stats) {
  State& s = *state_;
  s.read = stats;
  // Until now: reading and spilling, plus the passes that ran inside the callbacks.
  s.result.report.read_seconds =
      seconds_since(s.started) - s.result.report.order_seconds - s.result.report.faces_seconds;
  if (!s.ordered) {
    s.order_vertices();
    s.begin_faces();
    if (s.merge_corners) {
      std::vector<uint32_t> block;
      for (uint64_t t = 0; t < s.input_faces;) {
        const uint64_t n = std::min<uint64_t>(s.input_faces - t, 1 << 16);
        block.resize(3 * n);
        for (uint64_t i = 0; i < 3 * n; ++i) block[i] = uint32_t(3 * t + i);
        s.add_faces(block);
        t += n;
      }
    } else if (s.raw_faces) {
      s.raw_faces->drain(0, [&](std::span<const std::byte> bytes) {
        s.add_faces({reinterpret_cast<const uint32_t*>(bytes.data()), bytes.size() / 4});
      });
      s.raw_faces.reset();
    }
  }
  s.finish_faces();
  s.build_ranges();
  s.finish_result();
}

uint32_t stream_blocks_in_flight(uint64_t memory_limit) {
  // An eighth of the limit for all streams together, 1 to 64 blocks (1 MiB) each: a range's
  // output (~92 bytes per vertex, ~90 MB for a range of 2^20 vertices) then mostly fits.
  if (memory_limit == 0) return 64;
  return uint32_t(std::clamp<uint64_t>(memory_limit / 8 / kStreamCount / (uint64_t(1) << 20), 1, 64));
}

// ---- In-RAM soups -------------------------------------------------------------------------------

void stream_soup(const TriangleSoupView& soup, MeshSink& sink, uint32_t block) {
  if (soup.positions.size() % 3 != 0)
    throw InputError("store build: positions hold " + std::to_string(soup.positions.size()) +
                     " floats, not a multiple of 3");
  if (soup.triangles.size() % 3 != 0)
    throw InputError("store build: triangles hold " + std::to_string(soup.triangles.size()) +
                     " indices, not a multiple of 3");
  MeshHeaderInfo header;
  header.vertices = soup.positions.size() / 3;
  header.faces = soup.triangles.size() / 3;
  sink.begin(header);
  for (size_t i = 0; i < soup.positions.size(); i += 3 * size_t(block))
    sink.vertices(soup.positions.subspan(i, std::min<size_t>(3 * size_t(block), soup.positions.size() - i)), {});
  for (size_t i = 0; i < soup.triangles.size(); i += 3 * size_t(block))
    sink.triangles(soup.triangles.subspan(i, std::min<size_t>(3 * size_t(block), soup.triangles.size() - i)));
  ReadStats stats;
  stats.vertices = header.vertices;
  stats.triangles = header.faces;
  sink.end(stats);
}

}  // namespace streamcvd
