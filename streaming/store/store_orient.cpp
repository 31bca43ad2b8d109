// plan_face_flips (streaming/store/store_clean.h): the faces to flip so that a manifold store is
// consistently oriented, found from its misoriented edges outwards. A face flipped by an
// exporter or by a crude decimation gives its dual face the wrong way round, an edge of the
// output used twice in one direction, which no split of the clusters can mend (fertility with
// 3 faces flipped → 1000: 40 repair rounds, then faces deleted and a hole).
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <unordered_set>

#include "streamcvd/core/mesh/topology_conventions.h"
#include "streamcvd/streaming/store/store_clean.h"

namespace streamcvd {
namespace {

// A misoriented edge a – b: faces f and g around it both run it a → b (before any flip).
struct Misoriented {
  uint32_t f, g, a, b;
};

// Whether face f, flipped or not, runs its edge a – b as a → b.
bool runs(const MeshView& m, uint32_t f, bool flipped, uint32_t a, uint32_t b) {
  return (topology::next_corner(&m.triangles[3 * size_t(f)], a) == b) != flipped;
}

// The faces on edge a – b (both corners), up to two written to `out`; returns how many.
uint32_t faces_on_edge(const MeshView& m, uint32_t a, uint32_t b, uint32_t out[2]) {
  const auto fb = m.faces_of(b);
  uint32_t n = 0;
  for (uint32_t f : m.faces_of(a))
    if (std::find(fb.begin(), fb.end(), f) != fb.end()) {
      if (n < 2) out[n] = f;
      ++n;
    }
  return n;
}

// The misoriented edges of the store, each once (at its tail a, smaller face first): pairs of
// faces around a with the same next vertex. Only edges with exactly two faces: the cleaning
// has cut the others. In parallel over the vertices; O(Σ degree²) over tiny fans.
std::vector<Misoriented> misoriented_edges(const MeshView& m) {
  tbb::enumerable_thread_specific<std::vector<Misoriented>> found;
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, m.vertex_count(), 1 << 14), [&](const tbb::blocked_range<uint32_t>& r) {
    auto& out = found.local();
    for (uint32_t a = r.begin(); a != r.end(); ++a) {
      const auto faces = m.faces_of(a);
      auto next_of = [&](uint32_t f) { return topology::next_corner(&m.triangles[3 * size_t(f)], a); };
      for (size_t i = 0; i < faces.size(); ++i)
        for (size_t j = i + 1; j < faces.size(); ++j) {
          if (faces[i] == faces[j] || next_of(faces[i]) != next_of(faces[j])) continue;
          const uint32_t b = next_of(faces[i]);
          uint32_t on_edge[2];
          if (faces_on_edge(m, a, b, on_edge) == 2)
            out.push_back({std::min(faces[i], faces[j]), std::max(faces[i], faces[j]), a, b});
        }
    }
  });
  std::vector<Misoriented> all;
  for (const auto& v : found) all.insert(all.end(), v.begin(), v.end());
  std::sort(all.begin(), all.end(), [](const Misoriented& x, const Misoriented& y) {
    return x.f != y.f ? x.f < y.f : x.g < y.g;
  });
  return all;
}

}  // namespace

std::vector<uint32_t> misoriented_edge_vertices(const MeshView& m, uint64_t& edges) {
  const std::vector<Misoriented> found = misoriented_edges(m);
  edges = found.size();
  std::vector<uint32_t> ends;
  for (const Misoriented& e : found) ends.push_back(e.a), ends.push_back(e.b);
  std::sort(ends.begin(), ends.end());
  ends.erase(std::unique(ends.begin(), ends.end()), ends.end());
  return ends;
}

std::vector<uint64_t> plan_face_flips(const MeshView& m, uint64_t& unresolved, uint64_t max_region_faces) {
  unresolved = 0;
  const std::vector<Misoriented> edges = misoriented_edges(m);
  std::unordered_set<uint32_t> flipped, stuck;
  // The faces across f's edges that continue it consistently, under the flips so far.
  auto neighbours = [&](uint32_t f, std::vector<uint32_t>& out) {
    out.clear();
    const uint32_t* t = &m.triangles[3 * size_t(f)];
    const bool ff = flipped.contains(f);
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = t[k], b = t[(k + 1) % 3];
      uint32_t two[2];
      if (faces_on_edge(m, a, b, two) != 2) continue;  // a boundary edge (or one with more faces)
      const uint32_t other = two[0] == f ? two[1] : two[0];
      // f runs a → b when unflipped; consistent when the other runs b → a as it stands.
      if (runs(m, other, flipped.contains(other), ff ? a : b, ff ? b : a)) out.push_back(other);
    }
  };
  // Floods from either face of a misoriented edge, a face at a time in turn, across consistent
  // edges only: the side whose flood ends first is a region bounded by misoriented edges (and
  // the boundary), the smaller one; flipping it mends every edge round it. When the floods
  // meet, the surface is not orientable there (or the misoriented edges do not enclose a
  // region): left as it is. O(2 · smaller region · degree); memory O(smaller region).
  std::vector<uint32_t> around;
  for (const Misoriented& e : edges) {
    // Mended by a flip so far (a region flipped later may take in an earlier one: flips toggle).
    if (runs(m, e.f, flipped.contains(e.f), e.a, e.b) != runs(m, e.g, flipped.contains(e.g), e.a, e.b)) continue;
    if (stuck.contains(e.f) || stuck.contains(e.g)) {  // on a surface already found not orientable
      ++unresolved;
      continue;
    }
    std::unordered_set<uint32_t> seen[2] = {{e.f}, {e.g}};
    std::vector<uint32_t> queue[2] = {{e.f}, {e.g}};
    size_t head[2] = {0, 0};
    int done = -1;
    bool met = false;
    while (done < 0 && !met && seen[0].size() + seen[1].size() <= 2 * max_region_faces) {
      for (int s = 0; s < 2 && done < 0 && !met; ++s) {
        if (head[s] == queue[s].size()) {
          done = s;
          break;
        }
        neighbours(queue[s][head[s]++], around);
        for (uint32_t g : around) {
          if (seen[1 - s].contains(g)) {
            met = true;
            break;
          }
          if (seen[s].insert(g).second) queue[s].push_back(g);
        }
      }
    }
    if (done < 0) {  // the other misoriented edges of its faces would fail the same way
      ++unresolved;
      for (const auto& side : seen) stuck.insert(side.begin(), side.end());
      continue;
    }
    for (uint32_t f : queue[done])
      if (!flipped.erase(f)) flipped.insert(f);
  }
  std::vector<uint64_t> out(flipped.begin(), flipped.end());
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace streamcvd
