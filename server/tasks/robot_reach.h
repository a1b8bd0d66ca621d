#pragma once
/// \file
/// Generated tasks fitted to the robot arms' reach: the highest lift (grasp) or fling height a
/// URDF's arms can follow with their hands pointing nearly down (docs/robot.md, "Within reach").
/// Pseudo mode lifts a garment by its length plus 0.1 m; the Piper's gripper cannot point down
/// that high (the T-shirt's 0.87 m lift is out of reach; at 0.45 m inverse kinematics tilts the
/// hands by 68 degrees and the pads close on nothing).

#include <functional>
#include <memory>

#include "robot/arm_model.h"
#include "tasks/robot_arms.h"
#include "tasks/trajectory.h"

namespace gd::tasks {

/// What fit_height_to_reach found.
struct ReachFit {
  double wanted = 0;       ///< m: the height asked for
  double height = 0;       ///< m: the height taken (== wanted when that was within reach)
  double tilt = 0;         ///< rad: the hands' largest tilt from pointing down at `height`
  double bound = 0;        ///< rad: the tilt allowed (max_tilt, or the tilt at height 0 if larger)
  int trials = 0;          ///< trajectories solved by inverse kinematics
  bool lowered() const { return height < wanted; }
};

/// The highest height h in [0, wanted], to within `resolution` m, at which the arms follow
/// make(h) with inverse kinematics tilting no hand more than `max_tilt` rad from its pose (or
/// than the tilt make(0) needs, where that is larger): `wanted` itself when it is within reach.
/// Each trial builds a RobotController (options and model as the run's) on every `stride`-th
/// sample of make(h) and each arm's last one: the poses the run will solve, a few centimetres
/// apart (a generated task samples every 10 ms), so its tilt is the run's to within what lies
/// between them. Throws the controller's InputError when make(0) is already out of reach.
ReachFit fit_height_to_reach(const std::function<DualArmTrajectory(double)>& make, double wanted,
                             const RobotOptions& options, const std::shared_ptr<const robot::ArmModel>& model,
                             double max_tilt, double resolution = 0.01, int stride = 8);

/// Every `stride`-th sample of each arm's trajectory and its last one (stride >= 1).
DualArmTrajectory thin_trajectory(const DualArmTrajectory& traj, int stride);

}  // namespace gd::tasks
