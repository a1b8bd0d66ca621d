#pragma once
/// \file
/// The world frame of tasks and experiments (RGBench's): origin midway between the two robot
/// bases, +x forward (away from the robots), +z up, metres, table top at z = 0.
///
/// Base offsets. RGBench disagrees with itself about the sign of y: its docs/DATASET.md and
/// rgbench/transforms.py put the LEFT base at y = -0.25, while all of its simulation code
/// (cloth_pybullet_env.py::_load_scene, left_base_offset in both fixed-point environments) puts
/// the LEFT base at y = +0.25 and the RIGHT base at y = -0.25. We follow the simulation code,
/// since that is what turns the joints CSVs into the poses its pseudo mode replays:
///   left base  = (0, +0.25, 0),   right base = (0, -0.25, 0),
/// and the base frames are not rotated relative to the world (world = base + offset).
///
/// Quaternions in every file format of this module are scalar-first (w, x, y, z), as in
/// RGBench's joints CSVs. Eigen's Quaterniond constructor also takes (w, x, y, z) but stores
/// (x, y, z, w); use the helpers below at file boundaries so the order is never guessed.

#include <Eigen/Geometry>
#include <array>
#include <string>

#include "sim/types.h"

namespace gd::tasks {

using sim::Real;
using sim::Vec3;

/// The two arms, in RGBench's order [left, right].
enum class Arm { kLeft = 0, kRight = 1 };

/// "left" or "right".
inline const char* arm_name(Arm a) { return a == Arm::kLeft ? "left" : "right"; }

/// What a robot-mode hand does with the cloth (RobotArmState::grip, tasks/robot_arms.h).
enum class Grip {
  kOpen,     ///< commanded open
  kClosing,  ///< commanded closed, not (yet) squeezing the cloth with half the limit
  kHeld,     ///< squeezed with half the limit (RobotArmState::held_at) and not lost since
  kMissed,   ///< the fingers stopped closing on little cloth or none, short of a hold (RobotArmState::missed_at)
  kLost,     ///< held, then the cloth left the pads (RobotArmState::lost_at)
};
/// "open", "closing", "held", "missed", "lost".
inline const char* grip_name(Grip g) {
  switch (g) {
    case Grip::kOpen: return "open";
    case Grip::kClosing: return "closing";
    case Grip::kHeld: return "held";
    case Grip::kMissed: return "missed";
    case Grip::kLost: return "lost";
  }
  return "?";
}

/// Offset of the arm's base frame in the world frame (simulation-code convention, see above).
inline Vec3 base_offset(Arm a) { return a == Arm::kLeft ? Vec3(0, 0.25, 0) : Vec3(0, -0.25, 0); }

/// Position of RGBench's default garment placement (main.yaml fallback init_pose
/// [0.1, 0.0, 0.01, 1, 0, 0, 0]): the garment frame's origin in the world frame.
inline Vec3 default_garment_position() { return Vec3(0.1, 0.0, 0.01); }

/// The default garment placement: garment frame -> world, translation [0.1, 0, 0.01], identity
/// rotation. A garment laid flat in its own frame (garments/garment.h) then has its collar end
/// nearest the robots at x = 0.1 and its lowest layer 1 cm above the table.
inline Eigen::Isometry3d default_garment_pose() {
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.translation() = default_garment_position();
  return p;
}

/// A quaternion from scalar-first components (not normalised).
inline Eigen::Quaterniond quat_from_wxyz(Real w, Real x, Real y, Real z) { return Eigen::Quaterniond(w, x, y, z); }
inline Eigen::Quaterniond quat_from_wxyz(const std::array<Real, 4>& q) { return Eigen::Quaterniond(q[0], q[1], q[2], q[3]); }

/// Scalar-first components of a quaternion.
inline std::array<Real, 4> quat_to_wxyz(const Eigen::Quaterniond& q) { return {q.w(), q.x(), q.y(), q.z()}; }

/// The rigid motion with this position and orientation (orientation normalised).
inline Eigen::Isometry3d make_pose(const Vec3& position, const Eigen::Quaterniond& orientation) {
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.linear() = orientation.normalized().toRotationMatrix();
  p.translation() = position;
  return p;
}

/// The end-effector orientation of the generators: the gripper approaches from above with its
/// jaw (tool +z) pointing down, i.e. a half turn about world x (tool x stays along world +x).
/// w-first: (0, 1, 0, 0).
inline Eigen::Quaterniond top_down_orientation() { return Eigen::Quaterniond(0, 1, 0, 0); }

}  // namespace gd::tasks
