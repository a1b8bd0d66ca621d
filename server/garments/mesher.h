#pragma once
/// \file
/// Meshing one flat panel with CGAL's 2D constrained Delaunay refinement (the CGAL types stay in
/// mesher.cpp), plus the curve sampling and spacing helpers the garment assembly uses.

#include <Eigen/Core>
#include <functional>
#include <stdexcept>
#include <vector>

#include "sim/types.h"

namespace gd::garments {

using sim::Real;
using sim::Vec2;

/// Minimum-angle bound of the refinement: CGAL's aspect bound B = 1/(4 sin² θmin); 0.125 gives
/// θmin ≈ 20.7°.
inline constexpr Real kMesherAspectBound = 0.125;

/// The refinement's point budget: kMesherBudgetFactor x the panel's area in equilateral triangles
/// of side max_edge, plus the outline's points, plus kMesherBudgetFloor (a sane garment's panels
/// take a few times the area estimate near their small features; a degenerate one, like a 1e9 m
/// towel at 200 vertices, would take billions of points).
inline constexpr Real kMesherBudgetFactor = 50;
inline constexpr Real kMesherBudgetFloor = 20000;

/// The most points mesh_panel lets CGAL's refinement insert into a panel (see above).
long mesher_point_budget(const std::vector<Vec2>& boundary, Real max_edge);

/// Thrown by mesh_panel when the calling thread's MeshingCancellation says the mesh is no longer
/// wanted (the call that asked for it went away or passed its deadline, the job was cancelled).
class MeshingCancelled : public std::runtime_error {
 public:
  MeshingCancelled() : std::runtime_error("meshing cancelled: the garment is no longer wanted") {}
};

/// While alive, mesh_panel on this thread asks `cancelled` every kMesherCancelCheckPoints
/// refinement points and throws MeshingCancelled once it answers true: meshing a large garment
/// takes seconds, and a caller that is gone should not keep a thread busy with it. Scopes nest
/// (the innermost one is asked).
class MeshingCancellation {
 public:
  explicit MeshingCancellation(std::function<bool()> cancelled);
  ~MeshingCancellation();
  MeshingCancellation(const MeshingCancellation&) = delete;
  MeshingCancellation& operator=(const MeshingCancellation&) = delete;

  /// Throws MeshingCancelled when the innermost scope on this thread says so (no scope: never).
  static void check();

 private:
  std::function<bool()> cancelled_;
  MeshingCancellation* outer_;
};
inline constexpr int kMesherCancelCheckPoints = 256;

/// The triangulation of one panel in layout coordinates.
struct PanelMesh {
  std::vector<Vec2> points;            ///< every vertex of the triangulation
  /// Per point: its index in the input list (boundary points first, then the fold points in
  /// order), or -1 for a point the mesher added.
  std::vector<int> input_index;
  std::vector<Eigen::Vector3i> tris;   ///< counter-clockwise in layout coordinates
  /// Points the mesher added on a constrained segment (boundary or fold). Callers that need the
  /// constrained segments unsplit (seams shared with another panel) insert these into their
  /// sampling and mesh again.
  std::vector<Vec2> split_points;
};

/// Meshes the polygon `boundary` (closed, counter-clockwise, each corner once, sampled at the
/// wanted spacing) with the polylines `folds` (sampled; their points may coincide with boundary
/// points) as interior constraints. Triangles get edges no longer than `max_edge` and angles of
/// at least ~20.7° away from sharp input corners. GD_DEMANDs a valid polygon; throws
/// sim::InputError when the refinement would exceed mesher_point_budget (sizes far apart in scale).
PanelMesh mesh_panel(const std::vector<Vec2>& boundary, const std::vector<std::vector<Vec2>>& folds,
                     Real max_edge);

/// Resamples a polyline at spacing ~h: points where it turns by more than 20° are kept, each
/// stretch between them is divided into max(1, round(length / h)) equal arc-length pieces. Both
/// end points are kept exactly.
std::vector<Vec2> sample_polyline(const std::vector<Vec2>& pts, Real h);

/// Vertex spacing h such that `area` (m²) meshed with equilateral triangles of side h holds about
/// `vertices` vertices: a vertex per h²·√3/2 of area.
Real spacing_for_vertices(Real area, int vertices);

}  // namespace gd::garments
