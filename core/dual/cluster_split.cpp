// split_cluster (core/dual/cluster_repair.h): a cluster cut in parts grown inside its label
// (core/mesh/label_flood.h), from farthest-point seeds or, at a defect, from the arcs or paths
// that separate what makes its dual vertex not a disc.
#include <algorithm>
#include <iterator>
#include <numeric>

#include "streamcvd/core/dual/cluster_repair.h"
#include "streamcvd/core/dual/dual_topology.h"
#include "streamcvd/core/mesh/label_flood.h"

namespace streamcvd::detail {

namespace {

// Position of vertex v in the ascending member list of its cluster.
uint32_t slot_of(std::span<const uint32_t> members, uint32_t v) {
  return uint32_t(std::lower_bound(members.begin(), members.end(), v) - members.begin());
}

// The members of cluster c next to another cluster, as (that cluster, member), sorted: runs of
// one neighbour's frontier.
std::vector<std::pair<int32_t, uint32_t>> frontier_contacts(const MeshView& mesh, std::span<const int32_t> labels,
                                                            std::span<const uint32_t> members) {
  const int32_t c = labels[members[0]];
  std::vector<std::pair<int32_t, uint32_t>> contacts;
  for (uint32_t v : members)
    for (uint32_t n : mesh.neighbours(v))
      if (labels[n] >= 0 && labels[n] != c) contacts.push_back({labels[n], v});
  dual::sort_unique(contacts);
  return contacts;
}

// The members on c's frontier with any other cluster, sorted.
std::vector<uint32_t> frontier_members(std::span<const std::pair<int32_t, uint32_t>> contacts) {
  std::vector<uint32_t> frontier;
  for (const auto& [y, v] : contacts) frontier.push_back(v);
  dual::sort_unique(frontier);
  return frontier;
}

// The two largest connected parts (1-ring adjacency inside the cluster) of `vertices`, members
// of the cluster, largest first: one when they are connected. O(Σ degree + cluster size).
std::vector<std::vector<uint32_t>> two_largest_parts(const MeshView& mesh, std::span<const int32_t> labels,
                                                     std::span<const uint32_t> members,
                                                     std::span<const uint32_t> vertices, SplitScratch& scratch) {
  const int32_t c = labels[members[0]];
  auto slot = [&](uint32_t v) { return slot_of(members, v); };
  scratch.stamp.assign(members.size(), 0);  // 1: in `vertices`, 2: reached
  for (uint32_t v : vertices) scratch.stamp[slot(v)] = 1;
  std::vector<std::vector<uint32_t>> parts;
  for (uint32_t start : vertices) {
    if (scratch.stamp[slot(start)] == 2) continue;
    std::vector<uint32_t> part = {start};
    scratch.stamp[slot(start)] = 2;
    for (size_t h = 0; h < part.size(); ++h)
      for (uint32_t n : mesh.neighbours(part[h]))
        if (labels[n] == c && scratch.stamp[slot(n)] == 1) {
          scratch.stamp[slot(n)] = 2;
          part.push_back(n);
        }
    parts.push_back(std::move(part));
  }
  std::stable_sort(parts.begin(), parts.end(), [](const auto& a, const auto& b) { return a.size() > b.size(); });
  if (parts.size() > 2) parts.resize(2);
  return parts;
}

// The arcs along which cluster c meets a neighbour y: the input edges from c to y, joined
// when a triangle holds two of them (its corners labelled c and y only); a triangle with a
// third cluster ends an arc. For the first neighbour met along two arcs or more, the members
// of c on its two longest arcs (a member on both given to one); nothing when every neighbour
// is met along one arc. Edge-based: in a small cluster the members on two arcs are often
// adjacent, and their vertex sets then look like one arc. O(Σ degree · log) over the members.
std::vector<std::vector<uint32_t>> two_longest_arcs(const MeshView& mesh, std::span<const int32_t> labels,
                                                    std::span<const uint32_t> members) {
  const int32_t c = labels[members[0]];
  using Edge = std::pair<int32_t, uint64_t>;  // (y, member << 32 | vertex of y)
  std::vector<Edge> edges;
  for (uint32_t u : members)
    for (uint32_t w : mesh.neighbours(u))
      if (labels[w] >= 0 && labels[w] != c) edges.push_back({labels[w], uint64_t(u) << 32 | w});
  dual::sort_unique(edges);
  if (edges.size() < 2) return {};
  std::vector<uint32_t> parent(edges.size());
  std::iota(parent.begin(), parent.end(), 0u);
  auto find = [&](uint32_t a) {
    while (parent[a] != a) a = parent[a] = parent[parent[a]];
    return a;
  };
  auto index_of = [&](int32_t y, uint32_t u, uint32_t w) {
    return uint32_t(std::lower_bound(edges.begin(), edges.end(), Edge{y, uint64_t(u) << 32 | w}) - edges.begin());
  };
  for (uint32_t u : members)
    for (uint32_t f : mesh.faces_of(u)) {
      const uint32_t* t = &mesh.triangles[3 * size_t(f)];
      int32_t y = -1;
      bool two_labels = true;
      for (int k = 0; k < 3; ++k) {
        const int32_t l = labels[t[k]];
        if (l == c) continue;
        if (l < 0 || (y >= 0 && l != y)) two_labels = false;
        y = l;
      }
      if (!two_labels || y < 0) continue;
      // The face's two c–y edges.
      uint32_t found[2], n = 0;
      for (int k = 0; k < 3; ++k) {
        const uint32_t a = t[k], b = t[(k + 1) % 3];
        if (labels[a] == c && labels[b] == y) found[n++] = index_of(y, a, b);
        else if (labels[a] == y && labels[b] == c) found[n++] = index_of(y, b, a);
      }
      if (n == 2) parent[find(found[0])] = find(found[1]);
    }
  for (size_t i = 0; i < edges.size();) {
    size_t j = i;
    while (j < edges.size() && edges[j].first == edges[i].first) ++j;
    // Edges per arc of this neighbour, by root.
    std::vector<std::pair<uint32_t, uint32_t>> roots;  // (root, edge)
    for (size_t e = i; e < j; ++e) roots.push_back({find(uint32_t(e)), uint32_t(e)});
    std::sort(roots.begin(), roots.end());
    std::vector<std::pair<size_t, size_t>> runs;  // (edge count, first index in roots)
    for (size_t a = 0; a < roots.size();) {
      size_t b = a;
      while (b < roots.size() && roots[b].first == roots[a].first) ++b;
      runs.push_back({b - a, a});
      a = b;
    }
    i = j;
    if (runs.size() < 2) continue;
    std::stable_sort(runs.begin(), runs.end(), [](const auto& x, const auto& y) { return x.first > y.first; });
    std::vector<std::vector<uint32_t>> arcs(2);
    for (int k = 0; k < 2; ++k) {
      for (size_t r = runs[k].second; r < runs[k].second + runs[k].first; ++r)
        arcs[k].push_back(uint32_t(edges[roots[r].second].second >> 32));
      dual::sort_unique(arcs[k]);
    }
    // Members on both arcs (a pinch: the two arcs meet at one member of c) go to one of them:
    // to the longer arc, unless the other would be left with none.
    std::vector<uint32_t> both, only[2];
    std::set_intersection(arcs[0].begin(), arcs[0].end(), arcs[1].begin(), arcs[1].end(), std::back_inserter(both));
    for (int k = 0; k < 2; ++k)
      std::set_difference(arcs[k].begin(), arcs[k].end(), both.begin(), both.end(), std::back_inserter(only[k]));
    if (only[0].empty() && only[1].empty()) continue;
    const int to = only[1].empty() ? 1 : 0;
    arcs[to] = std::move(only[to]);
    arcs[to].insert(arcs[to].end(), both.begin(), both.end());
    arcs[1 - to] = std::move(only[1 - to]);
    if (!arcs[0].empty() && !arcs[1].empty()) return arcs;
  }
  return {};
}

// Seeds that cut a defective cluster where its dual vertex is not a disc, as two groups of
// members, or nothing when its frontier is one arc per neighbour and one part in all.
// - c meets a neighbour y along several arcs (the dual edge c–y has four faces): the two
//   largest arcs. A farthest-point split cuts such a cluster along its length, and each half
//   still meets y twice (dragon → 1000: the clusters at a tooth were halved 30 → 21 → 12 → 10
//   members over four rounds before the defect went).
// - c is a band (its frontier has several parts: a ring round a thin feature, two fans in the
//   dual): two paths across it, from one part to the other, on opposite sides; grown from the
//   parts themselves, the halves would be two bands again (elephant → 100: a 6-member half
//   between two clusters, dissolved back, 40 rounds running).
// Paths across a band (its frontier in two parts or more), `count` of them, from its largest
// frontier part to the second: the shortest one, then each next from the member of the first
// part farthest from the paths so far, kept apart from them. For a ring, the parts are its
// members next to the clusters of its first side and of its second: a ring one member wide
// somewhere has its frontier in one part, and the sides still tell where to cut across.
// Parts grown from the paths each hold one, so each reaches both frontier parts: cuts across.
// (Parts grown from far-apart points of one frontier part need not: the far end of a band
// longer than it is round lies at equal hop distance from both and goes to one of them.)
// Fewer than `count` when the band is too narrow for them. O(count · cluster size · log).
std::vector<std::vector<uint32_t>> paths_across_band(const MeshView& mesh, std::span<const int32_t> labels,
                                                     std::span<const uint32_t> members, size_t count,
                                                     SplitScratch& scratch, const Ring* ring) {
  const int32_t c = labels[members[0]];
  auto slot = [&](uint32_t v) { return slot_of(members, v); };
  std::vector<std::vector<uint32_t>> parts;
  std::vector<uint8_t> part_of(members.size(), 0);  // 1, 2: in that frontier part
  if (ring) {  // a member next to both sides is in part 2, and a source too
    parts.resize(2);
    for (const auto& [y, v] : frontier_contacts(mesh, labels, members))
      for (uint8_t k = 0; k < 2; ++k)
        if (std::binary_search(ring->sides[k].begin(), ring->sides[k].end(), y)) {
          parts[k].push_back(v);
          part_of[slot(v)] = std::max<uint8_t>(part_of[slot(v)], uint8_t(k + 1));
        }
    for (auto& part : parts) dual::sort_unique(part);
    if (parts[0].empty() || parts[1].empty()) return {};
  } else {
    parts = two_largest_parts(mesh, labels, members, frontier_members(frontier_contacts(mesh, labels, members)), scratch);
    if (parts.size() < 2) return {};
    for (uint8_t k = 0; k < 2; ++k)
      for (uint32_t v : parts[k]) part_of[slot(v)] = uint8_t(k + 1);
  }
  std::vector<uint32_t> parent(members.size(), UINT32_MAX);
  // The shortest path (BFS inside c, avoiding the members stamped 1 in scratch.stamp) from
  // `sources` to frontier part 2, from its part-2 end back to a source; empty when none.
  auto path_to_part2 = [&](std::span<const uint32_t> sources) {
    for (uint32_t v : sources) parent[slot(v)] = UINT32_MAX;
    flood_label(mesh, labels, c, sources, slot, scratch.stamp, 1, scratch.queue,
                [&](uint32_t from, uint32_t v) { parent[slot(v)] = from; });
    std::vector<uint32_t> path;
    for (uint32_t v : scratch.queue)
      if (part_of[slot(v)] == 2) {
        for (uint32_t x = v; x != UINT32_MAX; x = parent[slot(x)]) path.push_back(x);
        break;
      }
    return path;
  };
  scratch.stamp.assign(members.size(), 0);
  std::vector<std::vector<uint32_t>> paths;
  paths.push_back(path_to_part2(parts[0]));
  if (paths[0].empty()) return {};
  std::vector<uint32_t> on_paths = paths[0];
  while (paths.size() < count) {
    // The member of the first part farthest from the paths so far.
    scratch.stamp.assign(members.size(), 0);
    flood_label(mesh, labels, c, on_paths, slot, scratch.stamp, 1, scratch.queue, [](uint32_t, uint32_t) {});
    uint32_t far = UINT32_MAX;
    for (auto it = scratch.queue.rbegin(); it != scratch.queue.rend() && far == UINT32_MAX; ++it)
      if (part_of[slot(*it)] == 1) far = *it;
    if (far == UINT32_MAX || std::find(on_paths.begin(), on_paths.end(), far) != on_paths.end()) break;
    // Preferably not next to them either (parts that touch along a path's length do not part
    // the band there); in a band a few members wide, through their neighbours; failing that,
    // the next part grows from the far member alone.
    std::vector<uint32_t> next;
    for (const bool clear_of_neighbours : {true, false}) {
      scratch.stamp.assign(members.size(), 0);
      for (uint32_t v : on_paths) {
        scratch.stamp[slot(v)] = 1;
        if (clear_of_neighbours)
          for (uint32_t n : mesh.neighbours(v))
            if (labels[n] == c && n != far) scratch.stamp[slot(n)] = 1;
      }
      next = path_to_part2({&far, 1});
      if (!next.empty()) break;
    }
    if (next.empty()) next = {far};
    on_paths.insert(on_paths.end(), next.begin(), next.end());
    paths.push_back(std::move(next));
  }
  return paths;
}

// Seeds that cut a defective cluster where its dual vertex is not a disc, as groups of
// members, or nothing when its frontier is one arc per neighbour and one part in all.
// - c meets a neighbour y along several arcs (the dual edge c–y has four faces): the two
//   largest arcs. A farthest-point split cuts such a cluster along its length, and each half
//   still meets y twice (dragon → 1000: the clusters at a tooth were halved 30 → 21 → 12 → 10
//   members over four rounds before the defect went).
// - c is a band (its frontier has several parts: a ring round a thin feature, two fans in the
//   dual): two paths across it, from one part to the other, on opposite sides; grown from the
//   parts themselves, the halves would be two bands again (elephant → 100: a 6-member half
//   between two clusters, dissolved back, 40 rounds running).
std::vector<std::vector<uint32_t>> defect_cut_seeds(const MeshView& mesh, std::span<const int32_t> labels,
                                                    std::span<const uint32_t> members, SplitScratch& scratch) {
  std::vector<std::vector<uint32_t>> arcs = two_longest_arcs(mesh, labels, members);
  if (!arcs.empty()) return arcs;
  std::vector<std::vector<uint32_t>> paths = paths_across_band(mesh, labels, members, 2, scratch, nullptr);
  return paths.size() == 2 ? paths : std::vector<std::vector<uint32_t>>{};
}

// The vertices of c's two longest stretches along `loop` (runs of consecutive loop vertices
// labelled c, cyclically), longest first; fewer when c meets the loop in fewer stretches. A cut
// grown from them leaves one stretch in each part: a hole c met twice then has distinct
// clusters round it and can close. O(loop size).
std::vector<std::vector<uint32_t>> two_longest_stretches(std::span<const int32_t> labels, int32_t c,
                                                         std::span<const uint32_t> loop) {
  const size_t n = loop.size();
  size_t start = 0;  // a loop position not labelled c, so that no stretch wraps past the end
  while (start < n && labels[loop[start]] == c) ++start;
  if (start == n) return {};
  std::vector<std::vector<uint32_t>> stretches;
  for (size_t i = 1; i <= n; ++i) {
    const uint32_t v = loop[(start + i) % n];
    if (labels[v] != c) continue;
    if (labels[loop[(start + i - 1) % n]] != c) stretches.emplace_back();
    stretches.back().push_back(v);
  }
  if (stretches.size() < 2) return {};
  std::stable_sort(stretches.begin(), stretches.end(), [](const auto& a, const auto& b) { return a.size() > b.size(); });
  stretches.resize(2);
  return stretches;
}

// Labels `members` (all of cluster c, ascending) in parts grown from `groups` (disjoint
// members; group 0 keeps c, group k > 0 takes new_labels[k − 1]), each part connected and
// holding its group. Each member joins the group nearest in hops; when that leaves a part
// under a quarter of the mean part size, the parts are regrown balanced: the part with the
// fewest members takes the next member of its own queue. A short arc or path near a long one
// otherwise gets a sliver (dragon → 1000 seed 51: a 600-member cluster meeting a neighbour
// along arcs of 14 and 3 members lost a 10-member sliver a round for 4 rounds, each sliver a
// new defect). O(cluster size · (parts + log cluster size)).
void grow_parts_from_groups(const MeshView& mesh, std::span<int32_t> labels, std::span<const uint32_t> members,
                            std::span<const std::vector<uint32_t>> groups, std::span<const int32_t> new_labels,
                            SplitScratch& scratch) {
  const int32_t c = labels[members[0]];
  auto slot = [&](uint32_t v) { return slot_of(members, v); };
  auto label_of_group = [&](size_t k) { return k == 0 ? c : new_labels[k - 1]; };
  auto label_groups = [&] {
    scratch.stamp.assign(members.size(), 0);
    for (size_t k = 1; k < groups.size(); ++k)
      for (uint32_t v : groups[k]) labels[v] = label_of_group(k);
  };
  label_groups();
  std::vector<uint32_t> sources;
  for (const std::vector<uint32_t>& g : groups) sources.insert(sources.end(), g.begin(), g.end());
  flood_label(mesh, labels, c, sources, slot, scratch.stamp, 1, scratch.queue,
              [&](uint32_t from, uint32_t v) { labels[v] = labels[from]; });
  std::vector<size_t> size(groups.size(), 0);
  for (uint32_t v : members)
    for (size_t k = 0; k < groups.size(); ++k)
      if (labels[v] == label_of_group(k)) ++size[k];
  if (4 * groups.size() * *std::min_element(size.begin(), size.end()) >= members.size()) return;
  for (uint32_t v : members) labels[v] = c;
  label_groups();
  std::vector<std::vector<uint32_t>> queue(groups.begin(), groups.end());
  std::vector<size_t> head(groups.size(), 0);
  for (size_t k = 0; k < groups.size(); ++k) {
    size[k] = groups[k].size();
    for (uint32_t v : groups[k]) scratch.stamp[slot(v)] = 1;
  }
  for (;;) {
    size_t next = groups.size();
    for (size_t k = 0; k < groups.size(); ++k)
      if (head[k] < queue[k].size() && (next == groups.size() || size[k] < size[next])) next = k;
    if (next == groups.size()) break;
    const uint32_t u = queue[next][head[next]++];
    for (uint32_t n : mesh.neighbours(u))
      if (labels[n] == c && scratch.stamp[slot(n)] == 0) {
        scratch.stamp[slot(n)] = 1;
        labels[n] = label_of_group(next);
        queue[next].push_back(n);
        ++size[next];
      }
  }
}

}  // namespace

uint32_t split_cluster(const MeshView& mesh, std::span<int32_t> labels, std::span<const uint32_t> members,
                       std::span<const int32_t> new_labels, SplitScratch& scratch, bool at_defect,
                       const Ring* ring, std::span<const uint32_t> hole_loop) {
  if (members.size() < 2 || new_labels.empty()) return 0;
  const int32_t c = labels[members[0]];
  std::vector<uint32_t>& queue = scratch.queue;
  auto slot = [&](uint32_t v) { return slot_of(members, v); };
  if (new_labels.size() == 1 && !hole_loop.empty()) {
    const std::vector<std::vector<uint32_t>> groups = two_longest_stretches(labels, c, hole_loop);
    if (groups.size() == 2) {
      grow_parts_from_groups(mesh, labels, members, groups, new_labels, scratch);
      return 1;
    }
  }
  if (at_defect) {
    // One new label: the arcs or paths of defect_cut_seeds; more (a ring): paths across it.
    const std::vector<std::vector<uint32_t>> groups =
        new_labels.size() == 1 ? defect_cut_seeds(mesh, labels, members, scratch)
                               : paths_across_band(mesh, labels, members, new_labels.size() + 1, scratch, ring);
    if (groups.size() == new_labels.size() + 1) {
      grow_parts_from_groups(mesh, labels, members, groups, new_labels, scratch);
      return uint32_t(new_labels.size());
    }
  }
  scratch.stamp.assign(members.size(), 0);
  scratch.next_mark = 1;
  // The member farthest (in hops inside c) from every source: the last one a flood reaches.
  auto farthest = [&](std::span<const uint32_t> sources) {
    flood_label(mesh, labels, c, sources, slot, scratch.stamp, scratch.next_mark++, queue, [](uint32_t, uint32_t) {});
    return queue.back();
  };
  // Farthest-point seeds: the first is far from an arbitrary member, each next one is the
  // member farthest from all seeds chosen so far.
  std::vector<uint32_t> seeds;
  const uint32_t first = members[0];
  seeds.push_back(farthest({&first, 1}));
  if (queue.size() < members.size()) {
    // A cluster in pieces: its farthest points lie in the first piece, which a farthest-point
    // split could never part from the rest (dragon → 1000: an 8-member cluster with a stray
    // member, one seed found, 40 rounds). The piece of the first member not reached is cut off.
    const uint32_t mark = scratch.next_mark - 1;
    const auto stray =
        std::find_if(members.begin(), members.end(), [&](uint32_t v) { return scratch.stamp[slot(v)] != mark; });
    labels[*stray] = new_labels[0];
    flood_label(mesh, labels, c, {&*stray, 1}, slot, scratch.stamp, scratch.next_mark++, queue,
                [&](uint32_t from, uint32_t v) { labels[v] = labels[from]; });
    return 1;
  }
  while (seeds.size() < new_labels.size() + 1 && seeds.size() < members.size()) {
    const uint32_t s = farthest(seeds);
    if (std::find(seeds.begin(), seeds.end(), s) != seeds.end()) break;
    seeds.push_back(s);
  }
  if (seeds.size() < 2) return 0;
  // Multi-source flood: each member joins the seed that reaches it first; every part connected.
  for (size_t k = 1; k < seeds.size(); ++k) labels[seeds[k]] = new_labels[k - 1];
  flood_label(mesh, labels, c, seeds, slot, scratch.stamp, scratch.next_mark++, queue,
              [&](uint32_t from, uint32_t v) { labels[v] = labels[from]; });
  return uint32_t(seeds.size() - 1);
}

bool parts_are_discs(const MeshView& mesh, std::span<const int32_t> labels, std::span<const uint32_t> members,
                     std::span<const int32_t> parts, dual::FanScratch& scratch) {
  auto in_parts = [&](uint32_t x) { return std::find(parts.begin(), parts.end(), int32_t(x)) != parts.end(); };
  std::vector<dual::Face> faces;
  for (uint32_t v : members)
    for (uint32_t f : mesh.faces_of(v)) {
      dual::Face face;
      if (dual::face_triple(&mesh.triangles[3 * size_t(f)], labels, face) &&
          (in_parts(face[0]) || in_parts(face[1]) || in_parts(face[2])))
        faces.push_back(face);
    }
  dual::sort_unique(faces);
  std::vector<dual::Face> fan;
  for (const int32_t x : parts) {
    fan.clear();
    for (const dual::Face& f : faces)
      if (std::find(f.begin(), f.end(), uint32_t(x)) != f.end()) fan.push_back(f);
    if (fan.empty() || dual::fan_defective(uint32_t(x), fan, scratch)) return false;
  }
  return true;
}

bool frontier_in_one_part(const MeshView& mesh, std::span<const int32_t> labels, std::span<const uint32_t> members,
                          SplitScratch& scratch) {
  return two_largest_parts(mesh, labels, members, frontier_members(frontier_contacts(mesh, labels, members)), scratch)
             .size() < 2;
}

}  // namespace streamcvd::detail
