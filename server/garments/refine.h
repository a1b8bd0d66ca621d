#pragma once
/// \file
/// Local refinement of a garment's mesh: finer triangles where something small touches the
/// cloth. Robot mode's gripper pads (2 x 4 cm) touch the cloth at its vertices, and a garment
/// meshed at 2000 vertices (edges of ~2.5 cm) puts one or two vertices of each layer between
/// them (docs/robot.md, "Finer cloth under the pads"); refining only there keeps the rest of the
/// garment, and the cost of a step, as it was.

#include <vector>

#include "garments/garment.h"
#include "sim/demand.h"

namespace gd::garments {

/// Where and how finely refine_near refines.
struct RefineRegion {
  std::vector<Vec3> centres;  ///< garment frame, m
  Real radius = 0.06;         ///< m: triangles with a corner or centroid within this of a centre
  Real edge = 0.006;          ///< m: refined until their longest edge is at most this
  /// The refined garment's most vertices (0: up to 200000 added); refine_near throws
  /// TooManyVertices as soon as it would make more.
  long max_vertices = 0;
};

/// refine_near's vertex budget (RefineRegion::max_vertices) exceeded: an edge too small or a
/// radius too large for it.
class TooManyVertices : public sim::InputError {
 public:
  using sim::InputError::InputError;
};

/// Refines `g` by longest-edge bisection (Rivara's LEPP): every triangle near a centre whose
/// longest edge exceeds `edge` is bisected, and so is each neighbour whose longest edge is the
/// one split first, so the mesh stays conforming and its angles stay bounded (at most halved once,
/// whatever the depth). New vertices are edge midpoints: on the flat garment they lie on the
/// cloth, and their pattern coordinates (one per panel on a seam) are the midpoints of the edge's
/// own, so the rest shape is the same surface. Existing vertex indices are kept (landmark
/// vertices stay valid); a split seam edge puts its midpoint into the seam's vertex list, a split
/// crease or elastic edge gives two with the same values, and each new triangle keeps its
/// parent's panel. `g.spacing` stays the coarse mesh's spacing. Throws sim::InputError for a
/// non-positive or non-finite radius or edge, or an edge below 1 mm, and TooManyVertices past
/// the region's vertex budget (`g` is then partly refined); returns the number of vertices added.
int refine_near(Garment& g, const RefineRegion& region);

/// How finely `g` is meshed round `centres` (garment frame): the median longest edge, m, of the
/// triangles with a corner or their centroid within `radius` of a centre (those refine_near would
/// refine with that radius; 0 if none is). Robot mode compares it
/// with the pads' thickness: cloth meshed coarser than a pad is thick cannot fold between the
/// closing pads (docs/robot.md, "The garment refined under the pads").
Real edge_near(const Garment& g, const std::vector<Vec3>& centres, Real radius);

/// The points a task grasps, in the garment frame: both shoulders (grasp, fling), with `fold`
/// also both hem corners and, on a hooded garment, the hood's face corners (tasks/generators.h).
std::vector<Vec3> grasp_landmarks(const Landmarks& l, bool fold);

}  // namespace gd::garments
