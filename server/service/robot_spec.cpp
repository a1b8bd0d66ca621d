#include "service/robot_spec.h"

#include <spdlog/fmt/fmt.h>

#include <cmath>

#include "tasks/robot_arms.h"

namespace gd::service {

Status apply_robot_spec(const RobotSpec& spec, bool server_has_urdf, tasks::RobotOptions* options) {
  if (spec.urdf_xml.size() > kMaxUrdfBytes)
    return Status::ResourceExhausted(fmt::format("the robot URDF is {} bytes, over the limit of {} (send the URDF "
                                                 "without meshes or comments inlined)",
                                                 spec.urdf_xml.size(), kMaxUrdfBytes));
  if (spec.urdf_xml.empty() && !server_has_urdf)
    return Status::FailedPrecondition(
        "robot mode needs the arms' URDF: send its text in the request's robot settings (RobotSettings.urdf), or "
        "start the server with --robot-urdf PATH (e.g. RGBench's piper_with_gripper.urdf)");
  if (spec.grip_force) {
    if (!std::isfinite(*spec.grip_force) || *spec.grip_force <= 0)
      return Status::InvalidArgument(
          fmt::format("robot grip_force must be a finite number > 0 N (got {})", *spec.grip_force));
    options->grip_force = *spec.grip_force;
  }
  if (spec.finger_friction) {
    if (!std::isfinite(*spec.finger_friction) || *spec.finger_friction < 0)
      return Status::InvalidArgument(
          fmt::format("robot finger_friction must be a finite number >= 0 (got {})", *spec.finger_friction));
    options->finger_friction = *spec.finger_friction;
  }
  if (spec.pad_stiffness) {
    if (!std::isfinite(*spec.pad_stiffness) || *spec.pad_stiffness < 0)
      return Status::InvalidArgument(fmt::format(
          "robot pad_stiffness must be a finite number >= 0 N/m (0: pads wait where the cloth stops them; got {})",
          *spec.pad_stiffness));
    options->pad_stiffness = *spec.pad_stiffness;
  }
  if (spec.lift_max_tilt_deg) {
    const double deg = *spec.lift_max_tilt_deg;
    if (!std::isfinite(deg) || deg < 0 || deg > 180)
      return Status::InvalidArgument(
          fmt::format("robot lift_max_tilt_deg must be a finite angle in [0, 180] degrees (got {})", deg));
    options->lift_max_tilt = deg * 3.14159265358979323846 / 180;
  }
  return Status::Ok();
}

}  // namespace gd::service
