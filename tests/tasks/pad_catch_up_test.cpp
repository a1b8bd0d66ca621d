// A gripper pad that stopped short of its target (a yielding collider) catches up by a bounded
// amount per step: tasks::pad_catch_up.
#include <gtest/gtest.h>

#include <cmath>

#include "tasks/robot_arms.h"

namespace gd::tasks {
namespace {

Eigen::Isometry3d pose(const Vec3& p, double angle_about_z) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = Eigen::AngleAxisd(angle_about_z, Vec3::UnitZ()).toRotationMatrix();
  out.translation() = p;
  return out;
}

TEST(PadCatchUp, APadOnItsTargetFollowsItExactlyHoweverFarTheTargetMoves) {
  const Eigen::Isometry3d last = pose(Vec3(0.1, 0.2, 0.3), 0.1);
  const Eigen::Isometry3d next = pose(Vec3(0.15, 0.2, 0.3), 0.4);  // 5 cm in one step (a fling)
  const Eigen::Isometry3d out = pad_catch_up(last, last, next, 5e-4);
  EXPECT_LT((out.translation() - next.translation()).norm(), 1e-15);
  EXPECT_LT((out.linear() - next.linear()).norm(), 1e-12);
}

TEST(PadCatchUp, APadBehindItsTargetCatchesUpByAtMostTheExtraPerStep) {
  // The target moved 2 mm since the last step; the pad stopped 10 mm behind it.
  const Eigen::Isometry3d last = pose(Vec3(0, 0, 0.008), 0.0);
  const Eigen::Isometry3d target = pose(Vec3(0, 0, 0.010), 0.2);
  const Eigen::Isometry3d at = pose(Vec3(0, 0, 0), 0.0);
  const Eigen::Isometry3d out = pad_catch_up(at, last, target, 5e-4);
  EXPECT_NEAR(out.translation().z(), 0.0025, 1e-12);  // its target's own 2 mm plus 0.5 mm
  EXPECT_NEAR(out.translation().head<2>().norm(), 0.0, 1e-15);
  // The orientation goes the same fraction of the way (a quarter).
  EXPECT_NEAR(Eigen::AngleAxisd(out.linear()).angle(), 0.25 * 0.2, 1e-9);
  // Step after step the lag shrinks by the extra until the pad is on its target.
  Eigen::Isometry3d pad = out, tgt = target;
  int steps = 0;
  while ((pad.translation() - tgt.translation()).norm() > 0 && steps < 100) {
    const Eigen::Isometry3d next = pose(tgt.translation() + Vec3(0, 0, 0.002), 0.2);  // still rising 2 mm per step
    pad = pad_catch_up(pad, tgt, next, 5e-4);
    tgt = next;
    ++steps;
  }
  EXPECT_EQ(steps, 15);  // 7.5 mm of lag left, made up at 0.5 mm per step
  EXPECT_LT((pad.linear() - tgt.linear()).norm(), 1e-12);
}

TEST(PadCatchUp, ALagWithinTheExtraIsMadeUpAtOnce) {
  const Eigen::Isometry3d target = pose(Vec3(0.01, 0, 0), 0.0);
  const Eigen::Isometry3d at = pose(Vec3(0.0097, 0, 0), 0.0);  // 0.3 mm behind, target at rest
  const Eigen::Isometry3d out = pad_catch_up(at, target, target, 5e-4);
  EXPECT_LT((out.translation() - target.translation()).norm(), 1e-15);
}

}  // namespace
}  // namespace gd::tasks
