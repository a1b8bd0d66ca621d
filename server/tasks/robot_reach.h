#pragma once
/// \file
/// Generated tasks fitted to the robot arms' reach: the highest lift (grasp) or fling height a
/// URDF's arms can follow with their hands pointing nearly down (docs/robot.md, "Within reach").
/// Pseudo mode lifts a garment by its length plus 0.1 m; the Piper's gripper cannot point down
/// that high (the T-shirt's 0.87 m lift is out of reach; at 0.45 m inverse kinematics tilts the
/// hands by 68 degrees and the pads close on nothing).

#include <functional>
#include <memory>
#include <vector>

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

/// The highest height h in [lowest, wanted], to within `resolution` m, at which the arms follow
/// make(h) with inverse kinematics tilting no hand more than `max_tilt` rad from its pose (or,
/// where make(lowest) needs more, than that plus a degree: a fold's ends, which no height moves,
/// set it, and inverse kinematics solved along another path lands a fraction of a degree apart
/// there): `wanted` itself when it is within reach.
/// Each trial builds a RobotController (options and model as the run's) on every `stride`-th
/// sample of make(h) and each arm's last one: the poses the run will solve, a few centimetres
/// apart (a generated task samples every 10 ms), so its tilt is the run's to within what lies
/// between them. Throws the controller's InputError when make(lowest) is already out of reach.
ReachFit fit_height_to_reach(const std::function<DualArmTrajectory(double)>& make, double wanted,
                             const RobotOptions& options, const std::shared_ptr<const robot::ArmModel>& model,
                             double max_tilt, double resolution = 0.01, int stride = 8, double lowest = 0);

/// What place_within_reach found.
struct PlacementFit {
  double shift = 0;    ///< m along world x: how far the garment was moved from where it was given
  ReachFit reach;      ///< the task at that shift (its height fitted, or the given one)
  int candidates = 0;  ///< shifts tried
  int reachable = 0;   ///< of them, those at which the task was within reach at all
  int trials = 0;      ///< trajectories solved by inverse kinematics over every shift
  bool height_fitted = false;  ///< the height was fitted at each shift (fit_height), not given
};

/// Robot mode's automatic placement (docs/robot.md, "Placed within reach"): the shift along world
/// x (away from the arms' bases for shift > 0) at which the arms follow the task best. make(s, h)
/// builds the task with the garment moved by s and its lift (or fling height) at h.
/// - `fit_height`: at each shift the height is fitted as fit_height_to_reach does (the highest in
///   [lowest, wanted] within `max_tilt`, to `resolution`), and the highest wins. A shift is first tried
///   at the best height so far plus `resolution` (one trial); only one that reaches it is fitted.
///   Shifts are compared on every 4 x `stride`-th sample; the winner's height is then fitted again
///   on every `stride`-th (what `reach` holds).
/// - otherwise (a height the user gave): every shift is tried at
///   `wanted` and the one whose hands tilt least wins.
/// Shifts are tried in order and a later one wins only by more than `resolution` in height or by
/// more than a degree of tilt, so the given placement (shift 0, put first) is kept on a tie; once
/// a shift reaches `wanted` itself the search stops there.
/// Shifts at which the task is out of reach are skipped; throws InputError naming the range when
/// it is out of reach at every one.
PlacementFit place_within_reach(const std::function<DualArmTrajectory(double, double)>& make, double wanted,
                                bool fit_height, const std::vector<double>& shifts, const RobotOptions& options,
                                const std::shared_ptr<const robot::ArmModel>& model, double max_tilt,
                                double resolution = 0.01, int stride = 8, double lowest = 0);

/// The shifts automatic placement tries, nearest first: 0 (the given placement), then 2.5 cm
/// steps up to 30 cm away from the bases (the Piper reaches top-down highest some 25-45 cm in
/// front of its base) and up to 10 cm towards them (a fold's far end comes within reach; at the
/// default placement, 10 cm in front of the bases, that puts the garment's near end on their line).
std::vector<double> default_placement_shifts();

/// Every `stride`-th sample of each arm's trajectory and its last one (stride >= 1).
DualArmTrajectory thin_trajectory(const DualArmTrajectory& traj, int stride);

}  // namespace gd::tasks
