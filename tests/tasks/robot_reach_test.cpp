// Generated tasks fitted to the arms' reach (tasks/robot_reach.h): a lift the Piper cannot follow
// with its hand pointing down is lowered to the highest one it can, to within the resolution; a
// reachable one is kept; a task out of reach from the start is refused. Automatic placement moves
// the task to where the arms lift highest (or tilt least), keeps the given place on a tie and is
// refused where no place is within reach.
#include "tasks/robot_reach.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

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

// A fit from a lowest height (a fold's turns are fitted from 1 cm up, fold_arc = 0 being another
// path) stays at or above it; where the task already tilts a hand beyond the bound there, the bound
// is that tilt plus a degree, and the fit the highest within it.
TEST(RobotReach, AFitFromALowestHeightStaysAboveItWithinADegreeOfItsTilt) {
  if (testing::piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  RobotOptions ro;
  ro.urdf = testing::piper_urdf();
  const auto arms = std::make_shared<const robot::ArmModel>(robot::ArmModel::load(ro.urdf, ro.arm));
  auto make = [](double h) { return lift_by(h); };
  const double lowest = 0.3, resolution = 0.01;
  const double at_lowest = RobotController(lift_by(lowest), ro, arms).ik_max_tilt();
  ASSERT_GT(at_lowest, 30 * kReachDeg);  // 30 cm up the Piper no longer points down within 30 degrees
  const ReachFit fit = fit_height_to_reach(make, 0.8, ro, arms, 30 * kReachDeg, resolution, 8, lowest);
  EXPECT_TRUE(fit.lowered());
  EXPECT_GE(fit.height, lowest);
  EXPECT_NEAR(fit.bound, at_lowest + 1 * kReachDeg, 0.1 * kReachDeg);  // every 8th sample: within a tenth
  EXPECT_LE(fit.tilt, fit.bound);
  const RobotController above(lift_by(fit.height + 2 * resolution), ro, arms);
  EXPECT_GT(above.ik_max_tilt(), fit.bound);
  EXPECT_THROW(fit_height_to_reach(make, 0.2, ro, arms, 30 * kReachDeg, resolution, 8, lowest), sim::InputError);
  EXPECT_THROW(fit_height_to_reach(make, 0.8, ro, arms, 30 * kReachDeg, resolution, 8, -0.1), sim::InputError);
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

TEST(RobotReach, PlacementMovesALiftToWhereTheArmsLiftHighest) {
  if (testing::piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  RobotOptions ro;
  ro.urdf = testing::piper_urdf();
  const auto arms = std::make_shared<const robot::ArmModel>(robot::ArmModel::load(ro.urdf, ro.arm));
  const double resolution = 0.01, bound = 30 * kReachDeg;
  auto make = [](double shift, double h) { return lift_by(h, 0.163 + shift); };
  const std::vector<double> shifts{0.0, 0.05, -0.05, 0.1, 0.15, 0.2};
  const PlacementFit fit = place_within_reach(make, 0.8, /*fit_height=*/true, shifts, ro, arms, bound, resolution);
  EXPECT_EQ(fit.candidates, 6);
  EXPECT_EQ(fit.reachable, 6);
  // Each shift fitted on its own, on the fit's own samples: the placement's height is the highest
  // of them (to the resolution: shifts are compared on coarser samples), and higher than where
  // the lift was given.
  double highest = 0, at_given = 0;
  for (double s : shifts) {
    const ReachFit own = fit_height_to_reach([&](double h) { return make(s, h); }, 0.8, ro, arms, bound, resolution);
    highest = std::max(highest, own.height);
    if (s == 0.0) at_given = own.height;
    if (s == fit.shift) EXPECT_EQ(own.height, fit.reach.height);  // the winner refitted as fit_height_to_reach does
  }
  EXPECT_NE(fit.shift, 0.0);
  EXPECT_GT(fit.reach.height, at_given + resolution);
  EXPECT_GE(fit.reach.height, highest - 2 * resolution);
  EXPECT_LE(fit.reach.tilt, fit.reach.bound);
  // The run's controller at the place and height found keeps its hands within the bound.
  const RobotController run(make(fit.shift, fit.reach.height), ro, arms);
  EXPECT_LE(run.ik_max_tilt(), bound + 1 * kReachDeg);
}

TEST(RobotReach, PlacementKeepsTheGivenPlaceOnATieAndIsRefusedWhereNothingReaches) {
  if (testing::piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  RobotOptions ro;
  ro.urdf = testing::piper_urdf();
  const auto arms = std::make_shared<const robot::ArmModel>(robot::ArmModel::load(ro.urdf, ro.arm));
  const double bound = 30 * kReachDeg;
  auto make = [](double shift, double h) { return lift_by(h, 0.163 + shift); };
  const std::vector<double> shifts{0.0, 0.05, 0.1};
  // 5 cm is reached at every shift: the given place stays.
  const PlacementFit low = place_within_reach(make, 0.05, true, shifts, ro, arms, bound);
  EXPECT_EQ(low.shift, 0.0);
  EXPECT_EQ(low.reach.height, 0.05);
  EXPECT_EQ(low.candidates, 1);  // the height asked is reached at once: no other place can beat it
  // A height given (not fitted): the place where the hands tilt least, never more than at the given one.
  const PlacementFit given = place_within_reach(make, 0.15, /*fit_height=*/false, shifts, ro, arms, bound);
  EXPECT_EQ(given.reach.height, 0.15);
  EXPECT_EQ(given.trials, 3);
  const double tilt0 = RobotController(thin_trajectory(make(0.0, 0.15), 8), ro, arms).ik_max_tilt();
  EXPECT_LE(given.reach.tilt, tilt0);
  for (double s : shifts)
    EXPECT_GE(RobotController(thin_trajectory(make(s, 0.15), 8), ro, arms).ik_max_tilt(),
              given.reach.tilt - 1 * kReachDeg);
  // 1.5 m out and farther: out of reach at every place, named in the refusal.
  auto far = [](double shift, double h) { return lift_by(h, 1.5 + shift); };
  try {
    place_within_reach(far, 0.3, true, shifts, ro, arms, bound);
    ADD_FAILURE() << "a task out of reach everywhere was placed";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("out of the arms' reach with the garment moved anywhere from +0.000 to "
                                         "+0.100 m"),
              std::string::npos)
        << e.what();
  }
  EXPECT_THROW(place_within_reach(make, 0.3, true, {}, ro, arms, bound), sim::InputError);
  EXPECT_THROW(place_within_reach(make, 0.3, true, {0.0, std::nan("")}, ro, arms, bound), sim::InputError);
  EXPECT_THROW(place_within_reach(make, 0.3, true, shifts, ro, arms, -1.0), sim::InputError);
}

TEST(RobotReach, DefaultPlacementShiftsStartAtTheGivenPlaceNearestFirst) {
  const std::vector<double> s = default_placement_shifts();
  ASSERT_FALSE(s.empty());
  EXPECT_EQ(s.front(), 0.0);
  EXPECT_NEAR(*std::max_element(s.begin(), s.end()), 0.30, 1e-12);
  EXPECT_NEAR(*std::min_element(s.begin(), s.end()), -0.10, 1e-12);
  for (size_t i = 1; i < s.size(); ++i) EXPECT_GE(std::abs(s[i]) + 1e-12, std::abs(s[i - 1]));
}

}  // namespace
}  // namespace gd::tasks
