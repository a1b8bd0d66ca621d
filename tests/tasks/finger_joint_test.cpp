// The gripper's position-controlled, force-limited finger joint over one step:
// tasks::finger_joint_step (the law tasks::RobotController applies to each hand every step).
#include <gtest/gtest.h>

#include "tasks/robot_arms.h"

namespace gd::tasks {
namespace {

// A Piper-like joint: 35 mm of travel, 10 N, 1.5 mm contact distance, 2 mm per step at full speed.
FingerJointInput joint(double opening, double command, double squeeze) {
  FingerJointInput in;
  in.opening = opening;
  in.command = command;
  in.squeeze = squeeze;
  in.limit = 10;
  in.max_step = 0.002;
  in.dhat = 0.0015;
  in.opening_max = 0.035;
  return in;
}

TEST(FingerJoint, ClosesAtFullSpeedInFreeAirAndStopsAtTheCommand) {
  EXPECT_DOUBLE_EQ(finger_joint_step(joint(0.020, 0.0, 0.0)), 0.018);
  EXPECT_DOUBLE_EQ(finger_joint_step(joint(0.001, 0.0, 0.0)), 0.0);
  // A light touch (under 10% of the limit) does not slow it.
  EXPECT_DOUBLE_EQ(finger_joint_step(joint(0.020, 0.0, 0.9)), 0.018);
}

TEST(FingerJoint, ApproachesTheLimitByHalfTheWayAtTheSecantStiffness) {
  FingerJointInput in = joint(0.0010, 0.0, 6.0);
  in.stiffness = 20000;  // N/m: 4 N short of the limit is 0.2 mm; half of it is closed
  EXPECT_NEAR(finger_joint_step(in), 0.0010 - 0.0001, 1e-15);
  in.stiffness = 0;  // unknown: 5% of the contact distance
  EXPECT_NEAR(finger_joint_step(in), 0.0010 - 0.05 * 0.0015, 1e-15);
}

TEST(FingerJoint, GivesWayAboveTheLimitWhereThePadsReachedTheirPoses) {
  FingerJointInput in = joint(0.0010, 0.0, 14.0);
  in.stiffness = 20000;  // 4 N over the limit: opens by half of 0.2 mm
  EXPECT_NEAR(finger_joint_step(in), 0.0011, 1e-15);
  in.opening = 0.0349;  // never past the joint's travel
  EXPECT_DOUBLE_EQ(finger_joint_step(in), 0.035);
}

TEST(FingerJoint, HoldsItsOpeningAboveTheLimitWhileThePadsStandStoppedShort) {
  FingerJointInput in = joint(0.0010, 0.0, 400.0);  // the cloth the moving hand pressed
  in.stiffness = 20000;
  for (const double reached : {0.0, 0.03, 0.999}) {
    in.reached = reached;
    EXPECT_DOUBLE_EQ(finger_joint_step(in), 0.0010) << "reached " << reached;
  }
  // Below the limit a stopped-short hand still closes towards it.
  in.squeeze = 6.0;
  in.reached = 0.5;
  EXPECT_LT(finger_joint_step(in), 0.0010);
}

TEST(FingerJoint, OpeningAgainstClothStopsAtTheLimitAndClosesAboveIt) {
  EXPECT_DOUBLE_EQ(finger_joint_step(joint(0.010, 0.035, -0.5)), 0.012);   // a light push: full speed
  EXPECT_DOUBLE_EQ(finger_joint_step(joint(0.010, 0.035, -5.0)), 0.010 + 0.05 * 0.0015);  // slowed
  EXPECT_DOUBLE_EQ(finger_joint_step(joint(0.010, 0.035, -12.0)), 0.010 - 0.05 * 0.0015);  // gives way
  EXPECT_DOUBLE_EQ(finger_joint_step(joint(0.00005, 0.035, -12.0)), 0.0);  // down to the floor
  EXPECT_DOUBLE_EQ(finger_joint_step(joint(0.034, 0.035, 0.0)), 0.035);    // stops at the command
}

TEST(FingerJoint, StaysWhereTheCommandIs) {
  EXPECT_DOUBLE_EQ(finger_joint_step(joint(0.012, 0.012, 30.0)), 0.012);
}

}  // namespace
}  // namespace gd::tasks
