#pragma once
/// \file
/// A robot arm with a parallel gripper, read from its URDF: forward kinematics of every link,
/// inverse kinematics of the end effector within the joint limits, and the finger pads that hold
/// cloth in robot mode (docs/robot.md).
///
/// The URDF is parsed by urdfdom and turned into a kinematic tree by kdl_parser; Orocos KDL does
/// the kinematics (TreeFkSolverPos_recursive; ChainIkSolverPos_LMA, then ChainIkSolverPos_NR_JL
/// where LMA's answer leaves the limits). Defaults follow RGBench's AgileX Piper
/// (piper_with_gripper.urdf): arm joints joint1..joint6 from `base_link`, end effector `link7`
/// with the fingers at 0 (the frame of RGBench's recorded end pose), prismatic finger joints
/// joint7 (0..0.035 m) and joint8 (-0.035..0 m), a gripper value g in [0, 0.035] m setting
/// joint7 = +g and joint8 = -g (0 closed, 0.035 open, as RGBench's robot mode).
///
///   auto arm = gd::robot::ArmModel::load("piper_with_gripper.urdf");   // InputError if unusable
///   Eigen::Isometry3d ee = arm.ee_pose(q);                              // in the arm's base frame
///   auto ik = arm.ik(ee, seed);                                         // ik.ok, ik.q
///
/// Poses are in the arm's own base frame (the URDF's root); an arm placed in a world puts its
/// base pose in front. An ArmModel is immutable after load and safe to share between threads (its
/// kinematics run under a lock: KDL's joints cache their last pose).

#include <Eigen/Geometry>
#include <array>
#include <memory>
#include <string>
#include <vector>

#include "robot/link_shapes.h"

namespace gd::robot {

/// A box-shaped finger pad in its finger link's frame (the URDF here names no collision
/// geometry the simulator can use: its meshes are not shipped).
struct FingerPad {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();        ///< m, finger link frame
  Eigen::Vector3d half_extents = Eigen::Vector3d::Zero();  ///< m, along the link frame's axes
};

struct ArmModelOptions {
  std::string base_link = "base_link";  ///< root of the arm chain
  std::string ee_link = "link7";        ///< end-effector frame (with the fingers at 0)
  /// Prismatic finger joints: the first set to +g, the second to -g for a gripper value g.
  std::array<std::string, 2> finger_joints{"joint7", "joint8"};
  /// The pad of each finger in its link's frame. Piper default (docs/robot.md): 4 cm along the
  /// finger back from its frame origin (link y, towards the wrist), 2 cm wide (link x), 8 mm
  /// thick on the outer side of the frame origin (link z, the finger's opening direction), so the
  /// two pads' inner faces meet at a gripper value of 0.
  FingerPad pad{Eigen::Vector3d(0, -0.02, 0.004), Eigen::Vector3d(0.01, 0.02, 0.004)};
  /// Directories where `package://NAME/...` mesh URIs of the links' collision geometry are looked
  /// for (robot/link_shapes.h): DIR/NAME/... or, for a DIR named NAME, DIR/.... A mesh found
  /// nowhere is left out (skipped_meshes()); RGBench's Piper URDF names meshes it does not ship.
  std::vector<std::string> package_paths;
  /// Whether mesh files named by the URDF are read at all. The service sets false for a URDF a
  /// client sends, so that a request cannot make the server open files of its choosing.
  bool read_meshes = true;
};

struct JointLimits {
  double lower = 0, upper = 0;  ///< rad or m
  double effort = 0;            ///< N m or N (the URDF's <limit effort>); 0 when not given
  double velocity = 0;          ///< rad/s or m/s (<limit velocity>); 0 when not given
};

/// An inverse-kinematics answer.
struct IkResult {
  Eigen::VectorXd q;              ///< arm joints, within their limits
  double position_error = 0;      ///< m, |p(q) - p_target|
  double rotation_error = 0;      ///< rad, angle of R(q)^T R_target
  bool ok = false;                ///< both errors within the tolerances asked
};

class ArmModel {
 public:
  /// Reads the URDF at `path`. Throws sim::InputError naming the file and what is wrong: not
  /// readable, not a URDF, a link or joint of the options missing, a finger joint that is not
  /// prismatic, a chain with no movable joint.
  static ArmModel load(const std::string& path, const ArmModelOptions& options = {});
  /// The same from URDF text; `source` names it in messages.
  static ArmModel from_string(const std::string& urdf_xml, const std::string& source,
                              const ArmModelOptions& options = {});

  ArmModel(ArmModel&&) noexcept;
  ArmModel& operator=(ArmModel&&) noexcept;
  ~ArmModel();

  const std::string& name() const;
  const ArmModelOptions& options() const;
  /// The movable joints from the base to the end effector, in chain order (Piper: joint1..6).
  int arm_dofs() const;
  const std::vector<std::string>& arm_joint_names() const;
  const std::vector<JointLimits>& arm_limits() const;
  /// Largest gripper value: the smaller of the two finger joints' travel.
  double gripper_max() const;
  /// The first finger joint's limits (Piper joint7: 0..0.035 m, effort 10 N, velocity 1 m/s).
  const JointLimits& finger_limits() const;
  /// The links of the two finger joints (Piper: link7, link8).
  const std::array<std::string, 2>& finger_links() const;
  /// Every link of the URDF.
  std::vector<std::string> link_names() const;
  /// The links' collision shapes the URDF gives and that were found (robot/link_shapes.h), read
  /// at load: the fingers' too (robot mode holds cloth with its own pads and leaves those out).
  const std::vector<LinkShape>& link_shapes() const;
  /// Mesh URIs of the URDF's collision geometry found on no package path (left out).
  const std::vector<std::string>& skipped_meshes() const;
  /// Whether `link` is part of the hand: the child link of the last arm joint and every link
  /// below it (Piper: link6, gripper_base, link7, link8). Robot mode lifts the hand as a whole
  /// where a pad would go below the table.
  bool is_hand_link(const std::string& link) const;

  /// Pose of `link` in the base frame for arm joints q (arm_dofs() values) and gripper value g
  /// (clamped to [0, gripper_max()]). Throws InputError for an unknown link or a wrong-sized q.
  Eigen::Isometry3d link_pose(const std::string& link, const Eigen::VectorXd& q, double gripper) const;
  /// Every link's pose, in link_names() order.
  std::vector<Eigen::Isometry3d> link_poses(const Eigen::VectorXd& q, double gripper) const;
  /// The end effector's pose with the fingers at 0 (RGBench's recorded end pose).
  Eigen::Isometry3d ee_pose(const Eigen::VectorXd& q) const;
  /// The arm's chain as points in the base frame: the base, then the origin of each segment from
  /// the base to the end effector that moves it away from the last point (a viewer's skeleton).
  std::vector<Eigen::Vector3d> chain_points(const Eigen::VectorXd& q) const;

  /// Arm joints that put the end effector at `target` (base frame), starting from `seed`
  /// (arm_dofs() values; the previous sample's answer along a trajectory). ok when the position
  /// is within pos_tol (m) and the orientation within rot_tol (rad); otherwise q is the best
  /// found. The answer always lies within the joint limits.
  IkResult ik(const Eigen::Isometry3d& target, const Eigen::VectorXd& seed, double pos_tol = 1e-4,
              double rot_tol = 1e-3) const;
  /// The position exactly (within pos_tol) and the orientation as near as the joint limits allow:
  /// ik() when the whole pose is reachable, else the least tilt found. ok when the position is
  /// reached and the orientation is within max_rotation_error (rad). (A 6-joint arm whose wrist
  /// cannot point straight down everywhere, like the Piper high above its table, still lifts
  /// a garment where the task says.)
  IkResult ik_position_first(const Eigen::Isometry3d& target, const Eigen::VectorXd& seed, double max_rotation_error,
                             double pos_tol = 1e-4) const;

 private:
  struct Impl;
  explicit ArmModel(std::unique_ptr<Impl> impl);
  std::unique_ptr<Impl> impl_;
};

}  // namespace gd::robot
