// Passes 3 and 4 of the store build. Pass 3 remaps each face's corners to store ids and buckets
// the face by the vertex range of its owner (its smallest corner), in file order. Pass 4 visits
// the ranges in order: a range's faces are counting-sorted by owner (stable, so faces of one
// owner keep their file order) and get their final ids; faces with a corner in a later range are
// sent there ("foreign" faces, in face id order); the range's vertex→face and vertex→vertex CSR
// and flags come from its owned plus foreign faces, so they are exact across range and chunk
// frontiers; chunks are cut as the owned counts stream by. Every array is appended front to back.
#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <future>
#include <limits>
#include <vector>

#include "streamcvd/streaming/store/adjacency.h"
#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/core/mesh/mesh_view.h"
#include "streamcvd/core/mesh/topology_conventions.h"
#include "streamcvd/streaming/store/counting_sort.h"
#include "streamcvd/streaming/store/store_build_state.h"
#include "streamcvd/streaming/store/store_writer.h"

namespace streamcvd {

using namespace store_build;

void StoreBuilder::State::begin_faces() {
  // Ranges of range_width vertices, each working set within half the memory.
  const uint64_t range_budget = usable == ~uint64_t(0) ? usable : std::max(kMinWork, usable / 2);
  const uint64_t width = std::clamp<uint64_t>(range_budget / kRangeBytesPerVertex, 4096, options.max_range_vertices);
  range_width = uint32_t(width / kBoxBlock * kBoxBlock);  // whole box blocks (fewer partial reads)
  range_count = uint32_t((uint64_t(vertex_count) + range_width - 1) / range_width);
  const uint64_t map_bytes = 4 * input_vertices;
  const uint64_t resident = std::min(free_after(map_bytes), usable / 2);
  const uint32_t buckets = std::max<uint32_t>(range_count, 1);
  owned_faces = std::make_unique<SpillBuckets>(work_dir, buckets, 12, resident, SpillBuckets::block_size_for(buckets, resident));
  result.report.vertex_ranges = range_count;
}

void StoreBuilder::State::add_faces(std::span<const uint32_t> corners) {
  const size_t n = corners.size() / 3;
  if (face_count + face_batch.size() / 3 + n > std::numeric_limits<uint32_t>::max())
    throw InputError("store build: more than 2^32-1 faces");
  // The reader's blocks (64K faces) are batched: a batch is enough work for every thread in
  // the remap and the bucketing below, where a block kept the building thread busy with a
  // serial loop of one append per face while the other threads waited.
  if (face_batch.empty() && n >= kFaceBatch) return remap_faces(corners);
  const size_t old = face_batch.size();
  face_batch.resize(old + 3 * n);
  std::copy(corners.begin(), corners.begin() + 3 * n, face_batch.begin() + old);
  if (face_batch.size() / 3 >= kFaceBatch) flush_faces();
}

void StoreBuilder::State::flush_faces() {
  if (face_batch.empty()) return;
  remap_faces(face_batch);
  face_batch.clear();
}

// Faces face_count, face_count + 1, ... (file order): corners remapped to store ids, each face
// to the bucket of its owner's vertex range, in file order within a bucket.
void StoreBuilder::State::remap_faces(std::span<const uint32_t> corners) {
  const auto t0 = std::chrono::steady_clock::now();
  const size_t n = corners.size() / 3;
  remapped.resize(3 * n);
  face_range.resize(n);
  const uint64_t limit = input_vertices;
  const size_t bad = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, n, 4096), n,
      [&](const tbb::blocked_range<size_t>& r, size_t first_bad) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          const uint32_t a = corners[3 * i], b = corners[3 * i + 1], c = corners[3 * i + 2];
          if (a >= limit || b >= limit || c >= limit) {
            first_bad = std::min(first_bad, i);
            continue;
          }
          const uint32_t na = new_of_old[a], nb = new_of_old[b], nc = new_of_old[c];
          remapped[3 * i] = na, remapped[3 * i + 1] = nb, remapped[3 * i + 2] = nc;
          face_range[i] = std::min({na, nb, nc}) / range_width;
        }
        return first_bad;
      },
      [](size_t a, size_t b) { return std::min(a, b); });
  if (bad < n) {
    uint32_t v = corners[3 * bad];
    for (int k = 1; k < 3; ++k) v = std::max(v, corners[3 * bad + k]);
    throw InputError("store build: face " + std::to_string(face_count + bad) + " uses vertex " + std::to_string(v) +
                     " of " + std::to_string(limit));
  }
  // Grouped by range (a stable counting sort: file order within a range), then one append of
  // consecutive records per range.
  face_staging.resize(3 * n);
  counting_sort(
      n, owned_faces->bucket_count(), [&](uint64_t i) { return face_range[i]; }, face_range_start,
      [&](uint64_t i, uint32_t at) {
        for (int k = 0; k < 3; ++k) face_staging[3 * size_t(at) + k] = remapped[3 * i + k];
      });
  for (uint32_t b = 0; b < owned_faces->bucket_count(); ++b)
    if (face_range_start[b + 1] > face_range_start[b])
      owned_faces->append(b, &face_staging[3 * size_t(face_range_start[b])], face_range_start[b + 1] - face_range_start[b]);
  face_count += n;
  result.report.faces_seconds += seconds_since(t0);
  report("faces", face_count, header.faces != MeshHeaderInfo::kUnknown ? header.faces : 0, "faces");  // 0: unknown
}

void StoreBuilder::State::finish_faces() {
  if (!owned_faces) begin_faces();  // no face at all
  flush_faces();
  DefaultInitVector<uint32_t>().swap(new_of_old);
  for (auto* v : {&face_batch, &remapped, &face_range, &face_staging, &face_range_start}) DefaultInitVector<uint32_t>().swap(*v);
  result.face_count = face_count;
}

namespace {

// A chunk being filled: its record, and the foreign faces touching it (deduplicated at close).
struct OpenChunk {
  Chunk chunk;
  std::vector<uint32_t> halo;
  float lo[3] = {std::numeric_limits<float>::infinity(), std::numeric_limits<float>::infinity(),
                 std::numeric_limits<float>::infinity()};
  float hi[3] = {-std::numeric_limits<float>::infinity(), -std::numeric_limits<float>::infinity(),
                 -std::numeric_limits<float>::infinity()};
};

// The inputs of one range, loaded ahead (on another thread) while the previous range is built.
struct RangeInput {
  DefaultInitVector<std::byte> faces;  // owned faces, 3 corners each, file order
};

class RangePass {
 public:
  explicit RangePass(StoreBuilder::State& s);
  void run();

 private:
  void load(uint32_t r, RangeInput& in);  // into reused buffers
  void sort_owned(uint32_t r, const RangeInput& in);
  void cut_chunks(uint32_t r);
  void send_foreign(uint32_t r);
  void local_adjacency(uint32_t r);
  void screen_topology();
  struct RangeArrays;
  void write_range();
  void write(RangeArrays& a);
  void chunk_stats(uint32_t r, const RangeInput& in);
  void close_chunk(uint64_t end_vertex, uint64_t end_face);
  void add_box(uint32_t v0, uint32_t v1, float* lo, float* hi);
  void finish();

  uint32_t begin_of(uint32_t r) const { return r * s_.range_width; }
  uint32_t end_of(uint32_t r) const {
    return uint32_t(std::min<uint64_t>(uint64_t(r + 1) * s_.range_width, s_.vertex_count));
  }

  StoreBuilder::State& s_;
  ArrayOutput &triangles_, &vv_offsets_, &vv_, &vf_offsets_, &vf_, &flags_;
  SpillBuckets foreign_;
  std::unique_ptr<ChunkCutter> cutter_;
  // Per range (reused).
  uint32_t vb_ = 0, n_ = 0;
  uint64_t face_base_ = 0;
  DefaultInitVector<uint32_t> owned_start_;  // n + 1: local owner offsets
  DefaultInitVector<std::byte> foreign_in_;
  uint64_t foreign_count_ = 0;
  // The arrays a range produces, two sets: range r + 1 is built in one while the other is
  // written out (by writer_), so the serial appends and the disk waits overlap the next range.
  struct RangeArrays {
    DefaultInitVector<uint32_t> tri;  // foreign faces' corners, then the owned faces'
    DefaultInitVector<uint64_t> vf_off, vv_off;
    DefaultInitVector<uint32_t> vf, vv;
    DefaultInitVector<uint8_t> flags;
    uint64_t foreign = 0;             // foreign faces at the front of tri
    uint64_t vf_base = 0, vv_base = 0;  // global offsets of the range's first entries
  };
  RangeArrays arrays_[2];
  RangeArrays* a_ = &arrays_[0];
  std::future<void> writer_;
  std::vector<uint64_t> cuts_;
  DefaultInitVector<float> partial_;  // positions of a partly covered box block
  // Totals.
  uint64_t vf_base_ = 0, vv_base_ = 0;
  OpenChunk open_;
  std::vector<uint64_t> chunk_pairs_;  // (owner chunk << 32 | touched chunk) of halo faces
  double trace_[7] = {};  // per step of run(); 2 and 3 unused (cuts and foreign run with the adjacency)
};

RangePass::RangePass(StoreBuilder::State& s)
    : s_(s),
      triangles_(s.outputs.array("triangles.u32")),
      vv_offsets_(s.outputs.array("vv_offsets.u64")),
      vv_(s.outputs.array("vv.u32")),
      vf_offsets_(s.outputs.array("vf_offsets.u64")),
      vf_(s.outputs.array("vf.u32")),
      flags_(s.outputs.array("flags.u8")),
      foreign_(s.work_dir, std::max<uint32_t>(s.range_count, 1), sizeof(ForeignFace),
               s.usable == ~uint64_t(0) ? s.usable : s.usable / 8,
               SpillBuckets::block_size_for(std::max<uint32_t>(s.range_count, 1),
                                            s.usable == ~uint64_t(0) ? s.usable : s.usable / 8)) {
  cutter_ = std::make_unique<ChunkCutter>(s.vertex_count, s.face_count, s.options.faces_per_chunk);
  const uint64_t V = s.vertex_count, F = s.face_count;
  s.outputs.expect("triangles.u32", 12 * F);
  s.outputs.expect("vf.u32", 12 * F);
  s.outputs.expect("vv.u32", 4 * (3 * F + V));  // a vertex of one fan has ≤ deg_f + 1 neighbours
  s.outputs.expect("vf_offsets.u64", 8 * (V + 1));
  s.outputs.expect("vv_offsets.u64", 8 * (V + 1));
  s.outputs.expect("flags.u8", V);
}

void RangePass::load(uint32_t r, RangeInput& in) {
  s_.owned_faces->take(r, in.faces);
}

// Owned faces counting-sorted by owner (stable): final order and ids; owned_start_ = offsets.
void RangePass::sort_owned(uint32_t r, const RangeInput& in) {
  vb_ = begin_of(r);
  n_ = end_of(r) - vb_;
  const uint32_t* f = reinterpret_cast<const uint32_t*>(in.faces.data());
  const uint64_t m = in.faces.size() / 12;
  // a_->tri = [foreign (filled later) | owned]; the owned part is placed now.
  foreign_.take(r, foreign_in_);
  foreign_count_ = foreign_in_.size() / sizeof(ForeignFace);
  a_->tri.resize(3 * (foreign_count_ + m));
  uint32_t* owned = a_->tri.data() + 3 * foreign_count_;
  const uint32_t vb = vb_;
  // The screen's count of faces with a repeated index is taken here, where each owned face
  // passes once with its corners at hand, instead of in a second walk over the owned faces.
  std::atomic<uint64_t> repeated{0};
  counting_sort(
      m, n_, [&](uint64_t i) { return std::min({f[3 * i], f[3 * i + 1], f[3 * i + 2]}) - vb; }, owned_start_,
      [&](uint64_t i, uint32_t at) {
        const uint32_t a = f[3 * i], b = f[3 * i + 1], c = f[3 * i + 2];
        owned[3 * size_t(at)] = a, owned[3 * size_t(at) + 1] = b, owned[3 * size_t(at) + 2] = c;
        if (topology::repeated_index(a, b, c)) [[unlikely]] repeated.fetch_add(1, std::memory_order_relaxed);
      });
  s_.result.report.screen.repeated_index_faces += repeated.load();
  const ForeignFace* foreign = reinterpret_cast<const ForeignFace*>(foreign_in_.data());
  tbb::parallel_for(tbb::blocked_range<uint64_t>(0, foreign_count_, 1 << 14), [&](const tbb::blocked_range<uint64_t>& q) {
    for (uint64_t i = q.begin(); i != q.end(); ++i)
      for (int k = 0; k < 3; ++k) a_->tri[3 * i + k] = foreign[i].corner[k];
  });
}

// Chunk boundaries decided by this range's owned counts: vertices e in (vb, ve] (and 0).
void RangePass::cut_chunks(uint32_t r) {
  cuts_.clear();
  auto first_face = [&](uint64_t e) { return face_base_ + owned_start_[e - vb_]; };
  for (uint64_t e = r == 0 ? vb_ : vb_ + 1; e <= uint64_t(vb_) + n_; ++e)
    cutter_->visit(e, first_face(e), e > vb_ ? first_face(e - 1) : face_base_, cuts_);
}

// Faces with a corner in a later range go there, in face id order.
void RangePass::send_foreign(uint32_t r) {
  const uint32_t* owned = a_->tri.data() + 3 * foreign_count_;
  const uint64_t m = owned_start_[n_];
  const uint32_t ve = vb_ + n_;
  for (uint64_t i = 0; i < m; ++i) {
    const uint32_t* t = owned + 3 * i;
    if (std::max({t[0], t[1], t[2]}) < ve) continue;
    const ForeignFace face{uint32_t(face_base_ + i), {t[0], t[1], t[2]}};
    uint32_t sent[2] = {r, r};
    int count = 0;
    for (int k = 0; k < 3; ++k) {
      const uint32_t to = t[k] / s_.range_width;
      if (to == r || (count > 0 && sent[0] == to) || (count > 1 && sent[1] == to)) continue;
      sent[count++] = to;
      foreign_.append(to, &face);
    }
  }
}

// Vertex→face and vertex→vertex CSR and flags of the range from its foreign + owned faces.
void RangePass::local_adjacency(uint32_t) {
  build_vertex_face_adjacency(std::span<const uint32_t>(a_->tri), vb_, n_, a_->vf_off, a_->vf);
  a_->flags.resize(n_);
  build_vertex_vertex_adjacency(std::span<const uint32_t>(a_->tri), vb_, std::span<const uint64_t>(a_->vf_off),
                                std::span<const uint32_t>(a_->vf), a_->vv_off, a_->vv, std::span<uint8_t>(a_->flags));
  screen_topology();
  // Local face indices → face ids (foreign faces first, then the owned ones from face_base_).
  const ForeignFace* foreign = reinterpret_cast<const ForeignFace*>(foreign_in_.data());
  const uint64_t fc = foreign_count_, base = face_base_;
  tbb::parallel_for(tbb::blocked_range<size_t>(0, a_->vf.size(), 1 << 16), [&](const tbb::blocked_range<size_t>& q) {
    for (size_t j = q.begin(); j != q.end(); ++j) {
      const uint32_t l = a_->vf[j];
      a_->vf[j] = l < fc ? foreign[l].face : uint32_t(base + (l - fc));
    }
  });
}

// The cleaning's screen over the range (StoreBuildReport::TopologyScreen), from what the
// adjacency pass has just built: its flagged vertices, its isolated twins and the edges two
// faces run the same way (its faces with a repeated index are counted by sort_owned). A duplicate face anywhere else puts a third face
// on one of its edges or a second fan at one of its corners, so the flags show it; only a face
// and its twin alone (each corner with exactly those two faces) need a look. Exact for any():
// O(faces) compares and O(n) flag reads, no sort. Runs before the face lists are turned into
// face ids.
void RangePass::screen_topology() {
  using Screen = StoreBuildReport::TopologyScreen;
  constexpr uint64_t kSmallFan = 16;
  const uint32_t* tri = a_->tri.data();
  auto corners = [&](uint32_t f) { return topology::vertex_set(tri[3 * f], tri[3 * f + 1], tri[3 * f + 2]); };
  const Screen found = tbb::parallel_reduce(
      tbb::blocked_range<uint32_t>(0, n_, 1 << 14), Screen{},
      [&](const tbb::blocked_range<uint32_t>& q, Screen sc) {
        std::vector<uint32_t> next;  // the corners after v, reused across the block's vertices
        for (uint32_t v = q.begin(); v != q.end(); ++v) {
          sc.nonmanifold_vertices += (a_->flags[v] & kVertexNonManifold) != 0;
          // Two faces running the same edge v → w the same way: misoriented (counted at v), found
          // as equal corners after v among its faces.
          const uint64_t b = a_->vf_off[v], e = a_->vf_off[v + 1];
          // The next corners in a stack array for the usual vertex, in `next` for a large fan.
          uint32_t small[kSmallFan];
          if (e - b > kSmallFan) next.resize(e - b);
          uint32_t* corner = e - b > kSmallFan ? next.data() : small;
          for (uint64_t i = b; i < e; ++i) corner[i - b] = topology::next_corner(&tri[3 * size_t(a_->vf[i])], vb_ + v);
          if (e - b <= kSmallFan) {  // each corner with an equal one before it: the sorted count, no sort
            for (uint64_t i = 1; i < e - b; ++i) {
              bool seen = false;
              for (uint64_t j = 0; j < i; ++j) seen |= corner[j] == corner[i];
              sc.misoriented_edges += seen;
            }
          } else {
            std::sort(next.begin(), next.end());
            for (size_t i = 1; i < next.size(); ++i) sc.misoriented_edges += next[i] == next[i - 1];
          }
          if (e - b != 2) continue;
          const uint32_t f = a_->vf[a_->vf_off[v]], g = a_->vf[a_->vf_off[v] + 1];
          // Counted once, at the pair's owner (its smallest corner), when both faces are owned here.
          if (f >= foreign_count_ && corners(f)[0] == vb_ + v && corners(f) == corners(g)) ++sc.isolated_twin_faces;
        }
        return sc;
      },
      [](Screen a, const Screen& b) {
        a.nonmanifold_vertices += b.nonmanifold_vertices;
        a.repeated_index_faces += b.repeated_index_faces;
        a.isolated_twin_faces += b.isolated_twin_faces;
        a.misoriented_edges += b.misoriented_edges;
        return a;
      });
  Screen& total = s_.result.report.screen;
  total.nonmanifold_vertices += found.nonmanifold_vertices;
  total.isolated_twin_faces += found.isolated_twin_faces;
  total.misoriented_edges += found.misoriented_edges;
}

// Appends one range's arrays to the outputs (on the writer thread), offsets made global.
void RangePass::write(RangeArrays& a) {
  const uint64_t owned = a.tri.size() / 3 - a.foreign;
  triangles_.append(std::span<const uint32_t>(a.tri.data() + 3 * a.foreign, 3 * owned));
  auto write_offsets = [](ArrayOutput& out, DefaultInitVector<uint64_t>& local, uint64_t base) {
    local.pop_back();  // the entry past the range is the next range's first
    for (uint64_t& o : local) o += base;
    out.append(std::span<const uint64_t>(local));
  };
  write_offsets(vf_offsets_, a.vf_off, a.vf_base);
  vf_.append(std::span<const uint32_t>(a.vf));
  write_offsets(vv_offsets_, a.vv_off, a.vv_base);
  vv_.append(std::span<const uint32_t>(a.vv));
  flags_.append(std::span<const uint8_t>(a.flags));
}

// Hands the current range's arrays to the writer and switches to the other set (waiting for
// the writer to be done with it).
void RangePass::write_range() {
  a_->foreign = foreign_count_;
  a_->vf_base = vf_base_;
  a_->vv_base = vv_base_;
  vf_base_ += a_->vf.size();
  vv_base_ += a_->vv.size();
  if (writer_.valid()) writer_.get();
  RangeArrays& done = *a_;
  writer_ = std::async(std::launch::async, [this, &done] { write(done); });
  a_ = a_ == &arrays_[0] ? &arrays_[1] : &arrays_[0];
}

// Grows lo/hi by the positions of store vertices [v0, v1): whole blocks from the block boxes of
// pass 2, the vertices of partly covered blocks read back from the positions.
void RangePass::add_box(uint32_t v0, uint32_t v1, float* lo, float* hi) {
  constexpr uint32_t kBlock = StoreBuilder::State::kBoxBlock;
  auto grow = [&](const float* l, const float* h) {
    for (int k = 0; k < 3; ++k) lo[k] = std::min(lo[k], l[k]), hi[k] = std::max(hi[k], h[k]);
  };
  auto exact = [&](uint32_t a, uint32_t b) {
    if (a >= b) return;
    partial_.resize(3 * size_t(b - a));
    s_.outputs.read_back("positions.f32", 12 * uint64_t(a), partial_.data(), 12 * size_t(b - a));
    for (uint32_t i = 0; i < b - a; ++i) grow(&partial_[3 * i], &partial_[3 * i]);
  };
  const uint32_t first_whole = (v0 + kBlock - 1) / kBlock, last_whole = v1 / kBlock;  // blocks inside [v0, v1)
  if (first_whole >= last_whole) return exact(v0, v1);
  exact(v0, first_whole * kBlock);
  for (uint32_t b = first_whole; b < last_whole; ++b) grow(&s_.block_boxes[6 * b], &s_.block_boxes[6 * b + 3]);
  exact(last_whole * kBlock, v1);
}

void RangePass::close_chunk(uint64_t end_vertex, uint64_t end_face) {
  Chunk& c = open_.chunk;
  c.vertex_end = uint32_t(end_vertex);
  c.face_end = end_face;
  for (int k = 0; k < 3; ++k) {
    const bool empty = !(open_.lo[k] <= open_.hi[k]);
    c.bbox_min[k] = empty ? 0 : open_.lo[k];
    c.bbox_max[k] = empty ? 0 : open_.hi[k];
  }
  std::sort(open_.halo.begin(), open_.halo.end());
  open_.halo.erase(std::unique(open_.halo.begin(), open_.halo.end()), open_.halo.end());
  c.halo_faces = open_.halo.size();
  // The chunk owning each halo face neighbours this one (halo faces are owned by earlier chunks).
  const uint32_t self = uint32_t(s_.result.chunks.size());
  uint32_t last = UINT32_MAX;
  for (uint32_t face : open_.halo) {
    const auto& chunks = s_.result.chunks;
    const uint32_t owner = uint32_t(std::upper_bound(chunks.begin(), chunks.end(), uint64_t(face),
                                                     [](uint64_t f, const Chunk& ch) { return f < ch.face_begin; }) -
                                    chunks.begin() - 1);
    if (owner != last) chunk_pairs_.push_back(uint64_t(owner) << 32 | self);
    last = owner;
  }
  s_.result.chunks.push_back(c);
  open_ = OpenChunk{};
  open_.chunk.vertex_begin = uint32_t(end_vertex);
  open_.chunk.face_begin = end_face;
}

// Bounding boxes and halo faces of the chunks this range covers (cut at cuts_).
void RangePass::chunk_stats(uint32_t, const RangeInput&) {
  const uint32_t ve = vb_ + n_;
  size_t next_cut = 0;
  for (uint32_t s0 = vb_; s0 < ve;) {
    const uint32_t s1 = next_cut < cuts_.size() ? uint32_t(std::min<uint64_t>(cuts_[next_cut], ve)) : ve;
    const uint64_t chunk_face_begin = open_.chunk.face_begin;
    struct Part {
      std::vector<uint32_t> halo;
    };
    tbb::enumerable_thread_specific<Part> parts;
    tbb::parallel_for(tbb::blocked_range<uint32_t>(s0, s1, 4096), [&](const tbb::blocked_range<uint32_t>& q) {
      Part& p = parts.local();
      // A vertex's face ids ascend (foreign faces first, in id order, then the owned ones), so
      // its halo faces are a prefix of its list.
      for (uint32_t v = q.begin(); v != q.end(); ++v)
        for (uint64_t j = a_->vf_off[v - vb_], end = a_->vf_off[v - vb_ + 1]; j != end && a_->vf[j] < chunk_face_begin; ++j)
          p.halo.push_back(a_->vf[j]);
    });
    add_box(s0, s1, open_.lo, open_.hi);
    for (Part& p : parts) open_.halo.insert(open_.halo.end(), p.halo.begin(), p.halo.end());
    if (s1 < ve || (next_cut < cuts_.size() && cuts_[next_cut] == ve)) {
      close_chunk(s1, face_base_ + owned_start_[s1 - vb_]);
      ++next_cut;
    }
    s0 = s1;
  }
}

void RangePass::finish() {
  if (s_.vertex_count > 0) close_chunk(s_.vertex_count, s_.face_count);
  const uint64_t vf_total = vf_base_, vv_total = vv_base_;
  vf_offsets_.append(std::span<const uint64_t>(&vf_total, 1));
  vv_offsets_.append(std::span<const uint64_t>(&vv_total, 1));
  s_.result.vertex_vertex_count = vv_total;
  // Neighbour table: both directions of every pair, ascending per chunk.
  std::vector<uint64_t> pairs;
  pairs.reserve(2 * chunk_pairs_.size());
  for (uint64_t p : chunk_pairs_) pairs.push_back(p), pairs.push_back(p << 32 | p >> 32);
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  auto& chunks = s_.result.chunks;
  auto& table = s_.result.chunk_neighbours;
  size_t at = 0;
  for (uint32_t c = 0; c < chunks.size(); ++c) {
    chunks[c].neighbour_begin = uint32_t(table.size());
    for (; at < pairs.size() && (pairs[at] >> 32) == c; ++at)
      if (uint32_t(pairs[at]) != c) table.push_back(uint32_t(pairs[at]));
    chunks[c].neighbour_count = uint32_t(table.size()) - chunks[c].neighbour_begin;
  }
}

void RangePass::run() {
  open_.chunk.vertex_begin = 0;
  open_.chunk.face_begin = 0;
  // Two input buffers: range r + 1 loads into one while range r is built from the other.
  RangeInput buffers[2];
  std::future<void> next;
  if (s_.range_count > 0) next = std::async(std::launch::async, [&] { load(0, buffers[0]); });
  for (uint32_t r = 0; r < s_.range_count; ++r) {
    next.get();
    RangeInput& in = buffers[r % 2];
    if (r + 1 < s_.range_count) next = std::async(std::launch::async, [&, r] { load(r + 1, buffers[(r + 1) % 2]); });
    auto tick = [&, t = std::chrono::steady_clock::now()](int i) mutable {
      const auto now = std::chrono::steady_clock::now();
      trace_[i] += std::chrono::duration<double>(now - t).count();
      t = now;
    };
    tick(0);
    sort_owned(r, in);
    tick(1);
    // The chunk cuts and the foreign faces sent to later ranges are serial walks that only read
    // this range's sorted faces, as the (parallel) adjacency does: one task runs them while the
    // other threads build the adjacency, instead of leaving a core idle for them.
    tbb::parallel_invoke(
        [&] {
          cut_chunks(r);
          send_foreign(r);
        },
        [&] { local_adjacency(r); });
    tick(4);
    chunk_stats(r, in);
    tick(6);
    write_range();
    tick(5);
    face_base_ += owned_start_[n_];
    s_.report("adjacency", r + 1, s_.range_count, "ranges");
  }
  if (writer_.valid()) writer_.get();
  finish();
  if (std::getenv("STREAMCVD_BUILD_TRACE"))
    std::fprintf(stderr, "ranges: wait %.3f sort %.3f adjacency (with cuts and foreign) %.3f write %.3f chunks %.3f\n",
                 trace_[0], trace_[1], trace_[4], trace_[5], trace_[6]);
  s_.result.report.spilled_bytes += foreign_.bytes_spilled();
}

}  // namespace

void StoreBuilder::State::build_ranges() {
  const auto t0 = std::chrono::steady_clock::now();
  RangePass(*this).run();
  result.report.spilled_bytes += owned_faces->bytes_spilled();
  owned_faces.reset();
  result.report.adjacency_seconds = seconds_since(t0);
}

}  // namespace streamcvd
