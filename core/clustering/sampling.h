// The start of a clustering (paper §VI-G): how many clusters each connected component gets,
// the initial regions grown from weighted random seeds, and the absorption of vertices left
// free. All of it works range by range (the store's chunks, sampling_ranges), so memory is one
// range's scratch per thread plus K-sized tables, and the result does not depend on the thread
// count or the storage (DESIGN.md §4).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "streamcvd/core/clustering/item_data.h"
#include "streamcvd/core/mesh/chunked_components.h"
#include "streamcvd/core/mesh/large_array.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

enum class SmallComponents { Keep, Drop };

/// "keep" or "drop" (the CLI's, the Python binding's and the report's spelling). O(1).
const char* small_components_name(SmallComponents mode);
/// Parses "keep" or "drop"; false (`out` unchanged) when the text is neither.
bool parse_small_components(std::string_view text, SmallComponents& out);

/// How many clusters each connected component of the mesh gets.
struct ComponentBudget {
  /// Component of each vertex (V entries, from the storage given to plan_component_budget),
  /// numbered by smallest vertex; UINT32_MAX (kNoComponent) for isolated vertices.
  LargeArray<uint32_t> component_of_vertex;
  std::vector<uint32_t> clusters_per_component;
  std::vector<uint32_t> vertices_per_component;
  std::vector<uint8_t> component_closed;     ///< 1 when the component has no boundary vertex
  uint32_t total_clusters = 0;               ///< Σ clusters_per_component (may differ from N)
  uint32_t small_components_kept = 0;        ///< components given the minimum to stay a surface
  uint32_t components_dropped = 0;           ///< components given no cluster (Drop mode, sheets)
  uint32_t sheets_dropped = 0;               ///< of those, cut sheets (drop_touching_small)
  std::string note;                          ///< why total_clusters ≠ N, when it is
};

/// Splits N clusters over the vertex-connected components in proportion to their weight
/// (largest remainder). A component too small for its share gets min(4 closed / 3 open, its
/// vertex count) clusters, or one per vertex when it has at most 16 (Keep), or none (Drop);
/// kept small components take at most a fifth of N (the lightest are dropped beyond it, with a
/// note). No component gets more clusters than vertices.
/// Components come from the chunk-wise union-find (core/mesh/chunked_components.h) over the ranges
/// of sampling_ranges(mesh): memory is one range per thread plus the frontier records, and
/// component_of_vertex is allocated from `storage` and written range by range.
/// O(V + E), TBB-parallel over ranges; the result does not depend on the thread count or the
/// storage. With drop_touching_small, a small component that shares a vertex position with
/// another (a sheet the topology cleaning cut off: core/mesh/coincident_components.h) is
/// dropped even under Keep, and so is such a closed one of any size that encloses no volume
/// (|volume| < 1e-3 area^1.5: a double layer, both sides of one surface); both are counted in
/// sheets_dropped. One more O(V) pass when there are several components, and one over the
/// faces of the closed touching ones.
ComponentBudget plan_component_budget(const MeshView& mesh, const ItemData& items, uint32_t clusters,
                                      SmallComponents small_components, ArrayStorage& storage,
                                      bool drop_touching_small = false);

/// Initial sampling (§VI-G), range by range (the store's chunks, see sampling_ranges). Each
/// component's clusters are shared over the ranges it touches in proportion to its weight there
/// (largest remainder, at most one cluster per vertex: the totals are exact; a part too light
/// for a cluster may get none). In each range, seeds are drawn in a weighted random order (the
/// exponential race, RNG seeded by (seed, range index)) and regions grown from them over free
/// vertices of the range until each holds D = component weight / its cluster count (eq. 19);
/// when a part runs out of free vertices, single vertices are taken from its clusters (never
/// one that would cut its cluster). Free vertices are then absorbed (absorb_free_vertices).
/// Returns labels (V entries from `storage`) in [0, budget.total_clusters), −1 only for isolated
/// vertices and vertices of components without clusters; every cluster is non-empty and
/// connected. Labels are numbered by range, then by first vertex inside the range (store order).
/// Memory: the labels, plus one range's scratch per thread (~32 bytes per vertex of the largest
/// range, at most 2^20 vertices) and K-sized tables. O(V + E), TBB-parallel over ranges; the labels depend only on the
/// mesh, the items, the budget and the seed (not on the thread count or the storage).
/// Throws std::invalid_argument when the budget was made for another mesh.
LargeArray<int32_t> initial_sampling(const MeshView& mesh, const ItemData& items, const ComponentBudget& budget,
                                     uint64_t seed, ArrayStorage& storage);

/// The vertex ranges the budget, the sampling and the absorption of free vertices work on: the
/// store's chunks, cut by chunk_ranges into at least min(16, V / 65536) ranges (a store of one
/// chunk still runs on every thread, a small mesh stays one range), or all vertices as one range
/// for a view without a chunk table. Depends only on the chunk table and V.
std::vector<VertexRange> sampling_ranges(const MeshView& mesh);

/// Gives every free (−1) non-isolated vertex reachable from a labelled one the label of a
/// neighbouring region, so that connected regions stay connected. Range by range
/// (sampling_ranges): first a multi-source BFS inside each range from its labelled vertices,
/// then rounds across range frontiers (a free vertex next to a labelled one of another range
/// takes the label of its lowest-id such neighbour, and the BFS goes on inside its range) until
/// nothing changes. Memory: one range's queue per thread plus lists of frontier vertices.
/// O(V + E) plus O(frontier) per round; TBB-parallel over ranges; the result does not depend on
/// the thread count.
void absorb_free_vertices(const MeshView& mesh, std::span<int32_t> labels);

}  // namespace streamcvd
