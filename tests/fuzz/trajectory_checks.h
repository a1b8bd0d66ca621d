#pragma once
/// \file
/// Properties of a trajectory a reader accepted (shared by the trajectory fuzz targets).

#include <cmath>

#include "fuzz_common.h"
#include "tasks/trajectory.h"

namespace gd::fuzz {

/// Every sample finite with a unit quaternion, times strictly increasing per arm.
inline void check_trajectory(const gd::tasks::DualArmTrajectory& t) {
  GD_FUZZ_CHECK(std::isfinite(t.master_start_time), "master_start_time");
  for (const gd::tasks::ArmTrajectory* a : {&t.left, &t.right}) {
    const auto& s = a->samples();
    for (size_t k = 0; k < s.size(); ++k) {
      GD_FUZZ_CHECK(std::isfinite(s[k].t) && s[k].position.allFinite() && std::isfinite(s[k].gripper) &&
                        s[k].gripper >= 0,
                    "sample " + std::to_string(k));
      GD_FUZZ_CHECK(std::abs(s[k].orientation.norm() - 1) < 1e-9, "sample " + std::to_string(k) + " quaternion");
      GD_FUZZ_CHECK(k == 0 || s[k].t > s[k - 1].t, "sample " + std::to_string(k) + " time");
    }
  }
}

/// `b` (read back from what was written of `a`) holds the same samples.
inline void check_same(const gd::tasks::DualArmTrajectory& a, const gd::tasks::DualArmTrajectory& b,
                       const char* how) {
  GD_FUZZ_CHECK(a.master_start_time == b.master_start_time, how);
  for (const gd::tasks::Arm arm : {gd::tasks::Arm::kLeft, gd::tasks::Arm::kRight}) {
    const auto& x = a.arm(arm).samples();
    const auto& y = b.arm(arm).samples();
    GD_FUZZ_CHECK(x.size() == y.size(), how);
    for (size_t k = 0; k < x.size(); ++k) {
      GD_FUZZ_CHECK(x[k].t == y[k].t && x[k].position == y[k].position && x[k].gripper == y[k].gripper,
                    std::string(how) + ": sample " + std::to_string(k));
      GD_FUZZ_CHECK(x[k].orientation.angularDistance(y[k].orientation) < 1e-6,
                    std::string(how) + ": sample " + std::to_string(k) + " orientation");
    }
  }
}

}  // namespace gd::fuzz
