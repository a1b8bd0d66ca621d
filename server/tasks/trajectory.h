#pragma once
/// \file
/// End-effector trajectories of two arms and their file formats (docs/tasks.md):
///
/// * our CSV: header `time,arm,x,y,z,qw,qx,qy,qz,gripper`, one row per arm sample, world frame;
/// * our JSON: {"format": "gd-trajectory", "version": 1, "master_start_time": .., "left": [..],
///   "right": [..]} with samples {"t", "position": [x,y,z], "quat_wxyz": [w,x,y,z], "gripper"};
/// * RGBench's joints CSV pair `{left,right}_arm_joint_states_and_end_pose.csv` (end-pose
///   columns in each arm's base frame, absolute Unix times, w-first quaternions).
///
/// Times inside a DualArmTrajectory are seconds relative to master_start_time (the earliest
/// first sample of the two arms in RGBench's files); scene time 0 is that moment.
/// Every reader throws sim::InputError naming the file, line/sample and column at fault.

#include <Eigen/Geometry>
#include <iosfwd>
#include <nlohmann/json_fwd.hpp>
#include <string>
#include <vector>

#include "sim/types.h"
#include "tasks/frames.h"

namespace gd::tasks {

/// Gripper opening of RGBench's Piper when fully open, m (0 = closed).
inline constexpr Real kGripperOpen = 0.035;

/// One end-effector sample of one arm.
struct ArmSample {
  double t = 0;                   ///< s, relative to the trajectory's master start
  Vec3 position = Vec3::Zero();   ///< world frame, m
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< world frame, unit
  double gripper = kGripperOpen;  ///< opening, m: 0 = closed, 0.035 = open (RGBench's range)
  /// The arm's joint angles (rad) when the source recorded them (RGBench's pos_1..pos_6), else
  /// empty. Robot mode drives the arm from them; without them it solves inverse kinematics.
  std::vector<double> joints;
};

/// Checks one sample: finite time, position, orientation and gripper, unit quaternion (norm
/// within 1e-3 of 1), gripper >= 0. Throws InputError prefixed with `where`.
void check_sample(const ArmSample& s, const std::string& where);

/// A time-sorted list of samples of one arm, interpolated like RGBench's pseudo mode: linear
/// position, SLERP orientation (shortest arc), linear gripper and joints (where both samples have
/// them); clamped to the first/last sample
/// outside the covered range.
class ArmTrajectory {
 public:
  ArmTrajectory() = default;
  /// Validates the samples (check_sample on each, strictly increasing times) and normalises
  /// the quaternions. Throws InputError naming the sample ("<what> sample 3 (t=0.2): ...").
  explicit ArmTrajectory(std::vector<ArmSample> samples, const std::string& what = "trajectory");

  bool empty() const { return samples_.empty(); }
  size_t size() const { return samples_.size(); }
  const std::vector<ArmSample>& samples() const { return samples_; }
  /// First and last sample times; the trajectory must not be empty.
  double start_time() const;
  double end_time() const;

  /// Appends a sample after the last one (live control, e.g. the service's step actions).
  /// Throws InputError when it is invalid or not strictly later than the last sample.
  void append(ArmSample s, const std::string& what = "trajectory");

  /// The interpolated sample at time t (its .t is t). Throws InputError when empty or t is not finite.
  ArmSample sample(double t) const;
  /// The end-effector pose at time t.
  Eigen::Isometry3d pose(double t) const;

 private:
  std::vector<ArmSample> samples_;
};

/// Both arms' trajectories on one time base.
struct DualArmTrajectory {
  ArmTrajectory left, right;
  /// Absolute (Unix) time of t = 0, s; 0 for generated trajectories.
  double master_start_time = 0;

  const ArmTrajectory& arm(Arm a) const { return a == Arm::kLeft ? left : right; }
  ArmTrajectory& arm(Arm a) { return a == Arm::kLeft ? left : right; }
  /// Latest end time over the non-empty arms (0 when both are empty).
  double end_time() const;
};

// --- our CSV format ------------------------------------------------------------------------
/// Parses our CSV from text (`source` names it in error messages). Columns by header name in any
/// order: time, arm (left|right), x, y, z, qw, qx, qy, qz, gripper; all required, no others. Empty
/// lines are skipped; lines starting with '#' are comments, except `# master_start_time = <s>`.
/// Rows of the two arms may interleave; each arm's times must increase strictly.
DualArmTrajectory parse_trajectory_csv(const std::string& text, const std::string& source = "csv");
std::string format_trajectory_csv(const DualArmTrajectory& traj);
DualArmTrajectory read_trajectory_csv(const std::string& path);
void write_trajectory_csv(const std::string& path, const DualArmTrajectory& traj);

// --- our JSON format -----------------------------------------------------------------------
DualArmTrajectory trajectory_from_json(const nlohmann::json& j, const std::string& source = "json");
nlohmann::json trajectory_to_json(const DualArmTrajectory& traj);
DualArmTrajectory read_trajectory_json(const std::string& path);
void write_trajectory_json(const std::string& path, const DualArmTrajectory& traj);

/// Reads our CSV (.csv) or JSON (.json) by the file's extension.
DualArmTrajectory read_trajectory(const std::string& path);

// --- RGBench joints CSVs ---------------------------------------------------------------------
/// File names inside a capture's joints/ directory.
inline constexpr const char* kRgbenchLeftJointsCsv = "left_arm_joint_states_and_end_pose.csv";
inline constexpr const char* kRgbenchRightJointsCsv = "right_arm_joint_states_and_end_pose.csv";
/// The exact header RGBench writes.
inline constexpr const char* kRgbenchJointsHeader =
    "time,pos_1,pos_2,pos_3,pos_4,pos_5,pos_6,pos_gripper,pos_x,pos_y,pos_z,orn_w,orn_x,orn_y,orn_z";

/// Reads RGBench's joints CSV pair. Columns are found by header name (time, pos_gripper, pos_x,
/// pos_y, pos_z, orn_w, orn_x, orn_y, orn_z are required; pos_1..pos_6, when all present and not
/// all zero throughout the file (what write_rgbench_joints writes without joints), become each
/// sample's joints, which robot mode drives). Positions
/// are in each arm's base frame and become world positions by adding base_offset(arm) (the base
/// frames are not rotated); quaternions are w-first; `pos_gripper` is the opening in m.
/// master_start_time = the smaller of the two files' first times; the returned times are relative
/// to it.
DualArmTrajectory read_rgbench_joints(const std::string& left_csv, const std::string& right_csv);
/// read_rgbench_joints(dir/left_arm_..., dir/right_arm_...), dir being a capture's joints/ folder.
DualArmTrajectory read_rgbench_joints_dir(const std::string& dir);
/// Writes both files into `dir` (created if missing) with kRgbenchJointsHeader: absolute time =
/// master_start_time + t, positions back in each arm's base frame, w-first quaternions,
/// pos_gripper = gripper, pos_1..pos_6 = the samples' joints (robot mode's inverse kinematics
/// fills them in, tasks/robot_arms.h) or 0 where a sample has none: then the files drive
/// RGBench's pose-mode (fixed-point) replay but not its joint-mode robot replay.
/// Reading them back returns times relative to the earliest first sample (the same absolute times).
void write_rgbench_joints(const std::string& dir, const DualArmTrajectory& traj);

}  // namespace gd::tasks
