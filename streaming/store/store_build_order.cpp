// Pass 2 of the store build: the vertex order. Every vertex gets its Hilbert key; records
// (key, input id, position, attributes) go to key-range buckets whose bounds come from a sample
// of the keys, and each bucket is sorted in RAM by (key, input id). Emitting the buckets in key
// order writes positions, attributes and original ids in store order and fills the vertex map.
// The bucket bounds only balance the work: the order is (key, id) whatever they are.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <array>
#include <bit>
#include <cstddef>
#include <cstring>
#include <future>
#include <chrono>
#include <limits>
#include <numeric>

#include "streamcvd/core/mesh/errors.h"
#include "streamcvd/streaming/store/counting_sort.h"
#include "streamcvd/streaming/schedule/memory_budget.h"
#include "streamcvd/streaming/store/store_build_state.h"
#include "streamcvd/streaming/store/store_writer.h"

namespace streamcvd {

using namespace store_build;

namespace {

struct OrderItem {
  uint64_t key;
  uint32_t id;
  uint32_t slot;  // record index in the bucket
};

// (key, id), or for merged STL corners (key, position bits, id): identical corners adjacent.
struct ItemLess {
  const std::byte* records = nullptr;  // set when merging
  uint32_t record_bytes = 0;
  std::array<uint32_t, 3> bits(const OrderItem& a) const {
    std::array<uint32_t, 3> b;
    std::memcpy(b.data(), records + size_t(a.slot) * record_bytes + offsetof(VertexRecord, xyz), 12);
    return b;
  }
  bool operator()(const OrderItem& a, const OrderItem& b) const {
    if (a.key != b.key) return a.key < b.key;
    if (records) {
      const auto ba = bits(a), bb = bits(b);
      if (ba != bb) return ba < bb;
    }
    return a.id < b.id;
  }
};

void insertion_sort(OrderItem* a, size_t n, const ItemLess& less) {
  for (size_t i = 1; i < n; ++i) {
    const OrderItem x = a[i];
    size_t j = i;
    for (; j > 0 && less(x, a[j - 1]); --j) a[j] = a[j - 1];
    a[j] = x;
  }
}

// Sorts a[0, n) whose keys k satisfy k − base < 2^bits, items of equal key in id order (as they
// arrive: every distribution below is stable). MSD radix on digits of ≤ 11 bits down to runs of ≤ 32,
// which insertion sort finishes: a surface leaves most cells of a level empty, so the runs shrink
// fast. tmp has room for n items.
void msd_sort(OrderItem* a, OrderItem* tmp, size_t n, uint64_t base, int bits, const ItemLess& less) {
  if (n <= 32) return insertion_sort(a, n, less);
  if (bits <= 0) {  // equal keys: already in id order, unless merged corners order by position first
    if (less.records) std::sort(a, a + n, less);
    return;
  }
  // About two buckets per item (at most 2^11): a small run must not pay for a big count array.
  const int digit = std::min({bits, 11, std::max(4, int(std::bit_width(n)) + 1)}), shift = bits - digit;
  uint32_t start[(1 << 11) + 1];
  std::fill_n(start, (1 << digit) + 1, 0u);
  for (size_t i = 0; i < n; ++i) ++start[((a[i].key - base) >> shift) + 1];
  for (int d = 0; d < (1 << digit); ++d) start[d + 1] += start[d];
  uint32_t cursor[1 << 11];
  std::copy_n(start, 1 << digit, cursor);
  for (size_t i = 0; i < n; ++i) tmp[cursor[(a[i].key - base) >> shift]++] = a[i];
  std::copy_n(tmp, n, a);
  for (int d = 0; d < (1 << digit); ++d)
    if (start[d + 1] - start[d] > 1)
      msd_sort(a + start[d], tmp + start[d], start[d + 1] - start[d], base + (uint64_t(d) << shift), shift, less);
}

// Sorts all items: a parallel counting sort on the top bits of the key range, then msd_sort of
// each cell in parallel. Result in `items`.
void sort_items(DefaultInitVector<OrderItem>& items, DefaultInitVector<OrderItem>& tmp, const ItemLess& less) {
  const size_t n = items.size();
  tmp.resize(n);
  if (n <= 32) return insertion_sort(items.data(), n, less);
  using MinMax = std::pair<uint64_t, uint64_t>;
  const MinMax range = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, n, 1 << 16), MinMax{~uint64_t(0), 0},
      [&](const tbb::blocked_range<size_t>& r, MinMax m) {
        for (size_t i = r.begin(); i != r.end(); ++i) m = {std::min(m.first, items[i].key), std::max(m.second, items[i].key)};
        return m;
      },
      [](MinMax a, MinMax b) { return MinMax{std::min(a.first, b.first), std::max(a.second, b.second)}; });
  const auto ts0 = std::chrono::steady_clock::now();
  const int range_bits = std::bit_width(range.second - range.first);
  const int cell_bits = std::min({range_bits, 20, std::max(1, int(std::bit_width(n)) - 2)});
  const int shift = range_bits - cell_bits;
  const uint64_t base = range.first;
  DefaultInitVector<uint32_t> start;
  counting_sort(
      n, uint32_t(1) << cell_bits, [&](uint64_t i) { return uint32_t((items[i].key - base) >> shift); }, start,
      [&](uint64_t i, uint32_t at) { tmp[at] = items[i]; });
  items.swap(tmp);
  const auto ts1 = std::chrono::steady_clock::now();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, start.size() - 1, 256), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t c = r.begin(); c != r.end(); ++c)
      if (start[c + 1] - start[c] > 1)
        msd_sort(items.data() + start[c], tmp.data() + start[c], start[c + 1] - start[c], base + (uint64_t(c) << shift),
                 shift, less);
  });
  if (std::getenv("STREAMCVD_BUILD_TRACE")) {
    const auto ts2 = std::chrono::steady_clock::now();
    size_t big = 0, biggest = 0;
    for (size_t c = 0; c + 1 < start.size(); ++c) big += start[c + 1] - start[c] > 32, biggest = std::max<size_t>(biggest, start[c + 1] - start[c]);
    std::fprintf(stderr, "sort_items n=%zu cell_bits=%d counting %.3f cells %.3f (cells>32: %zu, biggest %zu)\n", n, cell_bits,
                 std::chrono::duration<double>(ts1 - ts0).count(), std::chrono::duration<double>(ts2 - ts1).count(), big, biggest);
  }
}

// Extends the per-block boxes (State::kBoxBlock store vertices each) with the positions of the
// store vertices first, first + 1, ... (3 floats each).
void add_block_boxes(std::vector<float>& boxes, uint64_t first, std::span<const float> xyz) {
  constexpr uint32_t kBlock = StoreBuilder::State::kBoxBlock;
  const uint64_t n = xyz.size() / 3, last_block = (first + n + kBlock - 1) / kBlock;
  constexpr float inf = std::numeric_limits<float>::infinity();
  while (boxes.size() < 6 * last_block) boxes.insert(boxes.end(), {inf, inf, inf, -inf, -inf, -inf});
  // One task per run of box blocks (each block's vertices in order, as a serial loop would):
  // this runs between the buckets' parallel sorts, where a serial loop leaves a core idle.
  tbb::parallel_for(tbb::blocked_range<uint64_t>(first / kBlock, last_block, 16), [&](const tbb::blocked_range<uint64_t>& r) {
    for (uint64_t b = r.begin(); b != r.end(); ++b) {
      float* box = &boxes[6 * b];
      const uint64_t i0 = std::max(b * kBlock, first) - first, i1 = std::min((b + 1) * kBlock, first + n) - first;
      for (uint64_t i = i0; i < i1; ++i)
        for (int k = 0; k < 3; ++k) box[k] = std::min(box[k], xyz[3 * i + k]), box[3 + k] = std::max(box[3 + k], xyz[3 * i + k]);
    }
  });
}

}  // namespace

// Plans pass 2 for n_in vertices in the box [box_lo, box_hi] (a sample of their positions
// gives the key ranges): the grid, the number of key buckets, their split keys, the buckets.
void StoreBuilder::State::plan_order(uint64_t n_in, const float* box_lo, const float* box_hi,
                                     std::span<const float> sample_xyz, uint64_t sample_stride) {
  order_record_bytes = uint32_t(sizeof(VertexRecord)) + 4 * attribute_count;
  // The vertex map (4 bytes per input vertex) lives until pass 3 ends.
  const uint64_t map_bytes = 4 * n_in;
  require(map_bytes + kMinWork, ("the vertex map of " + std::to_string(n_in) + " vertices").c_str());
  grid = make_hilbert_grid(box_lo, box_hi);
  // Buckets sized so that one, with its two item arrays and the next bucket read ahead, fits
  // the sort budget.
  const uint64_t per_vertex = 2 * order_record_bytes + 2 * sizeof(OrderItem);
  // A quarter of what the map leaves: smaller buckets leave more of them resident (unspilled).
  const uint64_t sort_budget = std::max(kMinWork, free_after(map_bytes) / 4);
  const uint32_t buckets = uint32_t(std::max<uint64_t>(1, (n_in * per_vertex + sort_budget - 1) / sort_budget));
  key_splits.clear();  // bucket of key k = number of splits ≤ k
  if (buckets > 1) {
    std::vector<uint64_t> keys(sample_xyz.size() / 3);
    for (size_t i = 0; i < keys.size(); ++i) keys[i] = vertex_key(i * sample_stride, &sample_xyz[3 * i]);
    std::sort(keys.begin(), keys.end());
    for (uint32_t b = 1; b < buckets; ++b) key_splits.push_back(keys.empty() ? 0 : keys[keys.size() * b / buckets]);
  }
  result.report.key_buckets = buckets;
  const uint64_t resident = free_after(map_bytes + sort_budget);
  key_records = std::make_unique<SpillBuckets>(work_dir, buckets, order_record_bytes, resident,
                                               SpillBuckets::block_size_for(buckets, resident));
  distribute_batch_bytes = size_t(std::clamp<uint64_t>(usable / 32, uint64_t(1) << 20, uint64_t(8) << 20));
}

// Vertices first_id, first_id + 1, ... (records of xyz + attributes): keys and buckets in
// parallel, the records counting-sorted by bucket into a staging buffer (stable: file order
// within a bucket), then one append per bucket.
void StoreBuilder::State::distribute(std::span<const std::byte> bytes, uint64_t first_id) {
  const auto t0 = std::chrono::steady_clock::now();
  struct Accumulate {
    double& total;
    std::chrono::steady_clock::time_point t0;
    ~Accumulate() { total += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); }
  } accumulate{distribute_seconds, t0};
  const uint32_t in_bytes = 12 + 4 * attribute_count, record_bytes = order_record_bytes;
  const uint32_t buckets = key_records->bucket_count();
  const size_t m = bytes.size() / in_bytes;
  auto& keys = order_scratch_keys;
  auto& bucket_of = order_scratch_buckets;
  bucket_of.resize(m);
  keys.resize(m);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, m, 4096), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t i = r.begin(); i != r.end(); ++i) {
      float p[3];
      std::memcpy(p, bytes.data() + i * in_bytes, 12);
      keys[i] = vertex_key(first_id + i, p);
      bucket_of[i] = uint32_t(std::upper_bound(key_splits.begin(), key_splits.end(), keys[i]) - key_splits.begin());
    }
  });
  order_staging.resize(m * record_bytes);
  auto place = [&](uint64_t i, uint32_t at) {
    std::byte* rec = order_staging.data() + size_t(at) * record_bytes;
    const VertexRecord head{keys[i], uint32_t(first_id + i), {}};
    std::memcpy(rec, &head, offsetof(VertexRecord, xyz));
    std::memcpy(rec + offsetof(VertexRecord, xyz), bytes.data() + i * in_bytes, in_bytes);  // xyz, attributes
  };
  auto& start = order_scratch_start;
  if (buckets > 1) {
    counting_sort(m, buckets, [&](uint64_t i) { return bucket_of[i]; }, start, place);
  } else {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, m, 4096), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) place(i, uint32_t(i));
    });
    start.assign({0, uint32_t(m)});
  }
  for (uint32_t b = 0; b < buckets; ++b)
    if (start[b + 1] > start[b])
      key_records->append(b, order_staging.data() + size_t(start[b]) * record_bytes, start[b + 1] - start[b]);
}

// Batches vertex records (from the reader or the pass-1 spill) into distribute() calls of
// ~distribute_batch_bytes: enough work per call for every thread. flush = the last call.
void StoreBuilder::State::distribute_batched(std::span<const std::byte> bytes, bool flush) {
  const uint32_t in_bytes = 12 + 4 * attribute_count;
  if (order_batch.empty() && bytes.size() >= distribute_batch_bytes) {
    distribute(bytes, distributed);
    distributed += bytes.size() / in_bytes;
  } else if (!bytes.empty()) {
    const size_t old = order_batch.size();
    order_batch.resize(old + bytes.size());
    std::memcpy(order_batch.data() + old, bytes.data(), bytes.size());
  }
  if (!order_batch.empty() && (flush || order_batch.size() >= distribute_batch_bytes)) {
    distribute(order_batch, distributed);
    distributed += order_batch.size() / in_bytes;
    order_batch.clear();
  }
}

uint64_t StoreBuilder::State::vertex_key(uint64_t id, const float* p) const {
  return options.hilbert_order ? hilbert_key(grid, p) : id;
}

void StoreBuilder::State::order_vertices() {
  const auto t0 = std::chrono::steady_clock::now();
  ordered = true;
  const uint64_t n_in = input_vertices;
  float box_lo[3], box_hi[3];
  for (int k = 0; k < 3; ++k) {
    const bool empty = !(lo[k] <= hi[k]);
    box_lo[k] = empty ? 0 : lo[k];
    box_hi[k] = empty ? 0 : hi[k];
  }
  outputs.plan(n_in, header.faces != MeshHeaderInfo::kUnknown ? header.faces
                     : merge_corners                          ? n_in / 3
                                                              : std::max(input_faces, 2 * n_in));
  if (key_records) {
    // Distributed while read (the header's bounds): they must be those of the vertices read.
    for (int k = 0; k < 3; ++k)
      if (!(lo[k] == header.bounds_lo[k]) || !(hi[k] == header.bounds_hi[k]))
        throw InputError("store build: the input changed while it was read (its vertex bounds differ)");
    distribute_batched({}, true);
  } else {
    plan_order(n_in, box_lo, box_hi, sample.xyz, sample.stride);
    vertex_records->drain(0, [&](std::span<const std::byte> bytes) { distribute_batched(bytes, false); });
    distribute_batched({}, true);
    vertex_records.reset();
  }
  DefaultInitVector<std::byte>().swap(order_batch);
  DefaultInitVector<std::byte>().swap(order_staging);
  SpillBuckets& key_records_ = *key_records;
  const uint32_t record_bytes = order_record_bytes;
  const uint32_t buckets = key_records_.bucket_count();
  double trace[5] = {};
  auto tick = [&, t = std::chrono::steady_clock::now()](int i) mutable {
    const auto now = std::chrono::steady_clock::now();
    trace[i] += std::chrono::duration<double>(now - t).count();
    t = now;
  };
  tick(0);

  // Each bucket sorted, then emitted in order.
  new_of_old.resize(n_in);
  outputs.expect("positions.f32", 12 * n_in);  // at most: merged corners give fewer
  outputs.expect("original_ids.u32", 4 * n_in);
  if (attribute_count) outputs.expect("vertex_attributes.f32", 4 * uint64_t(attribute_count) * n_in);
  ArrayOutput& positions = outputs.array("positions.f32");
  ArrayOutput& original_ids = outputs.array("original_ids.u32");
  ArrayOutput* attributes = attribute_count ? &outputs.array("vertex_attributes.f32") : nullptr;
  DefaultInitVector<std::byte> records;
  DefaultInitVector<OrderItem> items, tmp;
  DefaultInitVector<float> out_xyz, out_attributes;
  DefaultInitVector<uint32_t> out_ids;
  uint64_t emitted = 0;
  // Bucket b + 1 is read (from the disk, when spilled) while bucket b is sorted and emitted.
  DefaultInitVector<std::byte> next_records;
  std::future<void> next;
  if (buckets > 0) next = std::async(std::launch::async, [&] { key_records_.take(0, next_records); });
  for (uint32_t b = 0; b < buckets; ++b) {
    tick(4);
    next.get();
    records.swap(next_records);
    if (b + 1 < buckets) next = std::async(std::launch::async, [&, b] { key_records_.take(b + 1, next_records); });
    tick(1);
    const size_t n = records.size() / record_bytes;
    items.resize(n);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1 << 14), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) {
        VertexRecord k;
        std::memcpy(&k, records.data() + i * record_bytes, sizeof k);
        items[i] = {k.key, k.id, uint32_t(i)};
      }
    });
    ItemLess less;
    if (merge_corners) less = {records.data(), record_bytes};
    sort_items(items, tmp, less);
    tick(2);
    // A new store vertex per item, or per run of identical corners when merging.
    out_ids.resize(n);
    size_t out_n = 0;
    if (!merge_corners) {
      out_n = n;
      tbb::parallel_for(tbb::blocked_range<size_t>(0, n, 1 << 14), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
          out_ids[i] = items[i].id;
          new_of_old[items[i].id] = uint32_t(vertex_count + i);
        }
      });
    } else {
      for (size_t i = 0; i < n; ++i) {
        // The first corner of each position (the smallest id) represents it; items[out_n − 1]
        // is the current representative.
        const bool same = out_n > 0 && items[i].key == items[out_n - 1].key &&
                          less.bits(items[i]) == less.bits(items[out_n - 1]);
        if (!same) items[out_n++] = items[i];
        new_of_old[items[i].id] = uint32_t(vertex_count + out_n - 1);
      }
      for (size_t i = 0; i < out_n; ++i) out_ids[i] = items[i].id;
    }
    out_xyz.resize(3 * out_n);
    out_attributes.resize(size_t(attribute_count) * out_n);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, out_n, 1 << 14), [&](const tbb::blocked_range<size_t>& r) {
      for (size_t i = r.begin(); i != r.end(); ++i) {
        const std::byte* rec = records.data() + size_t(items[i].slot) * record_bytes;
        std::memcpy(&out_xyz[3 * i], rec + offsetof(VertexRecord, xyz), 12);
        if (attribute_count != 0)  // out_attributes is empty then: no element to address
          std::memcpy(&out_attributes[attribute_count * i], rec + sizeof(VertexRecord), 4 * attribute_count);
      }
    });
    add_block_boxes(block_boxes, vertex_count, out_xyz);
    positions.append(std::span<const float>(out_xyz));
    if (options.map_original_ids) options.map_original_ids(std::span<uint32_t>(out_ids.data(), out_n));
    original_ids.append(std::span<const uint32_t>(out_ids.data(), out_n));
    if (attributes) attributes->append(std::span<const float>(out_attributes));
    vertex_count += uint32_t(out_n);
    tick(3);
    emitted += n;
    report("order", emitted, n_in, "vertices");
  }
  result.report.spilled_bytes += key_records_.bytes_spilled();
  if (std::getenv("STREAMCVD_BUILD_TRACE"))
    std::fprintf(stderr, "order: distribute %.3f (during the read %.3f) take %.3f sort %.3f emit %.3f items %.3f\n", trace[0], distribute_seconds, trace[1],
                 trace[2], trace[3], trace[4]);
  key_records.reset();
  result.vertex_count = vertex_count;
  result.report.order_seconds = seconds_since(t0);
}

}  // namespace streamcvd
