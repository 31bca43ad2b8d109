#include "streamcvd/core/dual/component_topology.h"

#include <algorithm>
#include <numeric>

#include <tbb/blocked_range.h>
#include <tbb/combinable.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>

#include "streamcvd/core/mesh/union_find.h"

namespace streamcvd {
namespace {

constexpr uint32_t kNone = UINT32_MAX;

std::string with_commas(uint64_t n) {
  std::string s = std::to_string(n);
  for (int i = int(s.size()) - 3; i > 0; i -= 3) s.insert(size_t(i), ",");
  return s;
}

}  // namespace

std::vector<ComponentShape> input_component_shapes(const MeshView& mesh, std::span<const uint32_t> component_of_vertex,
                                                   uint32_t component_count, const BoundaryLoops& loops) {
  // χ = V − E + F per component from the CSR offsets alone: a component's edges are half its
  // vertices' degrees, its faces a third of their corners (the vertex → face lists hold one
  // entry per corner), both ends and all corners lying in the component. No list is read:
  // 17 bytes per vertex in vertex order (out of core, a fraction of the adjacency).
  // Integer sums: per-thread tables added up, the same for any thread count.
  struct Sums {
    int64_t vertices = 0;
    uint64_t degrees = 0, corners = 0;
    bool manifold = true;
  };
  tbb::combinable<std::vector<Sums>> partial([&] { return std::vector<Sums>(component_count); });
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, mesh.vertex_count(), 1u << 14), [&](const tbb::blocked_range<uint32_t>& r) {
    std::vector<Sums>& sums = partial.local();
    const RangeVisit visit(mesh, "checks", {r.begin(), r.end()}, kReadsFlags);  // and the offsets, read in order
    const uint64_t* vv = mesh.vertex_vertex_offsets.data();
    const uint64_t* vf = mesh.vertex_face_offsets.data();
    for (uint32_t v = r.begin(); v != r.end(); ++v) {
      const uint32_t c = component_of_vertex[v];
      if (c == kNone) continue;
      Sums& s = sums[c];
      ++s.vertices;
      s.degrees += vv[v + 1] - vv[v];
      s.corners += vf[v + 1] - vf[v];
      if (mesh.vertex_flags[v] & kVertexNonManifold) s.manifold = false;
    }
  });
  std::vector<Sums> sums(component_count);
  partial.combine_each([&](const std::vector<Sums>& part) {
    for (uint32_t c = 0; c < component_count; ++c) {
      sums[c].vertices += part[c].vertices;
      sums[c].degrees += part[c].degrees;
      sums[c].corners += part[c].corners;
      sums[c].manifold = sums[c].manifold && part[c].manifold;
    }
  });
  std::vector<ComponentShape> shapes(component_count);
  for (uint32_t c = 0; c < component_count; ++c) {
    shapes[c].faces = sums[c].corners / 3;
    shapes[c].euler = sums[c].vertices - int64_t(sums[c].degrees / 2) + int64_t(shapes[c].faces);
    shapes[c].manifold = sums[c].manifold;
  }
  for (size_t l = 0; l + 1 < loops.offsets.size(); ++l) {
    if (loops.offsets[l] == loops.offsets[l + 1]) continue;
    const uint32_t c = component_of_vertex[loops.vertices[loops.offsets[l]]];
    if (c != kNone) ++shapes[c].boundary_loops;
  }
  if (loops.skipped > 0)  // chains through non-manifold boundary vertices: no reliable count
    for (ComponentShape& s : shapes) s.manifold = s.manifold && loops.skipped == 0;
  return shapes;
}

ComponentCheck check_component_topology(std::span<const ComponentShape> input, const TriangleSoupView& output,
                                        std::span<const int32_t> cluster_of_output_vertex,
                                        std::span<const uint32_t> component_of_cluster, size_t max_problems) {
  ComponentCheck check;
  const uint32_t V = output.vertex_count();
  const uint64_t F = output.face_count();
  // Output components: vertices joined by faces.
  DisjointSets<uint32_t> uf(V);
  std::vector<uint8_t> referenced(V, 0);
  for (uint64_t f = 0; f < F; ++f) {
    const uint32_t* t = &output.triangles[3 * f];
    uf.unite(t[0], t[1]), uf.unite(t[1], t[2]);
    referenced[t[0]] = referenced[t[1]] = referenced[t[2]] = 1;
  }
  std::vector<uint32_t> id(V, kNone);
  uint32_t components = 0;
  for (uint32_t v = 0; v < V; ++v)
    if (referenced[v] && uf.find(v) == v) id[v] = components++;
  check.output_components = components;
  // χ and boundary loops per output component: edges by sorting (the output is small).
  std::vector<int64_t> euler(components, 0);
  std::vector<uint64_t> loops(components, 0);
  for (uint32_t v = 0; v < V; ++v)
    if (referenced[v]) ++euler[id[uf.find(v)]];
  std::vector<uint64_t> edges;  // (min << 32 | max)
  edges.reserve(3 * F);
  for (uint64_t f = 0; f < F; ++f) {
    ++euler[id[uf.find(output.triangles[3 * f])]];
    for (int k = 0; k < 3; ++k) {
      const uint32_t a = output.triangles[3 * f + k], b = output.triangles[3 * f + (k + 1) % 3];
      if (a != b) edges.push_back(uint64_t(std::min(a, b)) << 32 | std::max(a, b));
    }
  }
  tbb::parallel_sort(edges.begin(), edges.end());
  DisjointSets<uint32_t> boundary(V);
  std::vector<uint8_t> on_boundary(V, 0);
  for (size_t i = 0; i < edges.size();) {
    size_t j = i;
    while (j < edges.size() && edges[j] == edges[i]) ++j;
    const uint32_t a = uint32_t(edges[i] >> 32), b = uint32_t(edges[i]);
    --euler[id[uf.find(a)]];
    if (j - i == 1) boundary.unite(a, b), on_boundary[a] = on_boundary[b] = 1;
    i = j;
  }
  for (int64_t e : euler) check.output_euler_characteristic += e;
  for (uint32_t v = 0; v < V; ++v)
    if (on_boundary[v] && boundary.find(v) == v) ++loops[id[uf.find(v)]], ++check.output_boundary_loops;
  // Which input component each output component comes from (through any of its clusters).
  std::vector<uint32_t> source(components, kNone);
  for (uint32_t v = 0; v < V; ++v) {
    const int32_t c = cluster_of_output_vertex[v];
    if (!referenced[v] || c < 0 || size_t(c) >= component_of_cluster.size()) continue;
    source[id[uf.find(v)]] = component_of_cluster[size_t(c)];
  }
  std::vector<uint32_t> pieces(input.size(), 0);
  std::vector<uint32_t> output_of(input.size(), kNone);
  for (uint32_t o = 0; o < components; ++o)
    if (source[o] != kNone && source[o] < input.size()) ++pieces[source[o]], output_of[source[o]] = o;
  std::vector<uint8_t> expected(input.size(), 0);
  for (uint32_t comp : component_of_cluster)
    if (comp < input.size()) expected[comp] = 1;
  auto problem = [&](uint32_t c, const std::string& what) {
    if (check.problems.size() < max_problems)
      check.problems.push_back("component " + std::to_string(c) + " (" + with_commas(input[c].faces) +
                               " input faces): " + what);
    else if (check.problems.size() == max_problems)
      check.problems.push_back("...");
  };
  for (uint32_t c = 0; c < input.size(); ++c) {
    if (!expected[c]) continue;
    ++check.input_components;
    check.input_boundary_loops += input[c].boundary_loops;
    check.input_euler_characteristic += input[c].euler;
    if (pieces[c] != 1) {
      problem(c, pieces[c] == 0 ? "missing from the output" : "split into " + std::to_string(pieces[c]) + " pieces");
      continue;
    }
    const uint32_t o = output_of[c];
    ComponentShape out;
    out.euler = euler[o];
    out.boundary_loops = loops[o];
    if (out.boundary_loops > input[c].boundary_loops)
      problem(c, std::to_string(out.boundary_loops) + " boundary loops, the input has " +
                     std::to_string(input[c].boundary_loops));
    else if (input[c].manifold && out.genus() > input[c].genus())
      problem(c, "genus " + std::to_string(out.genus()) + ", the input has " + std::to_string(input[c].genus()));
  }
  if (check.problems.size() > max_problems) check.problems.resize(max_problems + 1);
  return check;
}

}  // namespace streamcvd
