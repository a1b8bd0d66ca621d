// ArmModel: URDF loading, forward kinematics against closed forms, inverse kinematics round trips
// within the joint limits, and the errors a user gets for an unusable URDF.
#include "robot/arm_model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <thread>

#include "sim/demand.h"

namespace gd::robot {
namespace {

/// A planar two-joint arm (z axes, links 0.3 and 0.2 m along x, base 0.1 m up) with a gripper
/// whose fingers slide along the hand's y axis: forward kinematics in closed form.
std::string two_link_urdf(const std::string& finger2_type = "prismatic") {
  return R"(<?xml version="1.0"?>
<robot name="planar">
  <link name="base_link"/><link name="l1"/><link name="l2"/><link name="hand"/><link name="fa"/><link name="fb"/>
  <joint name="j1" type="revolute"><parent link="base_link"/><child link="l1"/>
    <origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.3 0 0" rpy="0 0 0"/><axis xyz="0 0 1"/><limit lower="-2.5" upper="2.5" effort="1" velocity="1"/></joint>
  <joint name="j3" type="fixed"><parent link="l2"/><child link="hand"/><origin xyz="0.2 0 0" rpy="0 0 0"/></joint>
  <joint name="fj1" type="prismatic"><parent link="hand"/><child link="fa"/>
    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/><limit lower="0" upper="0.04" effort="1" velocity="1"/></joint>
  <joint name="fj2" type=")" + finger2_type + R"("><parent link="hand"/><child link="fb"/>
    <origin xyz="0 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/><limit lower="-0.03" upper="0" effort="1" velocity="1"/></joint>
</robot>)";
}

ArmModelOptions two_link_options() {
  ArmModelOptions o;
  o.ee_link = "hand";
  o.finger_joints = {"fj1", "fj2"};
  return o;
}

/// RGBench's Piper URDF under ../shared, or "" (tests that need it skip).
std::string piper_urdf() {
  std::filesystem::path shared;
  if (const char* s = std::getenv("GD_SHARED_DIR"); s && *s) shared = s;
  const auto p = shared / "data" / "rgbench" / "piper_with_gripper.urdf";
  return !shared.empty() && std::filesystem::exists(p) ? p.string() : "";
}

template <class F>
void expect_input_error(F&& f, const std::string& needle) {
  try {
    f();
    ADD_FAILURE() << "no InputError thrown";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

TEST(ArmModel, ForwardKinematicsOfAPlanarArmMatchesItsClosedForm) {
  const ArmModel arm = ArmModel::from_string(two_link_urdf(), "planar", two_link_options());
  EXPECT_EQ(arm.arm_dofs(), 2);
  EXPECT_EQ(arm.arm_joint_names(), (std::vector<std::string>{"j1", "j2"}));
  EXPECT_DOUBLE_EQ(arm.gripper_max(), 0.03);  // the shorter finger's travel
  EXPECT_EQ(arm.finger_links()[0], "fa");
  for (const auto& [a, b] : {std::pair{0.0, 0.0}, {0.7, -1.2}, {-2.1, 2.4}}) {
    Eigen::VectorXd q(2);
    q << a, b;
    const Eigen::Vector3d expect(0.3 * std::cos(a) + 0.2 * std::cos(a + b), 0.3 * std::sin(a) + 0.2 * std::sin(a + b), 0.1);
    const Eigen::Isometry3d ee = arm.ee_pose(q);
    EXPECT_LT((ee.translation() - expect).norm(), 1e-12);
    EXPECT_NEAR(std::atan2(ee.linear()(1, 0), ee.linear()(0, 0)), std::remainder(a + b, 2 * M_PI), 1e-12);
    // The fingers slide along the hand's y axis, +g and -g: 2g apart.
    const double g = 0.02;
    const Eigen::Isometry3d fa = arm.link_pose("fa", q, g), fb = arm.link_pose("fb", q, g);
    EXPECT_LT((fa.translation() - (ee * Eigen::Vector3d(0, g, 0))).norm(), 1e-12);
    EXPECT_LT((fb.translation() - (ee * Eigen::Vector3d(0, -g, 0))).norm(), 1e-12);
    // A gripper value beyond the travel is clamped.
    EXPECT_LT((arm.link_pose("fa", q, 1.0).translation() - (ee * Eigen::Vector3d(0, 0.03, 0))).norm(), 1e-12);
    // The chain (a viewer's skeleton): from the base through the elbow to the end effector.
    const std::vector<Eigen::Vector3d> chain = arm.chain_points(q);
    ASSERT_GE(chain.size(), 3u);
    EXPECT_LT(chain.front().norm(), 1e-12);
    EXPECT_LT((chain.back() - ee.translation()).norm(), 1e-12);
    const Eigen::Vector3d elbow(0.3 * std::cos(a), 0.3 * std::sin(a), 0.1);
    double nearest = 1e9;
    for (const Eigen::Vector3d& p : chain) nearest = std::min(nearest, (p - elbow).norm());
    EXPECT_LT(nearest, 1e-12);
    for (size_t k = 1; k < chain.size(); ++k) EXPECT_GT((chain[k] - chain[k - 1]).norm(), 1e-6);  // no repeats
  }
}

TEST(ArmModel, InverseKinematicsOfAPlanarArmReachesReachablePosesAndReportsUnreachableOnes) {
  const ArmModel arm = ArmModel::from_string(two_link_urdf(), "planar", two_link_options());
  Eigen::VectorXd q(2), seed = Eigen::VectorXd::Zero(2);
  q << 0.9, -1.4;
  const IkResult r = arm.ik(arm.ee_pose(q), seed);
  EXPECT_TRUE(r.ok);
  EXPECT_LT(r.position_error, 1e-6);
  EXPECT_LT((arm.ee_pose(r.q).translation() - arm.ee_pose(q).translation()).norm(), 1e-6);
  // 0.6 m away: beyond the 0.5 m reach.
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.translation() = Eigen::Vector3d(0.6, 0, 0.1);
  const IkResult f = arm.ik(far, seed);
  EXPECT_FALSE(f.ok);
  EXPECT_NEAR(f.position_error, 0.1, 1e-3);  // the best it can do: stretched out towards it
}

TEST(ArmModel, UnusableUrdfsAreRefusedWithWhatIsWrong) {
  expect_input_error([] { ArmModel::load("/nonexistent/arm.urdf"); }, "cannot be read");
  expect_input_error([] { ArmModel::from_string("<robot name='x'><link", "broken"); }, "not a valid URDF");
  expect_input_error([] { ArmModel::from_string(two_link_urdf(), "planar"); }, "no link named 'link7'");
  ArmModelOptions o = two_link_options();
  o.finger_joints = {"fj1", "nope"};
  expect_input_error([&] { ArmModel::from_string(two_link_urdf(), "planar", o); }, "no finger joint named 'nope'");
  expect_input_error([] { ArmModel::from_string(two_link_urdf("revolute"), "planar", two_link_options()); },
                     "must be prismatic");
  const ArmModel arm = ArmModel::from_string(two_link_urdf(), "planar", two_link_options());
  expect_input_error([&] { arm.ee_pose(Eigen::VectorXd::Zero(3)); }, "2 arm joint values expected");
  expect_input_error([&] { arm.link_pose("elbow", Eigen::VectorXd::Zero(2), 0); }, "no link named 'elbow'");
  Eigen::VectorXd bad(2);
  bad << 0, NAN;
  expect_input_error([&] { arm.ee_pose(bad); }, "joint j2 is not finite");
}

TEST(ArmModel, PiperChainAndFingersFollowTheUrdf) {
  const std::string path = piper_urdf();
  if (path.empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  const ArmModel arm = ArmModel::load(path);
  EXPECT_EQ(arm.arm_joint_names(), (std::vector<std::string>{"joint1", "joint2", "joint3", "joint4", "joint5", "joint6"}));
  EXPECT_DOUBLE_EQ(arm.gripper_max(), 0.035);
  EXPECT_EQ(arm.finger_links()[0], "link7");
  EXPECT_EQ(arm.finger_links()[1], "link8");
  // Base to first joint: joint1 sits 0.123 m above base_link, on its z axis.
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(6);
  EXPECT_LT((arm.link_pose("link1", zero, 0).translation() - Eigen::Vector3d(0, 0, 0.123)).norm(), 1e-12);
  std::mt19937 rng(7);
  for (int trial = 0; trial < 5; ++trial) {
    Eigen::VectorXd q(6);
    for (int k = 0; k < 6; ++k) {
      const JointLimits l = arm.arm_limits()[k];
      q[k] = std::uniform_real_distribution<double>(l.lower, l.upper)(rng);
    }
    // The end effector is link7 with the fingers closed; the fingers open symmetrically about
    // it along the gripper's y axis, 2g apart, and their frame z axes point away from each other.
    const Eigen::Isometry3d ee = arm.ee_pose(q);
    EXPECT_LT((arm.link_pose("link7", q, 0).matrix() - ee.matrix()).norm(), 1e-12);
    const Eigen::Isometry3d gb = arm.link_pose("gripper_base", q, 0.03);
    const Eigen::Isometry3d f7 = arm.link_pose("link7", q, 0.03), f8 = arm.link_pose("link8", q, 0.03);
    // (The URDF writes its right angles as 1.5708 and pi as 3.1416, hence the tolerances.)
    const Eigen::Vector3d gy = gb.linear().col(1);
    EXPECT_NEAR((f8.translation() - f7.translation()).dot(gy), 0.06, 1e-9);
    EXPECT_NEAR((f8.translation() - f7.translation()).norm(), 0.06, 1e-9);
    EXPECT_NEAR(f7.linear().col(2).dot(-gy), 1.0, 1e-9);
    EXPECT_NEAR(f8.linear().col(2).dot(gy), 1.0, 1e-9);
    // The fingertips lie 0.1358 m along the gripper's approach axis from the flange.
    EXPECT_NEAR((ee.translation() - gb.translation()).dot(gb.linear().col(2)), 0.1358, 1e-9);
  }
}

TEST(ArmModel, PiperInverseKinematicsRoundTripsWithinTheLimits) {
  const std::string path = piper_urdf();
  if (path.empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  const ArmModel arm = ArmModel::load(path);
  std::mt19937 rng(11);
  int reached = 0;
  const int trials = 40;
  for (int trial = 0; trial < trials; ++trial) {
    Eigen::VectorXd q(6), seed(6);
    for (int k = 0; k < 6; ++k) {
      const JointLimits l = arm.arm_limits()[k];
      q[k] = std::uniform_real_distribution<double>(l.lower + 0.1, l.upper - 0.1)(rng);
      // A seed as along a trajectory: the previous sample's joints, 0.1 rad away.
      seed[k] = q[k] + std::uniform_real_distribution<double>(-0.1, 0.1)(rng);
    }
    const Eigen::Isometry3d target = arm.ee_pose(q);
    const IkResult r = arm.ik(target, seed);
    for (int k = 0; k < 6; ++k) {
      EXPECT_GE(r.q[k], arm.arm_limits()[k].lower);
      EXPECT_LE(r.q[k], arm.arm_limits()[k].upper);
    }
    if (!r.ok) continue;
    ++reached;
    const Eigen::Isometry3d at = arm.ee_pose(r.q);
    EXPECT_LT((at.translation() - target.translation()).norm(), 1e-4);
    EXPECT_LT(Eigen::AngleAxisd(at.linear().transpose() * target.linear()).angle(), 1e-3);
  }
  EXPECT_EQ(reached, trials);  // every pose came from joints within the limits
}

// The Piper's wrist cannot point straight down 26 cm above its base: the exact pose is out of
// reach, position-first IK reaches the point and tilts as little as it finds (37 degrees here).
TEST(ArmModel, PiperPositionFirstReachesThePointWithTheLeastTilt) {
  const std::string path = piper_urdf();
  if (path.empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  const ArmModel arm = ArmModel::load(path);
  Eigen::Isometry3d down = Eigen::Isometry3d::Identity();
  down.linear().col(0) = Eigen::Vector3d(0, -1, 0);  // link7 y (approach) down, z (closing) along x
  down.linear().col(1) = Eigen::Vector3d(0, 0, -1);
  down.linear().col(2) = Eigen::Vector3d(1, 0, 0);
  const Eigen::VectorXd seed = Eigen::VectorXd::Zero(6);
  down.translation() = Eigen::Vector3d(0.25, 0, 0.05);  // low: exactly reachable
  EXPECT_TRUE(arm.ik(down, seed).ok);
  down.translation() = Eigen::Vector3d(0.25, 0, 0.26);
  EXPECT_FALSE(arm.ik(down, seed).ok);
  const IkResult r = arm.ik_position_first(down, seed, 1.0, 1e-3);
  EXPECT_TRUE(r.ok);
  EXPECT_LT(r.position_error, 1e-3);
  EXPECT_GT(r.rotation_error, 0.3);  // what the wrist's limits force
  EXPECT_LT(r.rotation_error, 0.8);
  EXPECT_FALSE(arm.ik_position_first(down, seed, 0.2, 1e-3).ok);  // more tilt than allowed
}

}  // namespace
}  // namespace gd::robot

namespace gd::robot {
namespace {

// One model shared by threads (a server's scenes share their URDF's arms): inverse and forward
// kinematics from two threads at once give exactly the serial answers (KDL's joints cache their
// last pose, so unguarded concurrent calls race).
TEST(ArmModel, SharedModelGivesTheSerialAnswersFromTwoThreads) {
  const std::string path = piper_urdf();
  if (path.empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  const ArmModel arm = ArmModel::load(path);
  std::vector<Eigen::Isometry3d> targets;
  for (int i = 0; i < 12; ++i) {
    Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
    t.translation() = Eigen::Vector3d(0.2 + 0.01 * i, 0.05 * std::sin(i), 0.1 + 0.01 * i);
    t.linear() = Eigen::AngleAxisd(M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
    targets.push_back(t);
  }
  const Eigen::VectorXd seed = Eigen::VectorXd::Zero(arm.arm_dofs());
  auto solve_all = [&] {
    std::vector<Eigen::VectorXd> out;
    for (const auto& t : targets) out.push_back(arm.ik_position_first(t, seed, 2.1, 1e-3).q);
    return out;
  };
  const std::vector<Eigen::VectorXd> serial = solve_all();
  std::vector<Eigen::VectorXd> a, b;
  std::thread ta([&] { a = solve_all(); });
  std::thread tb([&] { b = solve_all(); });
  ta.join();
  tb.join();
  for (size_t i = 0; i < targets.size(); ++i) {
    EXPECT_EQ(a[i], serial[i]) << i;
    EXPECT_EQ(b[i], serial[i]) << i;
  }
}

}  // namespace
}  // namespace gd::robot
