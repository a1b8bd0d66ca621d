#pragma once
/// \file
/// Robot mode's settings as scenes and jobs take them (proto RobotSettings; docs/robot.md).

#include <array>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

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

  bool empty() const {
    return urdf_xml.empty() && !grip_force && !finger_friction && initial_joints[0].empty() && initial_joints[1].empty();
  }
};

}  // namespace gd::service
