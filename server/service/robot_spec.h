#pragma once
/// \file
/// Robot mode's settings as scenes and jobs take them (proto RobotSettings; docs/robot.md).

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "service/status.h"

namespace gd::tasks {
struct RobotOptions;
}

namespace gd::service {

/// Largest URDF text a request may carry.
inline constexpr size_t kMaxUrdfBytes = size_t(1) << 20;

struct RobotSpec {
  std::string urdf_xml;                     ///< the URDF's text; empty: the server's --robot-urdf
  std::optional<double> grip_force;         ///< N (default: the URDF's finger effort limit)
  std::optional<double> finger_friction;    ///< default: the material's friction
  /// Scenes: each arm's joints at t = 0 and after a reset ([left, right]; empty: robot_home_pose()
  /// through inverse kinematics).
  std::array<std::vector<double>, 2> initial_joints;
  /// Jobs: RobotOptions::lift_max_tilt in degrees (default: its 30).
  std::optional<double> lift_max_tilt_deg;
  /// Jobs: ExperimentConfig::place_within_reach (default: the garment where the job puts it).
  std::optional<bool> place_within_reach;
  /// N/m: tasks::RobotOptions::pad_stiffness (default: its kDefaultPadStiffness).
  std::optional<double> pad_stiffness;

  bool empty() const {
    return urdf_xml.empty() && !grip_force && !finger_friction && initial_joints[0].empty() && initial_joints[1].empty() &&
           !lift_max_tilt_deg && !place_within_reach && !pad_stiffness;
  }
};

/// What scenes and jobs check alike before they parse the URDF: its size (RESOURCE_EXHAUSTED),
/// that there is one (the request's or, when `server_has_urdf`, the server's; else
/// FAILED_PRECONDITION saying how to give one), and the grip force (finite, > 0), finger
/// friction (finite, >= 0), pad stiffness (finite, >= 0) and lift tilt bound (finite, 0-180
/// degrees), which go into `options`.
Status apply_robot_spec(const RobotSpec& spec, bool server_has_urdf, tasks::RobotOptions* options);

}  // namespace gd::service
