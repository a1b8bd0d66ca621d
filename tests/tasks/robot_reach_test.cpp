// Generated tasks fitted to the arms' reach (tasks/robot_reach.h): a lift the Piper cannot follow
// with its hand pointing down is lowered to the highest one it can, to within the resolution; a
// reachable one is kept; a task out of reach from the start is refused.
#include "tasks/robot_reach.h"

#include <gtest/gtest.h>

#include <cmath>

#include "sim/demand.h"
#include "tasks/frames.h"
#include "tasks/task_test_util.h"

namespace gd::tasks {
namespace {

/// The left hand, top down, goes down onto (x, 0.178) in 0.4 s and lifts it by h until t = 2 s
/// (samples every 20 ms); the right hand waits open 8 cm above the mirror point.
DualArmTrajectory lift_by(double h, double x = 0.163) {
  std::vector<double> times;
  for (int k = 0; k <= 100; ++k) times.push_back(0.02 * k);
  return testing::two_arms(
      times, [&](double t) { return Vec3(x, 0.178, t <= 0.4 ? 0.08 - 0.125 * t : 0.03 + h * (t - 0.4) / 1.6); },
      [](double) { return kGripperOpen; }, Vec3(0.163, -0.178, 0.08));
}

constexpr double kReachDeg = 3.14159265358979323846 / 180;

TEST(RobotReach, AnUnreachableLiftIsLoweredToTheHighestWithinTheTiltBound) {
  if (testing::piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  RobotOptions ro;
  ro.urdf = testing::piper_urdf();
  const auto arms = std::make_shared<const robot::ArmModel>(robot::ArmModel::load(ro.urdf, ro.arm));
  // 0.8 m above a grasp 16 cm in front of the base: the Piper cannot point down there at all.
  EXPECT_THROW(RobotController(lift_by(0.8), ro, arms), sim::InputError);
  const double resolution = 0.01;
  const ReachFit fit =
      fit_height_to_reach([](double h) { return lift_by(h); }, 0.8, ro, arms, 30 * kReachDeg, resolution);
  EXPECT_TRUE(fit.lowered());
  EXPECT_EQ(fit.wanted, 0.8);
  EXPECT_GT(fit.height, 0.05);
  EXPECT_LT(fit.height, 0.8);
  EXPECT_NEAR(fit.bound, 30 * kReachDeg, 1e-12);  // the hands point straight down at height 0
  EXPECT_LE(fit.tilt, fit.bound);
  EXPECT_LE(fit.trials, 2 + static_cast<int>(std::ceil(std::log2(0.8 / resolution))));
  // The run solves every sample, not every eighth: its hands stay within the bound too (to a
  // degree: the poses between the trial's lie a few millimetres from them).
  const RobotController at(lift_by(fit.height), ro, arms);
  EXPECT_LE(at.ik_max_tilt(), fit.bound + 1 * kReachDeg);
  EXPECT_NEAR(at.ik_max_tilt(), fit.tilt, 1 * kReachDeg);
  // The highest within the resolution: a little higher tilts a hand beyond the bound.
  const RobotController above(lift_by(fit.height + 2 * resolution), ro, arms);
  EXPECT_GT(above.ik_max_tilt(), fit.bound);
}

TEST(RobotReach, AReachableLiftIsKeptAndATaskOutOfReachFromTheStartIsRefused) {
  if (testing::piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  RobotOptions ro;
  ro.urdf = testing::piper_urdf();
  const auto arms = std::make_shared<const robot::ArmModel>(robot::ArmModel::load(ro.urdf, ro.arm));
  const ReachFit low = fit_height_to_reach([](double h) { return lift_by(h); }, 0.05, ro, arms, 30 * kReachDeg);
  EXPECT_FALSE(low.lowered());
  EXPECT_EQ(low.height, 0.05);
  EXPECT_EQ(low.trials, 2);  // height 0, then the height asked
  EXPECT_LE(low.tilt, 30 * kReachDeg);
  // A grasp 1.5 m in front of the base: no lift helps; the controller's refusal comes through.
  try {
    fit_height_to_reach([](double h) { return lift_by(h, 1.5); }, 0.3, ro, arms, 30 * kReachDeg);
    ADD_FAILURE() << "a task out of reach was fitted";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("left arm cannot reach its pose"), std::string::npos) << e.what();
  }
  auto make = [](double h) { return lift_by(h); };
  EXPECT_THROW(fit_height_to_reach(make, -0.1, ro, arms, 30 * kReachDeg), sim::InputError);
  EXPECT_THROW(fit_height_to_reach(make, std::nan(""), ro, arms, 30 * kReachDeg), sim::InputError);
  EXPECT_THROW(fit_height_to_reach(make, 0.3, ro, arms, -1.0), sim::InputError);
  EXPECT_THROW(fit_height_to_reach(make, 0.3, ro, arms, 30 * kReachDeg, 0.0), sim::InputError);
  EXPECT_THROW(fit_height_to_reach(make, 0.3, ro, arms, 30 * kReachDeg, 0.01, 0), sim::InputError);
}

TEST(RobotReach, ThinningKeepsEveryStridethSampleAndEachArmsLast) {
  const DualArmTrajectory all = lift_by(0.2);  // 101 samples per arm
  const DualArmTrajectory thin = thin_trajectory(all, 8);
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    const auto& s = thin.arm(a).samples();
    ASSERT_EQ(s.size(), 14u);  // 0, 8, ..., 96, then 100
    for (size_t i = 0; i + 1 < s.size(); ++i) EXPECT_EQ(s[i].t, all.arm(a).samples()[8 * i].t);
    EXPECT_EQ(s.back().t, all.arm(a).samples().back().t);
    EXPECT_EQ(s.back().position, all.arm(a).samples().back().position);
  }
  EXPECT_EQ(thin_trajectory(all, 1).left.size(), 101u);
  EXPECT_EQ(thin_trajectory(all, 100).left.size(), 2u);  // the first and the last
  EXPECT_EQ(thin_trajectory(all, 200).left.size(), 2u);
}

}  // namespace
}  // namespace gd::tasks
