#pragma once
/// \file
/// Triangle meshes: the container, input validation, edge/hinge topology, simple generators
/// (rectangle, disc), small queries and a minimal OBJ reader/writer. Units are metres.

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

#include "sim/types.h"

namespace gd::sim {

/// A hinge whose bending stiffness is scaled, e.g. a pressed fold line of a pleat (scale < 1).
struct Crease {
  int a = 0, b = 0;     ///< the edge's vertices (either order)
  Real bend_scale = 1;  ///< multiplies the material's bending stiffness on this edge
};

/// An elastic edge (waistband, cuff): the triangles that contain it have their rest length
/// along the edge scaled by `ratio` (< 1 gathers the fabric), their rest width unchanged.
struct ElasticEdge {
  int a = 0, b = 0;  ///< the edge's vertices (either order)
  Real ratio = 1;    ///< rest-length ratio along the edge, in (0, 2]
};

/// A triangle mesh of one garment piece or garment.
struct Mesh {
  std::vector<Vec3> x;  ///< vertex positions, m
  /// 2D sewing-pattern (rest) coordinates in metres; axis 0 = warp, axis 1 = weft. Empty (rest
  /// shape from the 3D positions), one per vertex (uv_tris empty), or indexed by uv_tris.
  std::vector<Vec2> uv;
  std::vector<Eigen::Vector3i> tris;  ///< vertex indices; counter-clockwise seen from the front
  /// Empty, or one triple of uv indices per triangle: a vertex on a seam then has one pattern
  /// coordinate per panel (as OBJ `f v/vt` corners do).
  std::vector<Eigen::Vector3i> uv_tris;
  std::vector<Crease> creases;             ///< edges with scaled bending (fold lines)
  std::vector<ElasticEdge> elastic_edges;  ///< edges with a rest-length ratio
};

/// True when the mesh carries pattern coordinates.
inline bool has_uv(const Mesh& m) { return !m.uv.empty(); }
/// Pattern coordinate of corner k (0..2) of triangle t; the mesh must have uvs.
inline const Vec2& corner_uv(const Mesh& m, int t, int k) {
  return m.uv[m.uv_tris.empty() ? m.tris[t][k] : m.uv_tris[t][k]];
}

/// Checks that `m` can be simulated. Throws InputError with a specific message for: no vertices
/// or triangles, index out of range, non-finite positions or uvs, a uv count that differs from
/// the vertex count (without uv_tris) or uv_tris that do not match the triangles, creases or
/// elastic edges that are not edges of the mesh or have bad values, degenerate triangles (3D or uv area below max(1e-12 m², 1e-6 · mean edge²)),
/// duplicate triangles (same vertex set), non-manifold edges (more than 2 triangles), and
/// absurd scale (bounding-box diagonal > 100 m or mean edge < 1e-5 m).
void validate_mesh(const Mesh& m);

/// Edge and hinge connectivity derived from a mesh's triangles.
struct Topology {
  std::vector<Eigen::Vector2i> edges;  ///< unique undirected edges (i, j) with i < j, sorted
  /// Interior edges as (x0, x1, x2, x3): (x0, x1) is the shared edge; x2 is the opposite vertex of
  /// the triangle whose winding contains x0 -> x1; x3 is the opposite vertex of the other one.
  std::vector<Eigen::Vector4i> hinges;
  std::vector<Eigen::Vector2i> hinge_tris;  ///< per hinge: (triangle of x2, triangle of x3)
  std::vector<int> boundary_vertices;       ///< vertices on a boundary edge, sorted
};

/// Builds the topology of a mesh that passed validate_mesh, in O(F log F); hinges come in the
/// order of their (sorted) edges. Throws InputError for a non-manifold edge. If the two triangles
/// of an edge are inconsistently oriented, the hinge follows the lower-numbered triangle's
/// winding and one warning is logged per call.
Topology build_topology(const Mesh& m);

/// A flat size_x × size_y rectangle in the z = 0 plane with corner (0,0,0) and uv = (x, y).
/// Rows run along x, odd rows shifted by half a spacing; the shifted rows' half-cells at both
/// ends are snapped onto the left/right edges so the rectangle is exact. The column count is
/// rounded so the vertex spacing dx along x is as close to `spacing` as possible; the row count
/// so rows are as close to dx·√3/2 apart as possible (moving to the neighbouring count when that
/// keeps all angles above 40°). Interior triangles are near-equilateral; the boundary ones are
/// right triangles with legs dx and the row gap (about 41°, 49°, 90°). Throws InputError for
/// non-positive or non-finite arguments.
Mesh make_rect(Real size_x, Real size_y, Real spacing);

/// A flat disc of `radius` centred at the origin in the z = 0 plane, uv = (x, y): concentric
/// rings round(radius/spacing) apart, ring k holding 6k vertices (a hexagonal lattice bent onto
/// circles), consecutive rings zipped into roughly equilateral triangles.
Mesh make_disc(Real radius, Real spacing);

/// Index of the vertex closest to `p` (first one on ties). The mesh must not be empty.
int nearest_vertex(const Mesh& m, const Vec3& p);

/// Indices (ascending) of the vertices whose position satisfies `pred`.
std::vector<int> vertices_where(const Mesh& m, const std::function<bool(const Vec3&)>& pred);

/// Total 3D surface area, m².
Real mesh_area(const Mesh& m);

/// Mean length of the unique edges, m.
Real mean_edge_length(const Mesh& m);

/// Writes `m` as a Wavefront OBJ (v, vt when uvs exist, f with v/vt corners). `positions`, when non-empty,
/// replaces m.x (it must then have one entry per vertex). Throws InputError if the file cannot
/// be written.
void write_obj(const Mesh& m, const std::vector<Vec3>& positions, const std::string& path);

/// Reads a Wavefront OBJ with tinyobjloader: vertices in the file's `v` order (never merged or
/// reordered), polygons fan-triangulated (v0, vk, vk+1), faces of every group. When every face
/// corner has a vt, uv holds them: one per vertex if each vertex has a single value, else indexed
/// by uv_tris (seams). Throws InputError naming the file for a missing file, a parse failure (a
/// zero index) or an index out of range. Faces of fewer than 3 vertices are dropped (by
/// tinyobjloader), and a file with no faces gives the vertices alone (a point cloud). Comments
/// must start their line. The result is not validated; call validate_mesh.
Mesh read_obj(const std::string& path);

}  // namespace gd::sim
