// The gripper controller on a small cloth: pseudo grasp (take within the jaw radius, follow the
// end-effector rigidly, release, re-grasp) and RGBench's fixed-point semantics (grasp/fold, fling).
#include "tasks/grippers.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <set>

#include "sim/demand.h"
#include "tasks/task_test_util.h"

namespace gd::tasks {
namespace {

using sim::InputError;
using testing::make_scene;


ArmSample S(double t, const Vec3& p, double gripper, const Eigen::Quaterniond& q = top_down_orientation()) {
  return {t, p, q, gripper};
}

/// The cloth: 0.3 x 0.2 m, 2 cm spacing, flat at z = 0.01 (garment frame placed as RGBench's).
sim::Mesh cloth() { return testing::placed(testing::rect_garment(0.3, 0.2, 0.02)); }

/// A parked right arm: open, high above the cloth.
ArmTrajectory parked() { return ArmTrajectory({S(0, Vec3(0.2, -0.25, 0.5), kGripperOpen)}); }

std::vector<int> within(const std::vector<Vec3>& x, const Vec3& p, double r) {
  std::vector<int> out;
  for (size_t i = 0; i < x.size(); ++i)
    if ((x[i] - p).norm() <= r) out.push_back(static_cast<int>(i));
  return out;
}

TEST(PseudoGrasp, TakesTheVerticesWithinTheJawRadiusAndTheyFollowTheEndEffectorRigidly) {
  const sim::Mesh m = cloth();
  auto scene = make_scene(m);
  const Vec3 p0(0.25, 0.0, 0.01);  // on the cloth
  const Eigen::Quaterniond turned = Eigen::AngleAxisd(std::numbers::pi / 2, Vec3::UnitZ()) * top_down_orientation();
  DualArmTrajectory traj;
  traj.left = ArmTrajectory({S(0, p0, kGripperOpen), S(0.05, p0, 0.0), S(0.1, p0, 0.0),
                             S(0.5, p0 + Vec3(0.05, 0, 0.15), 0.0, turned)});
  traj.right = parked();
  GripperController c(traj);
  // The cloth settles onto the table meanwhile; the gripper closes during the step [0.03, 0.04]
  // (its opening drops below 1 cm at t = 0.0357).
  ASSERT_TRUE(run_until(*scene, c, 0.03));
  EXPECT_TRUE(c.events().empty());
  const std::vector<Vec3> xg = scene->positions();
  const std::vector<int> expect = within(xg, p0, 0.02);
  ASSERT_GE(expect.size(), 2u);
  ASSERT_TRUE(run_until(*scene, c, 0.6));
  ASSERT_EQ(c.events().size(), 1u);
  const GripperEvent& e = c.events()[0];
  EXPECT_TRUE(e.grasp);
  EXPECT_EQ(e.arm, Arm::kLeft);
  EXPECT_NEAR(e.t, 0.03, 1e-9);
  EXPECT_EQ(e.vertices, expect);
  EXPECT_EQ(c.state(Arm::kLeft).held, expect);
  EXPECT_TRUE(c.state(Arm::kRight).held.empty());
  EXPECT_EQ(scene->kinematic_vertices(), expect);
  // Rigid motion from the grasp moment: x = EE(t) EE(t_g)^-1 x_g.
  const Eigen::Isometry3d rel = traj.left.pose(scene->time()) * traj.left.pose(e.t).inverse();
  const auto x = scene->positions();
  for (int v : expect) EXPECT_LT((x[v] - rel * xg[v]).norm(), 1e-6) << "vertex " << v;
  // The grasped patch turned with the gripper: its vertices are not just translated.
  EXPECT_GT((x[expect[0]] - x[expect[1]] - (xg[expect[0]] - xg[expect[1]])).norm(), 1e-3);
}

TEST(PseudoGrasp, AppendedCommandsExtendTheMotionOfHeldVertices) {
  // Live control as the service does it: every step appends the pose reached at its end.
  const sim::Mesh m = cloth();
  auto scene = make_scene(m);
  const Vec3 p0(0.25, 0.0, 0.01);
  DualArmTrajectory traj;
  traj.left = ArmTrajectory({S(0, p0, kGripperOpen)});
  traj.right = parked();
  GripperController c(traj);
  const double dt = scene->options().dt;
  c.append(Arm::kLeft, S(dt, p0, 0.0));  // closes during the first step
  ASSERT_TRUE(run_until(*scene, c, dt));
  const std::vector<int> held = c.state(Arm::kLeft).held;
  ASSERT_FALSE(held.empty());
  const std::vector<Vec3> xg = scene->positions();
  Vec3 p = p0;
  for (int k = 2; k <= 20; ++k) {
    p += Vec3(0, 0, 0.005);
    c.append(Arm::kLeft, S(k * dt, p, 0.0));
    ASSERT_TRUE(run_until(*scene, c, k * dt));
  }
  const Vec3 lift = p - p0;
  const auto x = scene->positions();
  for (int v : held) EXPECT_LT((x[v] - (xg[v] + lift)).norm(), 1e-6) << "vertex " << v;
  // Out-of-order and invalid commands are refused with a message.
  EXPECT_THROW(c.append(Arm::kLeft, S(dt, p, 0.0)), InputError);
  EXPECT_THROW(c.append(Arm::kLeft, S(30 * dt, Vec3(NAN, 0, 0), 0.0)), InputError);
}

TEST(PseudoGrasp, ReleaseFreesTheVerticesAndReGraspTakesNewOnes) {
  const sim::Mesh m = cloth();
  auto scene = make_scene(m);
  const Vec3 p0(0.2, 0.05, 0.01), up = p0 + Vec3(0, 0, 0.1);
  DualArmTrajectory traj;
  traj.left = ArmTrajectory({S(0, p0, kGripperOpen), S(0.02, p0, 0.0), S(0.05, p0, 0.0), S(0.3, up, 0.0),
                             S(0.32, up, kGripperOpen),  // opens at the top
                             S(0.6, up, kGripperOpen), S(0.62, up, 0.0)});  // closes again
  traj.right = parked();
  GripperController c(traj);
  ASSERT_TRUE(run_until(*scene, c, 0.29));
  const std::vector<int> first = c.state(Arm::kLeft).held;
  ASSERT_FALSE(first.empty());
  // Opening: released at the step whose end has an opening >= 1 cm; velocities are kept.
  ASSERT_TRUE(run_until(*scene, c, 0.33));
  EXPECT_TRUE(c.state(Arm::kLeft).held.empty());
  EXPECT_TRUE(scene->kinematic_vertices().empty());
  ASSERT_EQ(c.events().size(), 2u);
  EXPECT_FALSE(c.events()[1].grasp);
  EXPECT_EQ(c.events()[1].vertices, first);
  // Free vertices fall away from the (still) gripper.
  ASSERT_TRUE(run_until(*scene, c, 0.6));
  for (int v : first) EXPECT_LT(scene->positions()[v].z(), up.z() - 0.05);
  // Closing again high above the fallen cloth takes nothing (beyond max_reach)...
  ASSERT_TRUE(run_until(*scene, c, 0.7));
  EXPECT_EQ(c.events().size(), 2u);
  EXPECT_TRUE(scene->kinematic_vertices().empty());
}

TEST(PseudoGrasp, ReGraspAfterReopeningOnTheCloth) {
  const sim::Mesh m = cloth();
  auto scene = make_scene(m);
  const Vec3 p0(0.2, 0.05, 0.01);
  DualArmTrajectory traj;
  traj.left = ArmTrajectory({S(0, p0, kGripperOpen), S(0.02, p0, 0.0), S(0.2, p0, 0.0), S(0.22, p0, kGripperOpen),
                             S(0.3, p0, kGripperOpen), S(0.32, p0, 0.0)});
  traj.right = parked();
  GripperController c(traj);
  ASSERT_TRUE(run_until(*scene, c, 0.5));
  ASSERT_EQ(c.events().size(), 3u);
  EXPECT_TRUE(c.events()[0].grasp);
  EXPECT_FALSE(c.events()[1].grasp);
  EXPECT_TRUE(c.events()[2].grasp);
  EXPECT_EQ(scene->kinematic_vertices(), c.state(Arm::kLeft).held);
  EXPECT_FALSE(c.state(Arm::kLeft).held.empty());
}

TEST(PseudoGrasp, IgnoresTheOtherGrippersVerticesAndTakesAtLeastTheNearest) {
  const sim::Mesh m = cloth();
  auto scene = make_scene(m);
  const Vec3 p0(0.2, 0.0, 0.01);
  DualArmTrajectory traj;
  traj.left = ArmTrajectory({S(0, p0, kGripperOpen), S(0.02, p0, 0.0)});
  traj.right = ArmTrajectory({S(0, p0, kGripperOpen), S(0.1, p0, kGripperOpen), S(0.12, p0, 0.0)});
  GripperOptions o;
  o.jaw_radius = 0.0;  // only the nearest free vertex
  GripperController c(traj, o);
  ASSERT_TRUE(run_until(*scene, c, 0.2));
  const auto& l = c.state(Arm::kLeft).held;
  const auto& r = c.state(Arm::kRight).held;
  ASSERT_EQ(l.size(), 1u);
  ASSERT_EQ(r.size(), 1u);
  EXPECT_EQ(l[0], sim::nearest_vertex(m, p0));
  EXPECT_NE(l[0], r[0]);
  EXPECT_EQ(scene->kinematic_vertices().size(), 2u);
}

TEST(FixedPoint, PinsTheNearestInitialVertexAtGrabTimeAndTracksPositionOnly) {
  const sim::Mesh m = cloth();
  auto scene = make_scene(m);
  const Vec3 a(0.12, 0.04, 0.02), b(0.3, -0.02, 0.012);
  const Eigen::Quaterniond turned = Eigen::AngleAxisd(std::numbers::pi / 2, Vec3::UnitZ()) * top_down_orientation();
  DualArmTrajectory traj;
  // Gripper columns say "open" throughout: fixed-point mode ignores them.
  traj.left = ArmTrajectory({S(0, a, kGripperOpen), S(0.3, b, kGripperOpen),
                             S(0.7, b + Vec3(0.02, 0.01, 0.2), kGripperOpen, turned)});
  traj.right = ArmTrajectory({S(0, Vec3(0.15, -0.09, 0.011), kGripperOpen)});
  GripperOptions o;
  o.mode = GraspMode::kFixedPoint;
  o.action = TaskKind::kFold;
  o.grab_time = 0.3;
  GripperController c(traj, o);
  EXPECT_EQ(c.sim_prepare_time(), 0.0);
  ASSERT_TRUE(run_until(*scene, c, 0.25));
  EXPECT_TRUE(c.state(Arm::kLeft).held.empty());
  EXPECT_TRUE(scene->kinematic_vertices().empty());
  ASSERT_TRUE(run_until(*scene, c, 0.7));
  const int vl = sim::nearest_vertex(m, b);  // nearest to the EE at grab_time
  const int vr = sim::nearest_vertex(m, Vec3(0.15, -0.09, 0.011));
  EXPECT_EQ(c.state(Arm::kLeft).held, std::vector<int>{vl});
  EXPECT_EQ(c.state(Arm::kRight).held, std::vector<int>{vr});
  const auto x = scene->positions();
  // Position only: the vertex sits on the EE position itself, not at a rigid offset from it.
  EXPECT_LT((x[vl] - traj.left.sample(scene->time()).position).norm(), 1e-6);
  EXPECT_LT((x[vr] - Vec3(0.15, -0.09, 0.011)).norm(), 1e-6);
  EXPECT_EQ(scene->kinematic_vertices().size(), 2u);
  ASSERT_EQ(c.events().size(), 2u);
  EXPECT_NEAR(c.events()[0].t, 0.3, 1e-9);
}

// The service streams one command per step, so at the first step the controller knows only the
// arms' starting pose; the pins must be chosen at grab_time from the pose then (RGBench's rule),
// not from the start (issue: the RGBench adapter pinned the vertices nearest the starting pose).
TEST(FixedPoint, StreamedCommandsPinTheVertexNearestTheArmAtGrabTimeNotAtTheStart) {
  const sim::Mesh m = cloth();
  auto scene = make_scene(m);
  const Vec3 start(0.12, 0.04, 0.02), grab(0.3, -0.02, 0.012);
  DualArmTrajectory traj;
  traj.left = ArmTrajectory({S(0, start, kGripperOpen)});
  traj.right = ArmTrajectory({S(0, Vec3(0.15, -0.09, 0.011), kGripperOpen)});
  GripperOptions o;
  o.mode = GraspMode::kFixedPoint;
  o.action = TaskKind::kGrasp;
  o.grab_time = 0.3;
  GripperController c(traj, o);
  const double dt = scene->options().dt;
  const int steps = static_cast<int>(std::lround(0.5 / dt));
  for (int k = 1; k <= steps; ++k) {  // the left arm moves from start to grab by 0.3 s, then lifts
    const double t = k * dt, a = std::min(t / 0.3, 1.0);
    const Vec3 p = (1 - a) * start + a * grab + Vec3(0, 0, t > 0.3 ? 0.2 * (t - 0.3) : 0.0);
    c.append(Arm::kLeft, S(t, p, kGripperOpen));
    c.append(Arm::kRight, S(t, Vec3(0.15, -0.09, 0.011), kGripperOpen));
    ASSERT_TRUE(run_until(*scene, c, t));
  }
  const int near_grab = sim::nearest_vertex(m, grab), near_start = sim::nearest_vertex(m, start);
  ASSERT_NE(near_grab, near_start);
  EXPECT_EQ(c.state(Arm::kLeft).held, std::vector<int>{near_grab});
  EXPECT_EQ(c.state(Arm::kRight).held, std::vector<int>{sim::nearest_vertex(m, Vec3(0.15, -0.09, 0.011))});
  EXPECT_GT(scene->positions()[near_grab].z(), 0.03);  // lifted with the arm
}

TEST(FixedPoint, FlingApproachesHoldsThenReplaysShiftedByThePrepareTime) {
  const sim::Mesh m = cloth();
  auto scene = make_scene(m);
  const garments::Garment g = testing::rect_garment(0.3, 0.2, 0.02);
  const int sl = g.landmarks.left_shoulder_vertex, sr = g.landmarks.right_shoulder_vertex;
  const Vec3 q0l(0.1, 0.1, 0.4), q0r(0.1, -0.1, 0.4);
  DualArmTrajectory traj;
  traj.left = ArmTrajectory({S(0, q0l, 0.0), S(0.3, q0l + Vec3(0.2, 0, 0), 0.0)});
  traj.right = ArmTrajectory({S(0, q0r, 0.0), S(0.3, q0r + Vec3(0.2, 0, 0), 0.0)});
  GripperOptions o;
  o.mode = GraspMode::kFixedPoint;
  o.action = TaskKind::kFling;
  o.shoulder_vertices = {sl, sr};
  o.fling_prepare_time = 0.2;
  o.fling_wait_time = 0.2;
  GripperController c(traj, o);
  EXPECT_DOUBLE_EQ(c.sim_prepare_time(), 0.4);
  EXPECT_DOUBLE_EQ(c.end_time(), 0.7);
  // Phase 1: linear from the initial position, alpha = t / prepare.
  ASSERT_TRUE(run_until(*scene, c, 0.1));
  EXPECT_LT((scene->positions()[sl] - (m.x[sl] + 0.5 * (q0l - m.x[sl]))).norm(), 1e-6);
  EXPECT_EQ(c.state(Arm::kLeft).held, std::vector<int>{sl});
  // Phase 2: held at the first pose.
  ASSERT_TRUE(run_until(*scene, c, 0.3));
  EXPECT_LT((scene->positions()[sl] - q0l).norm(), 1e-6);
  EXPECT_LT((scene->positions()[sr] - q0r).norm(), 1e-6);
  // Phase 3: the trajectory at t - 0.4.
  ASSERT_TRUE(run_until(*scene, c, 0.55));
  EXPECT_LT((scene->positions()[sl] - traj.left.sample(0.15).position).norm(), 1e-6);
  EXPECT_LT((scene->positions()[sr] - traj.right.sample(0.15).position).norm(), 1e-6);
}

TEST(GripperOptions, BadValuesAreInputErrors) {
  DualArmTrajectory traj;
  traj.left = parked();
  traj.right = parked();
  GripperOptions o;
  o.jaw_radius = -1;
  EXPECT_THROW(GripperController(traj, o), InputError);
  for (double wide : {0.25, 1e300}) {  // would take the whole garment
    o.jaw_radius = wide;
    EXPECT_THROW(GripperController(traj, o), InputError) << wide;
  }
  o.jaw_radius = kMaxJawRadius;
  EXPECT_NO_THROW(GripperController(traj, o));
  o = GripperOptions();
  o.mode = GraspMode::kFixedPoint;
  o.action = TaskKind::kFling;  // no shoulder vertices
  EXPECT_THROW(GripperController(traj, o), InputError);
  o.shoulder_vertices = {0, 100000};
  GripperController c(traj, o);
  auto scene = make_scene(cloth());
  EXPECT_THROW(c.update(*scene, 0.01), InputError);
  DualArmTrajectory one_arm;
  one_arm.left = parked();
  EXPECT_THROW(GripperController{one_arm}, InputError);
  EXPECT_THROW(task_kind_from_name("wave"), InputError);
  EXPECT_EQ(task_kind_from_name("fling"), TaskKind::kFling);
}

}  // namespace
}  // namespace gd::tasks
