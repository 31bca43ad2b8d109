// The dual mesh (core/dual/dual_mesh.h): boundary loops, the §VI-D strips (Douglas–Peucker
// corners, holes closed below the output resolution), build_dual_mesh on the triples of
// core/dual/dual_topology.h, and the output-side defect finder and last-resort removal.
#include "streamcvd/core/dual/dual_mesh.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <numeric>

#include "streamcvd/core/dual/dual_topology.h"
#include "streamcvd/core/dual/hole_closing.h"

namespace streamcvd {

namespace {

// Number of faces holding both u and v: the intersection of two ascending face lists.
inline uint32_t shared_faces(const MeshView& mesh, uint32_t u, uint32_t v) {
  auto fu = mesh.faces_of(u), fv = mesh.faces_of(v);
  uint32_t n = 0;
  size_t i = 0, j = 0;
  while (i < fu.size() && j < fv.size()) {
    if (fu[i] < fv[j]) ++i;
    else if (fv[j] < fu[i]) ++j;
    else { ++n; ++i; ++j; }
  }
  return n;
}

struct BoundaryEdge {
  uint32_t from, to;
  bool operator<(const BoundaryEdge& o) const { return from != o.from ? from < o.from : to < o.to; }
};

// Directed boundary edges (u → v as in their only face), sorted by (from, to): each chunk emits
// those of the faces it owns (every boundary edge has one face, so it is emitted once), merged
// in chunk order. Memory: the boundary, not V.
std::vector<BoundaryEdge> directed_boundary_edges(const MeshView& mesh) {
  const std::vector<dual::FaceRange> blocks = dual::chunk_face_blocks(mesh);
  std::vector<std::vector<BoundaryEdge>> found(blocks.size());
  const uint32_t* T = mesh.triangles.data();
  tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks.size(), 1), [&](const tbb::blocked_range<size_t>& r) {
    for (size_t b = r.begin(); b != r.end(); ++b)
      for (uint64_t f = blocks[b].begin; f < blocks[b].end; ++f)
        for (int i = 0; i < 3; ++i) {
          const uint32_t u = T[3 * f + i], v = T[3 * f + (i + 1) % 3];
          if (u == v || !(mesh.vertex_flags[u] & kVertexBoundary) || !(mesh.vertex_flags[v] & kVertexBoundary)) continue;
          if (shared_faces(mesh, u, v) == 1) found[b].push_back({u, v});
        }
  });
  std::vector<BoundaryEdge> edges;
  for (const auto& e : found) edges.insert(edges.end(), e.begin(), e.end());
  std::sort(edges.begin(), edges.end());
  return edges;
}

}  // namespace

BoundaryLoops find_boundary_loops(const MeshView& mesh) {
  BoundaryLoops loops;
  loops.offsets.push_back(0);
  const std::vector<BoundaryEdge> edges = directed_boundary_edges(mesh);
  if (edges.empty()) return loops;
  // Successor of each boundary edge: the unique boundary edge leaving its `to` vertex. Edges are
  // sorted by `from`, so a vertex's outgoing edges are one run (binary search), and its incoming
  // ones a run of the sorted `to` ends.
  std::vector<uint32_t> to(edges.size());
  for (size_t e = 0; e < edges.size(); ++e) to[e] = edges[e].to;
  std::sort(to.begin(), to.end());
  auto out_begin = [&](uint32_t v) {
    return uint32_t(std::lower_bound(edges.begin(), edges.end(), BoundaryEdge{v, 0}) - edges.begin());
  };
  auto simple = [&](uint32_t v) {
    const uint32_t b = out_begin(v);
    if (b >= edges.size() || edges[b].from != v || (b + 1 < edges.size() && edges[b + 1].from == v)) return false;
    const auto in = std::equal_range(to.begin(), to.end(), v);
    return in.second - in.first == 1;
  };
  std::vector<uint8_t> visited(edges.size(), 0);
  std::vector<uint32_t> loop;
  for (uint32_t start = 0; start < edges.size(); ++start) {
    if (visited[start]) continue;
    loop.clear();
    bool closed = false, usable = true;
    for (uint32_t e = start;;) {
      visited[e] = 1;
      loop.push_back(edges[e].from);
      uint32_t v = edges[e].to;
      if (!simple(v)) { usable = false; break; }
      uint32_t next = out_begin(v);
      if (next == start) { closed = true; break; }
      if (visited[next]) { usable = false; break; }
      e = next;
    }
    if (!closed || !usable) {  // through a non-manifold boundary vertex: no strip there
      ++loops.skipped;
      continue;
    }
    loops.vertices.insert(loops.vertices.end(), loop.begin(), loop.end());
    loops.offsets.push_back(uint32_t(loops.vertices.size()));
  }
  return loops;
}

namespace {

// Appends an output vertex at p with no cluster, lying at the mean of the input vertices `from`.
// Returns its id.
uint32_t add_strip_vertex(DualMesh& dual, const float* p, std::span<const uint32_t> from) {
  const uint32_t id = dual.mesh.vertex_count();
  dual.mesh.positions.insert(dual.mesh.positions.end(), p, p + 3);
  dual.cluster_of_output_vertex.push_back(-1);
  dual.source_of_output_vertex.push_back({uint32_t(dual.source_vertices.size()), uint32_t(from.size())});
  dual.source_vertices.insert(dual.source_vertices.end(), from.begin(), from.end());
  ++dual.boundary_vertices_added;
  return id;
}

// The ring of clusters round a loop: for each change (a loop position k whose edge
// loop[k] → loop[k+1] changes cluster), the cluster the change leads into.
std::vector<int32_t> ring_of_changes(std::span<const uint32_t> loop, std::span<const uint32_t> changes,
                                     std::span<const int32_t> labels) {
  std::vector<int32_t> ring(changes.size());
  for (size_t t = 0; t < changes.size(); ++t) ring[t] = labels[loop[(changes[t] + 1) % loop.size()]];
  return ring;
}

// Closes a hole below the output resolution in the dual when the clusters around it are
// distinct: each change a → b of the loop (`changes`: loop positions k whose edge
// loop[k] → loop[k+1] changes cluster) gives the dual edge b → a on the hole's side, and the
// ring of those edges is triangulated (core/dual/hole_closing.h); a `narrow` hole (diameter
// below the closing one) whose ring has no such triangulation gets a fan from a vertex at the
// loop's centroid. A cluster met twice encloses the clusters between its two stretches: no disc
// over the hole has it as one vertex (it would be pinched), so such a loop keeps its strip:
// returns false. `diagonals`: the cluster pairs joined across the holes closed so far (sorted;
// dual::cluster_pair_key), barred from this one and extended by it (dragon → 1000: two holes
// side by side closed with the same diagonal, a dual edge with four faces, which the repair
// chased round the two rims for 8 rounds).
bool close_hole(const MeshView& mesh, std::span<const uint32_t> loop, std::span<const uint32_t> changes,
                std::span<const int32_t> labels, std::span<const uint32_t> output_of_cluster, bool narrow,
                std::vector<uint64_t>& diagonals, DualMesh& dual, std::vector<dual::Face>& faces) {
  const size_t n = loop.size(), m = changes.size();
  const std::vector<int32_t> ring = ring_of_changes(loop, changes, labels);
  std::vector<int32_t> sorted = ring;
  std::sort(sorted.begin(), sorted.end());
  if (std::adjacent_find(sorted.begin(), sorted.end()) != sorted.end()) return false;
  if (m == 3) {  // the edges r1 → r0, r2 → r1, r0 → r2
    faces.push_back(dual::rotate_smallest_first(output_of_cluster[ring[0]], output_of_cluster[ring[2]], output_of_cluster[ring[1]]));
    return true;
  }
  const auto triangles = dual::triangulate_hole_ring(mesh, loop, changes, ring, labels, diagonals);
  const size_t before = diagonals.size();
  for (const auto& t : triangles) {
    faces.push_back(dual::rotate_smallest_first(output_of_cluster[t[0]], output_of_cluster[t[1]], output_of_cluster[t[2]]));
    // Ring edges join clusters that meet along the loop, which no diagonal may join anyway.
    for (int k = 0; k < 3; ++k) diagonals.push_back(dual::cluster_pair_key(t[k], t[(k + 1) % 3]));
  }
  if (!triangles.empty()) {
    // The few new keys merged into the sorted ones: O(diagonals) per hole. Sorting them all
    // again was O(d log d) per hole, quadratic over a scan's holes (crude dragon ×20 → 200,000:
    // ~2,000 holes closed at every check of the repair; 48 s → 40 s in all).
    std::sort(diagonals.begin() + std::ptrdiff_t(before), diagonals.end());
    std::inplace_merge(diagonals.begin(), diagonals.begin() + std::ptrdiff_t(before), diagonals.end());
    diagonals.erase(std::unique(diagonals.begin(), diagonals.end()), diagonals.end());
    return true;
  }
  if (!narrow) return false;
  const float* P = mesh.positions.data();
  double c[3] = {0, 0, 0};
  for (uint32_t v : loop)
    for (int k = 0; k < 3; ++k) c[k] += P[3 * size_t(v) + k];
  const float centre[3] = {float(c[0] / double(n)), float(c[1] / double(n)), float(c[2] / double(n))};
  const uint32_t h = add_strip_vertex(dual, centre, loop);
  for (size_t t = 0; t < m; ++t)
    faces.push_back(dual::rotate_smallest_first(h, output_of_cluster[ring[t]], output_of_cluster[ring[(t + m - 1) % m]]));
  return true;
}

// Appends the §VI-D strip of every boundary loop: for each change of cluster a → b along the
// loop, a vertex p at the middle of that boundary edge and the triangles (p, b, a) and
// (p, p_next, b). Loops meeting fewer than three clusters, and loops below the output
// resolution (options.close_hole_diameter, close_hole_width), close instead; those that cannot
// (a cluster met twice round them) list that cluster with the loop in `open_holes` (may be null).
void add_boundary_strips(const MeshView& mesh, const BoundaryLoops& loops, std::span<const int32_t> labels,
                         std::span<const uint32_t> output_of_cluster, std::span<const uint32_t> cluster_size,
                         const DualMeshOptions& options, DualMesh& dual, std::vector<dual::Face>& faces,
                         std::vector<OpenHole>* open_holes) {
  const float* P = mesh.positions.data();
  dual.loops_skipped = loops.skipped;
  std::vector<uint64_t> diagonals;  // of the holes closed so far (close_hole)
  for (size_t l = 0; l + 1 < loops.offsets.size(); ++l) {
    std::span<const uint32_t> loop(loops.vertices.data() + loops.offsets[l], loops.offsets[l + 1] - loops.offsets[l]);
    const size_t n = loop.size();
    struct Edge {
      uint32_t from, to;
    };
    auto edge = [&](size_t k) { return Edge{loop[k], loop[(k + 1) % n]}; };
    // Cluster changes along the loop.
    std::vector<uint32_t> changes;
    bool labelled = true;
    for (uint32_t k = 0; k < loop.size(); ++k) {
      int32_t a = labels[edge(k).from], b = labels[edge(k).to];
      if (a < 0 || b < 0) { labelled = false; break; }
      if (a != b) changes.push_back(k);
    }
    if (!labelled) continue;
    if (changes.empty()) {  // the hole lies inside one cluster: its dual vertex covers it
      ++dual.holes_closed;
      continue;
    }
    if (changes.size() == 2) {
      // Two clusters around a hole: the dual edge between them crosses the hole, and the
      // interior triangles on either side of it already close the surface there. A strip
      // would fold onto that edge, so the hole is left closed (counted, not a defect).
      ++dual.holes_closed;
      continue;
    }
    // Clusters of one vertex all along the loop: the dual boundary is the input boundary
    // already (a component copied as it is); a strip would only add flat triangles.
    bool all_single = changes.size() == loop.size();
    for (uint32_t k = 0; all_single && k < loop.size(); ++k) all_single = cluster_size[labels[loop[k]]] == 1;
    if (all_single) continue;
    const bool narrow = options.close_hole_diameter > 0 && dual::diameter_below(mesh.positions, loop, options.close_hole_diameter);
    const bool slit = !narrow && options.close_hole_width > 0 && dual::loop_width(mesh.positions, loop) < options.close_hole_width;
    if ((narrow || slit) && close_hole(mesh, loop, changes, labels, output_of_cluster, narrow, diagonals, dual, faces)) {
      ++dual.holes_closed;
      continue;
    }
    if ((narrow || slit) && open_holes) {  // the clusters met twice keep it open
      std::vector<int32_t> ring = ring_of_changes(loop, changes, labels);
      std::sort(ring.begin(), ring.end());
      for (size_t i = 1; i < ring.size(); ++i)
        if (ring[i] == ring[i - 1]) open_holes->push_back({ring[i], uint32_t(l)});  // the caller dedupes
    }
    // One strip point per change, except that consecutive changes whose midpoints coincide
    // (coincident input vertices) share one point, so no strip triangle is flat; with a strip
    // spacing, also those closer than half of it, as long as the clusters meeting at the shared
    // point are distinct (a repeated one would give the point two fans).
    std::vector<std::array<float, 3>> points;
    std::vector<Edge> point_edges;  // the boundary edge each point is the midpoint of
    std::vector<uint32_t> point_of_change(changes.size());
    auto make_points = [&](double merge_distance) {
      points.clear();
      point_edges.clear();
      const double merge2 = merge_distance * merge_distance;
      std::vector<int32_t> run, first_run;  // clusters around the current (first) point
      auto distinct_from = [](const std::vector<int32_t>& r, int32_t c) { return std::find(r.begin(), r.end(), c) == r.end(); };
      auto close = [&](const std::array<float, 3>& p, const std::array<float, 3>& q) {
        double d2 = 0;
        for (int c = 0; c < 3; ++c) d2 += (double(p[c]) - q[c]) * (double(p[c]) - q[c]);
        return d2 < merge2;
      };
      for (uint32_t t = 0; t < changes.size(); ++t) {
        const Edge e = edge(changes[t]);
        std::array<float, 3> p;
        for (int c = 0; c < 3; ++c) p[c] = 0.5f * (P[3 * e.from + c] + P[3 * e.to + c]);
        if (!points.empty() && (points.back() == p || (close(p, points.back()) && distinct_from(run, labels[e.to])))) {
          point_of_change[t] = uint32_t(points.size() - 1);
          run.push_back(labels[e.to]);
          continue;
        }
        if (points.size() == 1) first_run = run;
        run = {labels[e.from], labels[e.to]};
        point_of_change[t] = uint32_t(points.size());
        points.push_back(p);
        point_edges.push_back(e);
      }
      if (points.size() == 1) first_run = run;
      // The last point joins the first: the last run ends with the cluster the first run starts with.
      bool wrap = points.size() > 1 && points.back() == points.front();
      if (!wrap && points.size() > 3 && close(points.back(), points.front())) {
        wrap = true;
        for (size_t i = 1; i < first_run.size() && wrap; ++i) wrap = distinct_from(run, first_run[i]);
      }
      if (wrap) {
        for (uint32_t t = 0; t < changes.size(); ++t)
          if (point_of_change[t] == points.size() - 1) point_of_change[t] = 0;
        points.pop_back();
        point_edges.pop_back();
      }
    };
    make_points(0.5 * options.strip_spacing);
    if (points.size() < 3 && options.strip_spacing > 0) make_points(0);  // a hole keeps its 3 points
    if (points.size() < 3) {
      ++dual.holes_closed;
      continue;
    }
    const double corner_d2 = 0.04 * options.strip_spacing * options.strip_spacing;  // (a fifth of it)²
    const uint32_t first_new = dual.mesh.vertex_count();
    for (size_t i = 0; i < points.size(); ++i) {
      const uint32_t ends[2] = {point_edges[i].from, point_edges[i].to};
      add_strip_vertex(dual, points[i].data(), ends);
    }
    for (uint32_t t = 0; t < changes.size(); ++t) {
      const Edge e = edge(changes[t]);
      uint32_t a = output_of_cluster[labels[e.from]], b = output_of_cluster[labels[e.to]];
      uint32_t p = first_new + point_of_change[t];
      uint32_t p_next = first_new + point_of_change[(t + 1) % changes.size()];
      faces.push_back(dual::rotate_smallest_first(p, b, a));
      if (p_next == p) continue;
      // Where the boundary bends inside b's stretch (corners), the chord p → p_next cuts them
      // and the triangle (p, p_next, b) can fold over b. Douglas–Peucker on the stretch: the
      // vertex farthest from a chord (beyond 30% of its length) becomes a strip vertex, then
      // both halves are checked again; the strip fans from b along p → corners → p_next.
      const size_t begin = (changes[t] + 1) % n;  // b's stretch: loop indices begin … begin+length−1
      const size_t length = (changes[(t + 1) % changes.size()] + n - begin) % n + 1;
      std::vector<uint32_t> chain = {p, p_next};           // output vertex ids
      std::vector<int64_t> chain_index = {-1, int64_t(length)};  // stretch positions (ends outside)
      for (size_t c = 0; c + 1 < chain.size();) {
        const float* pa = &dual.mesh.positions[3 * size_t(chain[c])];
        const float* pb = &dual.mesh.positions[3 * size_t(chain[c + 1])];
        double chord[3] = {double(pb[0]) - pa[0], double(pb[1]) - pa[1], double(pb[2]) - pa[2]};
        double chord2 = chord[0] * chord[0] + chord[1] * chord[1] + chord[2] * chord[2];
        int64_t far = -1;
        double far_d2 = std::max(0.09 * chord2, corner_d2);
        for (int64_t i = chain_index[c] + 1; i < chain_index[c + 1]; ++i) {
          const float* q = &P[3 * size_t(loop[(begin + size_t(i)) % n])];
          double d[3] = {double(q[0]) - pa[0], double(q[1]) - pa[1], double(q[2]) - pa[2]};
          double along = chord2 > 0 ? (d[0] * chord[0] + d[1] * chord[1] + d[2] * chord[2]) / chord2 : 0.0;
          along = std::clamp(along, 0.0, 1.0);
          double r[3] = {d[0] - along * chord[0], d[1] - along * chord[1], d[2] - along * chord[2]};
          double d2 = r[0] * r[0] + r[1] * r[1] + r[2] * r[2];
          if (d2 > far_d2) {
            far_d2 = d2;
            far = i;
          }
        }
        if (far < 0) {
          ++c;
          continue;
        }
        const uint32_t corner = loop[(begin + size_t(far)) % n];
        const uint32_t q = add_strip_vertex(dual, &P[3 * size_t(corner)], {&corner, 1});
        chain.insert(chain.begin() + std::ptrdiff_t(c + 1), q);
        chain_index.insert(chain_index.begin() + std::ptrdiff_t(c + 1), far);
      }
      for (size_t c = 0; c + 1 < chain.size(); ++c) faces.push_back(dual::rotate_smallest_first(chain[c], chain[c + 1], b));
    }
  }
}

}  // namespace

double typical_dual_edge(double area, uint32_t clusters) {
  return clusters > 0 && area > 0 ? std::sqrt(4.0 * area / (2.0 * clusters) / std::sqrt(3.0)) : 0.0;
}

std::vector<dual::Face> boundary_strip_faces(const MeshView& mesh, const BoundaryLoops& loops, std::span<const int32_t> labels,
                                         uint32_t cluster_count, std::span<const uint32_t> cluster_size,
                                         const DualMeshOptions& options, uint32_t& strip_vertices,
                                         std::vector<OpenHole>* open_holes) {
  // The strip code reads chord ends back from the output positions: give it a scratch dual
  // whose first cluster_count vertices stand for the clusters (identity numbering).
  DualMesh scratch;
  scratch.mesh.positions.assign(3 * size_t(cluster_count), 0.0f);
  scratch.cluster_of_output_vertex.assign(cluster_count, 0);
  scratch.source_of_output_vertex.assign(cluster_count, {});
  std::vector<uint32_t> identity(cluster_count);
  std::iota(identity.begin(), identity.end(), 0u);
  std::vector<dual::Face> faces;
  add_boundary_strips(mesh, loops, labels, identity, cluster_size, options, scratch, faces, open_holes);
  strip_vertices = scratch.mesh.vertex_count() - cluster_count;
  return faces;
}

DualMesh build_dual_mesh(const MeshView& mesh, std::span<const int32_t> labels, uint32_t cluster_count,
                         std::span<const double> cluster_positions, const DualMeshOptions& options,
                         const BoundaryLoops* boundary_loops, std::optional<dual::Triples> given) {
  DualMesh dual;
  // Non-empty clusters, in id order, become the output vertices.
  const std::vector<uint32_t> cluster_size = dual::cluster_sizes(mesh, labels, cluster_count);
  std::vector<uint32_t> output_of_cluster(cluster_count, UINT32_MAX);
  for (uint32_t c = 0; c < cluster_count; ++c) {
    if (cluster_size[c] == 0) continue;
    output_of_cluster[c] = dual.mesh.vertex_count();
    for (int k = 0; k < 3; ++k) dual.mesh.positions.push_back(float(cluster_positions[3 * size_t(c) + k]));
    dual.cluster_of_output_vertex.push_back(int32_t(c));
    dual.source_of_output_vertex.push_back({});
  }
  // The triples in cluster ids, renumbered: output_of_cluster is increasing on the non-empty
  // clusters, so the renumbered triples stay rotated, sorted and unique.
  dual::Triples triples = given ? std::move(*given) : dual::collect_triples(mesh, labels);
  std::vector<dual::Face>& faces = triples.faces;
  for (dual::Face& t : faces)
    for (uint32_t& x : t) x = output_of_cluster[x];
  uint64_t emitted = triples.emitted();
  if (options.boundary_strips) {
    std::vector<dual::Face> strips;
    if (boundary_loops) {
      add_boundary_strips(mesh, *boundary_loops, labels, output_of_cluster, cluster_size, options, dual, strips, nullptr);
    } else {
      BoundaryLoops loops = find_boundary_loops(mesh);
      add_boundary_strips(mesh, loops, labels, output_of_cluster, cluster_size, options, dual, strips, nullptr);
    }
    emitted += strips.size();
    dual::merge_faces(faces, std::move(strips));
  }
  dual.duplicate_faces_removed = emitted - faces.size();
  dual.mesh.triangles.reserve(faces.size() * 3);
  for (const dual::Face& t : faces) dual.mesh.triangles.insert(dual.mesh.triangles.end(), t.begin(), t.end());
  return dual;
}

std::vector<uint32_t> find_manifold_defects(const TriangleSoupView& mesh) {
  const uint64_t F = mesh.face_count();
  const uint32_t V = mesh.vertex_count();
  const uint32_t* T = mesh.triangles.data();
  std::vector<uint32_t> bad;
  // Faces with a repeated index flag their corners; the others go to the fan test as they are
  // (exact repeats included: the fan test flags an edge used twice in one direction).
  std::vector<dual::Face> faces;
  faces.reserve(F);
  for (uint64_t f = 0; f < F; ++f) {
    const dual::Face t = {T[3 * f], T[3 * f + 1], T[3 * f + 2]};
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) bad.insert(bad.end(), t.begin(), t.end());
    else faces.push_back(t);
  }
  std::vector<uint8_t> on_face(V, 0);  // V is the output's vertex count (K-sized)
  for (const dual::FanVerdict& v : dual::check_fans(faces, [](uint32_t) { return true; })) {
    on_face[v.vertex] = 1;
    if (v.defective) bad.push_back(v.vertex);
  }
  for (uint32_t v = 0; v < V; ++v)
    if (!on_face[v]) bad.push_back(v);  // on no face, or only on faces with a repeated index
  std::sort(bad.begin(), bad.end());
  bad.erase(std::unique(bad.begin(), bad.end()), bad.end());
  return bad;
}

DefectRemoval remove_manifold_defects(DualMesh& dual) {
  MeshBuffers& mesh = dual.mesh;
  std::vector<int32_t>& cluster_of_output_vertex = dual.cluster_of_output_vertex;
  std::vector<VertexSource>& source_of_output_vertex = dual.source_of_output_vertex;
  DefectRemoval removal;
  for (int iteration = 0; iteration < 64; ++iteration) {
    std::vector<uint32_t> defects = find_manifold_defects(mesh.view());
    if (defects.empty()) break;
    std::vector<uint8_t> bad(mesh.vertex_count(), 0);
    for (uint32_t v : defects) bad[v] = 1;
    size_t kept = 0;
    auto& T = mesh.triangles;
    for (size_t f = 0; f < T.size(); f += 3) {
      if (bad[T[f]] || bad[T[f + 1]] || bad[T[f + 2]]) {
        ++removal.faces_removed;
        continue;
      }
      T[kept] = T[f];
      T[kept + 1] = T[f + 1];
      T[kept + 2] = T[f + 2];
      kept += 3;
    }
    T.resize(kept);
    // Drop vertices left without faces, renumbering the rest in order.
    std::vector<uint32_t> new_id(mesh.vertex_count(), UINT32_MAX);
    for (uint32_t i : T) new_id[i] = 0;
    uint32_t next = 0;
    for (uint32_t v = 0; v < mesh.vertex_count(); ++v) {
      if (new_id[v] == UINT32_MAX) {
        ++removal.vertices_removed;
        continue;
      }
      new_id[v] = next;
      for (int c = 0; c < 3; ++c) mesh.positions[3 * size_t(next) + c] = mesh.positions[3 * size_t(v) + c];
      cluster_of_output_vertex[next] = cluster_of_output_vertex[v];
      source_of_output_vertex[next] = source_of_output_vertex[v];
      ++next;
    }
    mesh.positions.resize(3 * size_t(next));
    cluster_of_output_vertex.resize(next);
    source_of_output_vertex.resize(next);
    for (uint32_t& i : T) i = new_id[i];
  }
  return removal;
}

}  // namespace streamcvd
