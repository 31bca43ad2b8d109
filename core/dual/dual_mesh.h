// Dual meshing of a vertex clustering (paper §VI-C, §VI-D): one output vertex per non-empty
// cluster, one output triangle per input triangle whose three vertices lie in three different
// clusters (duplicates removed, orientation from the input), and triangle strips along the
// input boundaries so the output boundary follows the input one.
#pragma once

#include <array>
#include <compare>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include "streamcvd/core/mesh/mesh_buffers.h"
#include "streamcvd/core/mesh/mesh_view.h"

namespace streamcvd {

namespace dual {

/// A dual face: three vertex (cluster) ids in the orientation of the input face.
using Face = std::array<uint32_t, 3>;

/// The dual faces of a clustering as collect_triples finds them (core/dual/dual_topology.h).
struct Triples {
  std::vector<Face> faces;    ///< rotated, sorted, unique
  /// One entry per input face whose triple another input face also gives (the copies past the
  /// first), sorted: what deduplication drops. Rare on a clean clustering (dragon ×9 → 300,000: none).
  std::vector<Face> repeats;
  /// Input faces with three distinct labels (before deduplication).
  uint64_t emitted() const { return faces.size() + repeats.size(); }
  /// With neighbour_pairs asked for: the cluster pairs {a < b} (packed a << 32 | b) joined by
  /// an edge of an input face, sorted, unique.
  std::vector<uint64_t> neighbour_pairs;
};

}  // namespace dual

struct DualMeshOptions {
  bool boundary_strips = true;  ///< §VI-D: one vertex + two triangles per cluster change along a boundary
  /// Boundary loops whose diameter (largest distance between two of their vertices, input
  /// units) is below this are holes under the output resolution: they close (a triangle or a fan
  /// over the clusters around them) instead of getting a strip of slivers. 0 = never.
  double close_hole_diameter = 0;
  /// Boundary loops whose width (their extent across their main direction) is below this are
  /// holes under the output resolution too — slits whose two sides are closer than an output
  /// edge: their ring of clusters is triangulated (core/dual/hole_closing.h). 0 = never.
  double close_hole_width = 0;
  /// Typical output edge length (typical_dual_edge), 0 = off. When set, the strip follows the
  /// clusters' spacing rather than the input's boundary edges: consecutive cluster changes whose
  /// strip points are closer than half of it share one point (while the clusters around the
  /// point are distinct and the loop keeps 3 points), and a Douglas–Peucker corner must also
  /// leave its chord by a fifth of it. Scan holes are jagged: without this, strip chords are a
  /// seventh of an output edge and every strip triangle is a needle.
  double strip_spacing = 0;
};

/// A typical output edge length for `clusters` clusters on a surface of area `area`: the side
/// of the equilateral triangle of area area / (2·clusters) (a closed mesh has 2N faces).
double typical_dual_edge(double area, uint32_t clusters);

/// Where a boundary-strip vertex lies: at the mean of the input vertices
/// DualMesh::source_vertices[begin, begin + count) — the two ends of the boundary edge whose
/// midpoint it is, the one input vertex a Douglas–Peucker corner copies, or every vertex of the
/// hole whose centroid closes it. count = 0 for a cluster vertex. With count = 2 the vertex is at
/// (1 − t)·first + t·second (0.5 from the dual; the strip shaping slides it, core/dual/strip_shape.h).
/// Per-vertex input data (colours) is interpolated the same way (core/mesh/vertex_attributes.h).
struct VertexSource {
  uint32_t begin = 0, count = 0;
  float t = 0.5f;
};

struct DualMesh {
  MeshBuffers mesh;
  std::vector<int32_t> cluster_of_output_vertex;  ///< cluster id, or −1 for boundary-strip vertices
  std::vector<VertexSource> source_of_output_vertex;  ///< one per output vertex (count 0: a cluster's)
  std::vector<uint32_t> source_vertices;          ///< input vertex ids the sources point into
  uint64_t duplicate_faces_removed = 0;
  uint64_t boundary_vertices_added = 0;
  /// Boundary loops that meet fewer than three clusters: the hole is smaller than the output
  /// resolution and closes in the dual (no strip is added for it).
  uint64_t holes_closed = 0;
  /// Boundary loops skipped because they pass through a non-manifold boundary vertex.
  uint64_t loops_skipped = 0;
};

/// The input's boundary loops as cyclic vertex sequences (v_k → v_k+1 in face orientation).
struct BoundaryLoops {
  std::vector<uint32_t> offsets;   ///< loop l is vertices[offsets[l] .. offsets[l+1])
  std::vector<uint32_t> vertices;
  uint64_t skipped = 0;            ///< chains through non-manifold boundary vertices (no strip)
};

/// Finds the boundary loops of `mesh`. O(F) plus the boundary size. Depends on geometry only,
/// so a caller building the dual several times computes it once.
BoundaryLoops find_boundary_loops(const MeshView& mesh);

/// Builds the dual mesh. `cluster_positions` holds 3 doubles per cluster (the output vertex of
/// each cluster, z_i). Empty clusters produce no vertex. `boundary_loops` may be null (then
/// computed here). `triples`, when given, must be dual::collect_triples of these labels (the
/// repair keeps them: DefectRepairResult::dual_faces); otherwise they are collected here.
/// O(F + D log D) for D dual faces (O(V + D log D) with `triples`). Deterministic. Thread-safe (pure).
DualMesh build_dual_mesh(const MeshView& mesh, std::span<const int32_t> labels, uint32_t cluster_count,
                         std::span<const double> cluster_positions, const DualMeshOptions& options = {},
                         const BoundaryLoops* boundary_loops = nullptr, std::optional<dual::Triples> triples = {});

/// A cluster that keeps a hole below the output resolution open, and the hole's boundary loop.
struct OpenHole {
  int32_t cluster;
  uint32_t loop;
  auto operator<=>(const OpenHole&) const = default;
};

/// The labels-only topology of the §VI-D strips, for defect checks that need no positions:
/// the strip faces of every loop with cluster c as vertex c and the strip vertices numbered
/// from cluster_count up (`strip_vertices` receives their count). Same faces, up to that
/// renumbering, as build_dual_mesh adds. O(boundary size). Deterministic. `open_holes`, when
/// given, receives the clusters that keep a hole below the output resolution open, with the
/// hole's loop: each meets it in two stretches or more, so the hole cannot close as a disc and
/// keeps a strip (appended, possibly more than once: sort and dedupe).
std::vector<std::array<uint32_t, 3>> boundary_strip_faces(const MeshView& mesh, const BoundaryLoops& loops,
                                                          std::span<const int32_t> labels, uint32_t cluster_count,
                                                          std::span<const uint32_t> cluster_size,
                                                          const DualMeshOptions& options, uint32_t& strip_vertices,
                                                          std::vector<OpenHole>* open_holes = nullptr);

/// Output vertices involved in a defect of a triangle mesh: non-manifold edges (> 2 faces),
/// edges used twice in the same direction, vertices whose faces do not form one fan,
/// duplicate faces (same vertex set), degenerate faces (repeated index), vertices on no face.
/// Sorted, unique. The fan test of core/dual/dual_topology.h (check_fans): O(F + V) plus a sort
/// of each vertex's fan.
std::vector<uint32_t> find_manifold_defects(const TriangleSoupView& mesh);

struct DefectRemoval {
  uint64_t faces_removed = 0, vertices_removed = 0;
};

/// Last resort after the clustering repair: deletes the faces around every defect vertex of
/// find_manifold_defects (and then vertices left without faces), until none is left (at most 64
/// passes). Leaves small holes instead of non-manifold output. The per-output-vertex arrays
/// (positions, clusters, sources) are compacted together, in order: the only place output
/// vertices are removed.
DefectRemoval remove_manifold_defects(DualMesh& dual);

}  // namespace streamcvd
