#pragma once
/// \file
/// Where a kinematic collider cuts through the cloth: the contact model keeps the cloth's VERTICES
/// out of a collider (collider.h), not its edges and faces, so a collider thinner than the cloth's
/// edges are long (a gripper pad 8 mm thick in cloth with 1.7 cm edges) can stand in the sheet
/// with vertices on either side of it, an edge passing through it or one of its own edges through
/// a triangle. Such cloth is threaded on the collider: it comes off only by sliding along the
/// collider's faces past its end, so with friction on them a rising pad carries it up however open
/// its fingers (docs/robot.md, "Pads that cut through the cloth"). Points sampled over the
/// triangles a pad's half thickness apart (surface_samples.h, SceneOptions::pad_samples) are held
/// out of yielding colliders too, which leaves only chords across a pad's rim; this count says
/// whether a run rests on cuts all the same. A diagnostic, not part of the solve.

#include <vector>

#include <Eigen/Geometry>

#include "sim/contact/collider.h"
#include "sim/types.h"

namespace gd::sim {

/// The cuts of one collider through a triangle mesh.
struct ColliderCuts {
  int edges_through = 0;  ///< cloth edges that pass through the collider's inside
  int faces_pierced = 0;  ///< cloth triangles one of the collider's edges (a box's 12, a capsule's axis) passes through
  /// m: how far inside the collider the cloth passes where it cuts it: the largest depth below
  /// the collider's surface along the edges through it and over the triangles pierced (a capsule's
  /// axis through a triangle: its radius; a box: over a grid of points a sixteenth of the
  /// triangle's edges apart). 0 when nothing cuts. A chord across an edge of the collider that the
  /// cloth wraps round passes a little way in; cloth threaded on it, as deep as it is thick.
  double depth = 0;
  int total() const { return edges_through + faces_pierced; }
};

/// The cuts of a box or capsule collider at `pose` through the cloth (positions x, triangles tris;
/// each edge counted once). Elements whose bounding box misses the collider's are skipped. Throws
/// InputError for a plane or mesh collider (a plane's side is a matter of the table; meshes are
/// not covered) and for an index out of range.
ColliderCuts collider_cuts(const Collider& collider, const Eigen::Isometry3d& pose, const std::vector<Vec3>& x,
                           const std::vector<Eigen::Vector3i>& tris);

}  // namespace gd::sim
