// Robot mode: Piper arms from their URDF hold cloth only by their finger pads' contact and
// friction. A strip hangs from pins; the left gripper closes on it (force-limited), the pins are
// released and the arm lifts: with friction the strip goes up with the hand, without it the
// strip slides out and falls.
#include "tasks/robot_arms.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>

#include "robot/arm_model.h"
#include "robot/urdf_test_util.h"
#include "tasks/task_test_util.h"
#include "sim/demand.h"

namespace gd::tasks {
namespace {

using testing::make_scene;
using testing::piper_urdf;
using testing::two_arms;
using testing::task_options;

constexpr double kGripX = 0.25, kGripY = 0.25, kTipZ = 0.05;  // left hand's fingertips, world

/// The left hand: top down over the strip (moved by `offset`), open, closing at t = 0.1 s,
/// lifting 8 cm from 0.6 s to 1.0 s.
DualArmTrajectory lift_trajectory(const Vec3& offset = Vec3::Zero()) {
  return two_arms(
      {0.0, 0.1, 0.6, 1.0, 1.4},
      [&](double t) -> Vec3 { return Vec3(kGripX, kGripY, kTipZ + (t >= 1.0 ? 0.08 : 0.0)) + offset; },
      [](double t) { return t < 0.1 ? kGripperOpen : 0.0; });
}

struct Lifted {
  double rise = 0;          ///< m: the strip's mean height gain
  double squeeze = 0;       ///< N: the pads' squeeze when the pins let go
  double gripper = 0;       ///< m: finger opening then
  bool failed = false;
  RobotArmState hand;       ///< the left hand when the pins let go
};

/// A 4 x 12 cm cotton strip hanging in the plane x = kGripX, its top row at `top_z` pinned (no
/// table); returns the scene and the pins' group.
std::pair<std::unique_ptr<sim::Scene>, int> hanging_strip(double top_z) {
  sim::Mesh m = sim::make_rect(0.04, 0.12, 0.005);
  for (Vec3& p : m.x) p = Vec3(kGripX, kGripY - 0.02 + p.x(), top_z - p.y());
  sim::SceneOptions o = task_options();
  o.dt = 0.005;
  o.table = false;
  auto scene = make_scene(m, o);
  std::vector<int> top;
  for (int i = 0; i < scene->vertex_count(); ++i)
    if (m.x[i].z() > top_z - 1e-9) top.push_back(i);
  const int pins = scene->pin(top);
  return {std::move(scene), pins};
}

/// A 4 x 12 cm strip hanging in the plane x = kGripX (its top row pinned at z = 0.11), gripped
/// by the left hand, pins released at t = 0.5 s, then lifted.
Lifted lift_strip(double finger_friction, const Vec3& hand_offset = Vec3::Zero()) {
  auto strip = hanging_strip(0.11);
  sim::Scene* scene = strip.first.get();
  const int pins = strip.second;
  RobotOptions ro;
  ro.urdf = piper_urdf();
  ro.finger_friction = finger_friction;
  RobotController c(lift_trajectory(hand_offset), ro);
  double z0 = 0;
  for (const Vec3& p : scene->positions()) z0 += p.z() / scene->vertex_count();
  Lifted out;
  if (!run_until(*scene, c, 0.5)) return {0, 0, 0, true};
  out.squeeze = c.state(Arm::kLeft).squeeze;
  out.gripper = c.state(Arm::kLeft).gripper;
  out.hand = c.state(Arm::kLeft);
  scene->release(pins);
  EXPECT_TRUE(scene->kinematic_vertices().empty());  // nothing pinned: the fingers hold it
  if (!run_until(*scene, c, 1.4)) return {0, 0, 0, true};
  double z1 = 0;
  for (const Vec3& p : scene->positions()) z1 += p.z() / scene->vertex_count();
  out.rise = z1 - z0;
  return out;
}

TEST(RobotArms, FingersHoldAStripByFrictionAndLiftIt) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  // The strip off the fingers' midplane by up to 3 mm, the hand 5 mm higher or lower.
  for (const Vec3& offset : {Vec3(0, 0, 0), Vec3(0.003, 0, 0), Vec3(-0.003, 0, 0.005), Vec3(0, 0.005, -0.005)}) {
    SCOPED_TRACE(::testing::Message() << "hand offset " << offset.transpose());
    const Lifted held = lift_strip(0.8, offset);
    ASSERT_FALSE(held.failed);
    // The fingers stopped on the cloth with the URDF's 10 N, not closed through it.
    EXPECT_NEAR(held.squeeze, 10.0, 1.0);
    EXPECT_GT(held.gripper, 0.0);
    EXPECT_NEAR(held.rise, 0.08, 0.01);  // it went up with the hand
    EXPECT_EQ(held.hand.grip, Grip::kHeld);
    EXPECT_GE(held.hand.held_at, 0.1);
    EXPECT_LT(held.hand.missed_at, 0.0);
    std::printf("offset (%g, %g, %g): squeeze %.2f N at a %.2f mm opening, rise %.1f mm\n", offset.x(), offset.y(),
                offset.z(), held.squeeze, 1e3 * held.gripper, 1e3 * held.rise);
  }
  const Lifted slipped = lift_strip(0.0);
  ASSERT_FALSE(slipped.failed);
  std::printf("without friction: rise %.1f mm\n", 1e3 * slipped.rise);
  EXPECT_LT(slipped.rise, -0.03);  // without friction it slid out and fell
}

TEST(RobotArms, AHandClosingBesideTheStripSaysItMissedIt) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  // The hand beside the strip (its pads clear of the strip's edge) at two distances and heights:
  // the fingers close on nothing, which the hand's state says (a warning is logged), and the
  // strip falls when the pins let go.
  for (const Vec3& offset : {Vec3(0, 0.04, 0), Vec3(0, 0.1, 0.005), Vec3(0.002, -0.045, -0.005)}) {
    SCOPED_TRACE(::testing::Message() << "hand offset " << offset.transpose());
    const Lifted r = lift_strip(0.8, offset);
    ASSERT_FALSE(r.failed);
    std::printf("offset (%g, %g, %g): grip %s, missed at %.3f s, %d vertices on the pads, rise %.1f mm\n", offset.x(),
                offset.y(), offset.z(), grip_name(r.hand.grip), r.hand.missed_at, r.hand.vertices_open, 1e3 * r.rise);
    EXPECT_EQ(r.hand.grip, Grip::kMissed);
    EXPECT_LT(r.hand.held_at, 0.0);
    // Closing from 0.1 s at the fingers' speed, they reach their command before the pins let go.
    EXPECT_GT(r.hand.missed_at, 0.1);
    EXPECT_LT(r.hand.missed_at, 0.5);
    EXPECT_LT(r.rise, -0.03);  // nothing held it
  }
}

/// The left hand over the hanging strip at kTipZ, its samples at `times`, lifted 8 cm from the
/// sample before `lift_end` to `lift_end`, its gripper commanding `gripper(t)` at each sample.
DualArmTrajectory left_hand_with_gripper(const std::vector<double>& times, double lift_end,
                                         const std::function<double(double)>& gripper) {
  return two_arms(
      times, [lift_end](double t) -> Vec3 { return Vec3(kGripX, kGripY, kTipZ + (t >= lift_end ? 0.08 : 0.0)); },
      gripper);
}

/// Robot options with the Piper's URDF and pads of friction 0.8 (the strip holds).
RobotOptions sticky_pads() {
  RobotOptions ro;
  ro.urdf = piper_urdf();
  ro.finger_friction = 0.8;
  return ro;
}

/// The controller's gripper events of one arm, in order.
std::vector<GripperEvent> events_of(const RobotController& c, Arm a) {
  std::vector<GripperEvent> out;
  for (const GripperEvent& e : c.events())
    if (e.arm == a) out.push_back(e);
  return out;
}

TEST(RobotArms, AGripIsAskedBelowHalfTheOpeningTheHandLastStoodOpenAt) {
  constexpr double kMax = 0.035;
  EXPECT_FALSE(RobotController::grip_asked(0.015, 0.015, kMax));  // hovering 3 cm apart: open
  EXPECT_FALSE(RobotController::grip_asked(0.008, 0.015, kMax));
  EXPECT_TRUE(RobotController::grip_asked(0.007, 0.015, kMax));   // below half the pre-grasp opening
  EXPECT_FALSE(RobotController::grip_asked(0.018, 0.035, kMax));   // from fully open: half of it, as before
  EXPECT_TRUE(RobotController::grip_asked(0.017, 0.035, kMax));
  // A hand not yet stood open (a trajectory starting with the fingers shut) is judged against the
  // full opening.
  EXPECT_TRUE(RobotController::grip_asked(0.0, 0.0, kMax));
  EXPECT_TRUE(RobotController::grip_asked(0.017, 0.002, kMax));
  EXPECT_FALSE(RobotController::grip_asked(0.018, 0.002, kMax));
}

TEST(RobotArms, AHandHoveringHalfOpenIsOpenAndGripsWhenItCloses) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  // The left hand round the hanging strip with its fingers 2.4 cm or 1.6 cm apart (below half
  // their full 7 cm) until 0.1 s, closing to 0 by 0.2 s, lifting 8 cm from 0.6 s to 1.0 s. While
  // it hovers it is open (no grasp event, nothing missed); the grasp is the command crossing half
  // the hovering opening, and the hand holds the strip.
  for (const double g0 : {0.012, 0.008}) {
    SCOPED_TRACE(::testing::Message() << "pre-grasp opening " << g0);
    auto strip = hanging_strip(0.11);
    sim::Scene* scene = strip.first.get();
    RobotController c(left_hand_with_gripper({0.0, 0.1, 0.2, 0.6, 1.0, 1.4}, 1.0,
                                             [g0](double t) { return t < 0.15 ? g0 : 0.0; }),
                      sticky_pads());
    const auto left_events = [&] { return events_of(c, Arm::kLeft); };
    ASSERT_TRUE(run_until(*scene, c, 0.09));
    EXPECT_EQ(c.state(Arm::kLeft).grip, Grip::kOpen);
    EXPECT_TRUE(left_events().empty());
    EXPECT_NEAR(c.state(Arm::kLeft).gripper, g0, 1e-9);  // the fingers stand at their command
    ASSERT_TRUE(run_until(*scene, c, 0.5));
    const std::vector<GripperEvent> ev = left_events();
    ASSERT_EQ(ev.size(), 1u);
    EXPECT_TRUE(ev[0].grasp);
    // The command ramps from g0 at 0.1 s to 0 at 0.2 s: half of g0 at 0.15 s.
    EXPECT_NEAR(ev[0].t, 0.15, 0.011);
    scene->release(strip.second);
    ASSERT_TRUE(run_until(*scene, c, 1.4));
    const RobotArmState& st = c.state(Arm::kLeft);
    std::printf("pre-grasp opening %.1f mm: grasp at %.3f s, held at %.3f s, grip %s, squeeze %.2f N\n", 1e3 * g0,
                ev[0].t, st.held_at, grip_name(st.grip), st.squeeze);
    EXPECT_EQ(st.grip, Grip::kHeld);
    EXPECT_GE(st.held_at, ev[0].t);
    EXPECT_LT(st.missed_at, 0.0);
    EXPECT_EQ(left_events().size(), 1u);  // no release
  }
}

TEST(RobotArms, AHandPreShapedFromFullyOpenStandsOpenThenGrips) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  // The left hand round the hanging strip, fully open, pre-shaped to 3 cm apart (1.5 cm each) from
  // 0.1 s to 0.2 s, then closing to 0 from 0.5 s to 0.6 s; the pins let go at 0.9 s and the hand
  // lifts 8 cm from 1.3 s to 1.7 s. The pre-shape crosses half the full opening (a grip asked),
  // but once the fingers rest at 15 mm with nothing between the pads the hand stands open there,
  // not "missed"; the grasp is the command crossing half of 15 mm, and the hand holds the strip.
  auto strip = hanging_strip(0.11);
  sim::Scene* scene = strip.first.get();
  RobotController c(left_hand_with_gripper({0.0, 0.1, 0.2, 0.5, 0.6, 0.9, 1.3, 1.7}, 1.7,
                                           [](double t) { return t < 0.15 ? kGripperOpen : t < 0.55 ? 0.015 : 0.0; }),
                    sticky_pads());
  const auto left_events = [&] { return events_of(c, Arm::kLeft); };
  ASSERT_TRUE(run_until(*scene, c, 0.45));
  EXPECT_EQ(c.state(Arm::kLeft).grip, Grip::kOpen);
  EXPECT_NEAR(c.state(Arm::kLeft).gripper, 0.015, 1e-9);
  EXPECT_LT(c.state(Arm::kLeft).missed_at, 0.0);  // not a grasp that closed on nothing
  const std::vector<GripperEvent> before = left_events();
  ASSERT_EQ(before.size(), 2u);  // the pre-shape's motion, then standing open at 15 mm
  EXPECT_TRUE(before[0].grasp);
  EXPECT_FALSE(before[1].grasp);
  EXPECT_LT(before[1].t, 0.45);
  ASSERT_TRUE(run_until(*scene, c, 0.9));
  const std::vector<GripperEvent> ev = left_events();
  ASSERT_EQ(ev.size(), 3u);
  EXPECT_TRUE(ev[2].grasp);
  EXPECT_NEAR(ev[2].t, 0.55, 0.011);  // the command ramps from 15 mm at 0.5 s to 0 at 0.6 s
  scene->release(strip.second);
  ASSERT_TRUE(run_until(*scene, c, 1.7));
  const RobotArmState& st = c.state(Arm::kLeft);
  std::printf("pre-shaped: events at %.3f, %.3f (standing open), %.3f s; held at %.3f s, grip %s, squeeze %.2f N\n",
              ev[0].t, ev[1].t, ev[2].t, st.held_at, grip_name(st.grip), st.squeeze);
  EXPECT_EQ(st.grip, Grip::kHeld);
  EXPECT_GE(st.held_at, ev[2].t);
  EXPECT_LT(st.missed_at, 0.0);
}

TEST(RobotArms, AHandClosingOnTheStripsLowEdgeSaysItClosedOnLittleCloth) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  // The hand 9.6-9.8 cm lower: only the strip's bottom edge lies between the pads' tips. The
  // fingers stop a quarter contact distance apart on it (cloth between them) with a squeeze the
  // barrier caps below half the limit (what counts as a hold): the grasp closed on little cloth.
  for (const Vec3& offset : {Vec3(0, 0, -0.096), Vec3(0, 0, -0.098), Vec3(0.002, 0.003, -0.097)}) {
    SCOPED_TRACE(::testing::Message() << "hand offset " << offset.transpose());
    const Lifted r = lift_strip(0.8, offset);
    ASSERT_FALSE(r.failed);
    std::printf("offset (%g, %g, %g): grip %s, missed at %.3f s, %d vertices on the pads, squeeze %.2f N at a %.3f "
                "mm opening\n", offset.x(), offset.y(), offset.z(), grip_name(r.hand.grip), r.hand.missed_at,
                r.hand.vertices_open, r.squeeze, 1e3 * r.gripper);
    EXPECT_EQ(r.hand.grip, Grip::kMissed);
    EXPECT_LT(r.hand.held_at, 0.0);
    EXPECT_GT(r.hand.missed_at, 0.1);
    EXPECT_LT(r.hand.missed_at, 0.5);
    EXPECT_GT(r.hand.vertices_open, 0);  // cloth between the pads, not nothing
    EXPECT_GT(r.gripper, 0.0);           // and the fingers stopped on it
    EXPECT_LT(r.squeeze, 5.0);
  }
}

/// A strip like lift_strip's, its top 5 mm above the pads, held by the left hand (closed at 0.1 s,
/// the pins let go at 0.8 s) without lifting while the squeeze limit falls from 10 N at 0.6 s to
/// 0.1 N at 0.8 s and to 1 mN at 4.8 s.
struct LetGo {
  RobotArmState hand;       ///< at the end (held_at, lost_at, force_at_loss)
  double weight = 0;        ///< N
  double slip_limit = -1;   ///< N: the limit when the strip had slid 1 mm down between the pads
};
LetGo let_go_strip(double finger_friction) {
  // Its top 5 mm above the pads (4 cm long): none of it to fold over them.
  auto strip = hanging_strip(kTipZ + 0.045);
  sim::Scene* scene = strip.first.get();
  const int pins = strip.second;
  RobotOptions ro;
  ro.urdf = piper_urdf();
  ro.finger_friction = finger_friction;
  ro.grip_force_schedule = {{0.6, 10.0}, {0.8, 0.1}, {4.8, 0.001}};
  const DualArmTrajectory traj = two_arms(
      {0.0, 0.1, 5.2}, [](double) -> Vec3 { return Vec3(kGripX, kGripY, kTipZ); },
      [](double t) { return t < 0.1 ? kGripperOpen : 0.0; });
  RobotController c(traj, ro);
  EXPECT_NEAR(c.grip_force_at(0.7), 5.05, 1e-12);  // the limit is the schedule's, linear between knots
  EXPECT_DOUBLE_EQ(c.grip_force_at(5.0), 0.001);
  auto mean_z = [&] {
    double z = 0;
    for (const Vec3& p : scene->positions()) z += p.z() / scene->vertex_count();
    return z;
  };
  if (!run_until(*scene, c, 0.8)) return {};  // closed at 0.1 s; at 0.8 s the pins let go at a 0.1 N limit
  scene->release(pins);
  LetGo out;
  const double z0 = mean_z();
  if (!run_until(*scene, c, 5.2, [&](const sim::StepStats&) {
        if (out.slip_limit < 0 && mean_z() < z0 - 0.001) out.slip_limit = c.state(Arm::kLeft).grip_force;
      }))
    return {};
  out.hand = c.state(Arm::kLeft);
  out.weight = scene->material().density * 0.04 * 0.12 * sim::kGravity;
  return out;
}

// The force a pinch needs: with the squeeze limit falling slowly, a flat strip held by two pads
// starts to slide once 2 mu F (F: each pad's push) falls below its weight W, so at a limit that
// scales as 1/mu: asserted within a factor 2 of W / (2 mu). The hand lets go (the strip has left
// the pads) at a lower limit still.
TEST(RobotArms, AFallingGripLimitLetsTheStripGoWhereFrictionNoLongerCarriesIt) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  double slip[2] = {0, 0};
  const double mus[2] = {0.2, 0.8};
  for (int k = 0; k < 2; ++k) {
    const LetGo r = let_go_strip(mus[k]);
    ASSERT_GT(r.weight, 0) << "the run failed";
    const double coulomb = r.weight / (2 * mus[k]);
    std::printf("mu %.1f: held from %.3f s; slid 1 mm at a limit of %.4f N (W / 2 mu = %.4f N); let go at %.3f s at "
                "%.4f N\n", mus[k], r.hand.held_at, r.slip_limit, coulomb, r.hand.lost_at, r.hand.force_at_loss);
    EXPECT_GE(r.hand.held_at, 0.0);  // it held at 10 N
    ASSERT_GT(r.slip_limit, 0.0);    // and slid once the limit fell
    EXPECT_GT(r.slip_limit, coulomb / 2);
    EXPECT_LT(r.slip_limit, 2 * coulomb);
    EXPECT_GT(r.hand.lost_at, 0.8);  // then left the pads
    EXPECT_LE(r.hand.force_at_loss, r.slip_limit);
    slip[k] = r.slip_limit;
  }
  EXPECT_GT(slip[0], 2 * slip[1]);  // four times the friction: a quarter of the force, within a factor 2
}

// The schedule is checked: finite knots, forces >= 0, times increasing, not all 0 N.
TEST(RobotArms, AGripForceScheduleWithBadKnotsIsRefusedNamingTheKnot) {
  RobotOptions ro;
  ro.urdf = "arms.urdf";
  ro.grip_force_schedule = {{1.0, 10.0}, {1.0, 5.0}};
  EXPECT_THROW(ro.validate(), sim::InputError);
  ro.grip_force_schedule = {{1.0, 10.0}, {2.0, -1.0}};
  try {
    ro.validate();
    ADD_FAILURE() << "a negative force was taken";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("knot 1"), std::string::npos) << e.what();
  }
  ro.grip_force_schedule = {{1.0, 0.0}, {2.0, 0.0}};
  EXPECT_THROW(ro.validate(), sim::InputError);
  ro.grip_force_schedule = {{1.0, NAN}};
  EXPECT_THROW(ro.validate(), sim::InputError);
  ro.grip_force_schedule = {{1.0, 10.0}, {2.0, 0.0}};
  EXPECT_NO_THROW(ro.validate());
}

/// A 12 x 12 cm cloth lying on the table; the left hand comes down on it (aimed at the table
/// top: the hand stops just above it), closes, and lifts 5 cm. Returns the cloth's highest point
/// after the lift and the squeeze.
std::pair<double, double> pick_from_table(double finger_friction, const Vec3& offset) {
  sim::Mesh m = sim::make_rect(0.12, 0.12, 0.005);
  for (Vec3& p : m.x) p = Vec3(0.19 + p.x(), 0.19 + p.y(), 0.001);
  sim::SceneOptions o = task_options();
  o.dt = 0.005;
  auto scene = make_scene(m, o);
  scene->step(20);  // settle on the table
  const DualArmTrajectory traj = two_arms(
      {0.0, 0.3, 0.5, 1.2, 1.7}, [&](double t) -> Vec3 { return Vec3(0.25, 0.25, t >= 0.3 && t < 1.5 ? 0.0 : 0.05) + offset; },
      [](double t) { return t < 0.5 ? kGripperOpen : 0.0; });
  RobotOptions ro;
  ro.urdf = piper_urdf();
  ro.finger_friction = finger_friction;
  RobotController c(traj, ro);
  double lifted = 0;
  if (!run_until(*scene, c, 1.9, [&](const sim::StepStats&) { lifted = std::max(lifted, c.state(Arm::kLeft).table_lift); }))
    return {NAN, NAN};
  EXPECT_GT(lifted, 0.0);  // the hand was held off the table
  EXPECT_TRUE(scene->kinematic_vertices().empty());
  return {testing::max_z(scene->positions()), c.state(Arm::kLeft).squeeze};
}

// Closing pads catch lying cloth with their lower edges, bunch it up between them and hold it:
// the cloth goes up with the hand (the pads' tips end 5 cm above the table). Grasp point moved
// by up to 5 mm; without friction the cloth stays down.
TEST(RobotArms, FingersPickClothOffTheTable) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  for (const Vec3& offset : {Vec3(0, 0, 0), Vec3(0.005, 0, 0), Vec3(-0.003, -0.005, 0)}) {
    SCOPED_TRACE(::testing::Message() << "hand offset " << offset.transpose());
    const auto [top, squeeze] = pick_from_table(0.8, offset);
    std::printf("offset (%g, %g, %g): cloth top %.1f mm, squeeze %.2f N\n", offset.x(), offset.y(), offset.z(),
                1e3 * top, squeeze);
    EXPECT_GT(top, 0.04);  // held: the pads' tips end 5 cm up; lying cloth is at 0.5 mm
    EXPECT_NEAR(squeeze, 10.0, 2.0);
  }
  const auto [top, squeeze] = pick_from_table(0.0, Vec3::Zero());
  std::printf("without friction: cloth top %.1f mm, squeeze %.2f N\n", 1e3 * top, squeeze);
  EXPECT_LT(top, 0.03);
}

/// A 4 x 6 cm strip standing 4 mm outside the +x finger pad's outer face (the fingers closed),
/// pinned along its top and bottom rows; the fingers then open towards it with a grip force of
/// `grip` N. Returns the largest push against the opening (the mean of the two pads' pushes along
/// their opening directions, negated) after the pad reached the strip, and the final opening.
std::pair<double, double> open_against_strip(double grip) {
  sim::Mesh m = sim::make_rect(0.04, 0.06, 0.004);
  for (Vec3& p : m.x) p = Vec3(kGripX + 0.012, kGripY - 0.02 + p.x(), kTipZ - 0.01 + p.y());
  sim::SceneOptions o = task_options();
  o.dt = 0.005;
  o.table = false;
  auto scene = make_scene(m, o);
  std::vector<int> rows;
  for (int i = 0; i < scene->vertex_count(); ++i)
    if (std::abs(m.x[i].z() - (kTipZ - 0.01)) < 1e-9 || std::abs(m.x[i].z() - (kTipZ + 0.05)) < 1e-9) rows.push_back(i);
  scene->pin(rows);
  const DualArmTrajectory traj = two_arms(
      {0.0, 0.1, 1.0}, [](double) { return Vec3(kGripX, kGripY, kTipZ); }, [](double t) { return t < 0.1 ? 0.0 : kGripperOpen; });
  RobotOptions ro;
  ro.urdf = piper_urdf();
  ro.grip_force = grip;
  RobotController c(traj, ro);
  double resist = 0;
  if (!run_until(*scene, c, 1.0, [&](const sim::StepStats&) { resist = std::max(resist, -c.state(Arm::kLeft).squeeze); }))
    return {NAN, NAN};
  return {resist, c.state(Arm::kLeft).gripper};
}

// The finger joint's force limit holds while opening too: fingers opening against cloth that
// presses their outer faces (a towel folded round them, cloth beside them on the table) stop at
// the grip force instead of pressing the cloth with hundreds of newtons (docs/robot.md, "Opening
// against the cloth"). Here the strip pinned beyond the +x pad takes more than the limit to push
// aside by the full opening, so the fingers stop short.
TEST(RobotArms, FingersOpeningAgainstClothStopAtTheGripForce) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  for (const double grip : {1.0, 2.0}) {
    SCOPED_TRACE(::testing::Message() << "grip force " << grip << " N");
    const auto [resist, opening] = open_against_strip(grip);
    std::printf("grip %.1f N: largest push against the opening %.2f N, final opening %.1f mm\n", grip, resist,
                1e3 * opening);
    ASSERT_TRUE(std::isfinite(resist));
    EXPECT_GT(resist, 0.5 * grip) << "the pad never pressed the strip: the test does not reach the limit";
    EXPECT_LT(resist, 1.5 * grip);
    EXPECT_LT(opening, kGripperOpen - 0.005) << "the fingers opened fully through the limit";
  }
}

TEST(RobotArms, GeneratedPosesBecomeJointsWithinReachAndUnreachableOnesAreRefused) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  RobotOptions ro;
  ro.urdf = piper_urdf();
  RobotController c(lift_trajectory(), ro);
  EXPECT_EQ(c.ik_solved(), 10);
  for (Arm a : {Arm::kLeft, Arm::kRight})
    for (const ArmSample& s : c.trajectory().arm(a).samples()) {
      ASSERT_EQ(s.joints.size(), 6u);
      // The fingertips' midpoint (the end effector with the fingers closed) is where the pose asked.
      Eigen::Isometry3d base = Eigen::Isometry3d::Identity();
      base.translation() = base_offset(a);
      const Eigen::Isometry3d ee =
          base * c.arm_model().ee_pose(Eigen::Map<const Eigen::VectorXd>(s.joints.data(), 6));
      EXPECT_LT((ee.translation() - s.position).norm(), 1e-3);
      // Pointing down (the approach axis, link7 y, along world -z) within the tilt it reports.
      EXPECT_GT(-ee.linear().col(1).z(), std::cos(c.ik_max_tilt()) - 1e-6);
    }
  // Each sample's answer is seeded by the previous one: the joints move continuously (no jump to
  // another branch of the inverse kinematics) as the hand goes down to a T-shirt's shoulder and
  // up 45 cm, tilting as it must, in samples 2-5 cm apart.
  std::vector<double> times;
  for (int k = 0; k <= 14; ++k) times.push_back(0.1 * k);
  auto height = [](double t) { return t <= 0.4 ? 0.08 - 0.2 * t : 0.45 * (t - 0.4); };
  const DualArmTrajectory path = two_arms(
      times, [&](double t) -> Vec3 { return Vec3(0.163, 0.178, height(t)); }, [](double) { return kGripperOpen; });
  RobotController along(path, ro);
  double largest = 0;
  const auto& js = along.trajectory().left.samples();
  for (size_t k = 1; k < js.size(); ++k)
    for (size_t j = 0; j < 6; ++j) largest = std::max(largest, std::abs(js[k].joints[j] - js[k - 1].joints[j]));
  EXPECT_LT(largest, 0.5);
  DualArmTrajectory far = lift_trajectory();
  std::vector<ArmSample> s = far.left.samples();
  s[2].position = Vec3(1.5, 0.25, 0.3);
  far.left = ArmTrajectory(s, "left");
  try {
    RobotController bad(far, ro);
    ADD_FAILURE() << "an unreachable pose was accepted";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("left arm cannot reach its pose at t=0.600"), std::string::npos) << e.what();
  }
  // Exactly top down where the Piper's wrist allows it: low, in front of its base.
  EXPECT_LT(c.ik_max_tilt(), 1.0);
  RobotOptions none;
  EXPECT_THROW(RobotController(lift_trajectory(), none), sim::InputError);  // no URDF given
}

// A left hand reaching across its base (a small towel's corner, 14 cm to its right) squares its
// fingers with the garment's edge only turned half a turn: as the trajectory asks, the wrist
// (joint6, down to -120 degrees) would stop 3.7 degrees short and tilt the hand. The arm's first
// pose takes the half turn, exactly top down, and keeps it along the whole path; the right hand,
// in front of its own base, reaches as asked.
TEST(RobotArms, AHandTurnsHalfATurnWhereItsWristCannotReachTheOrientationAsked) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  RobotOptions ro;
  ro.urdf = piper_urdf();
  DualArmTrajectory path;
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    std::vector<ArmSample> samples;
    for (const double t : {0.0, 0.5, 1.0}) {
      ArmSample s;
      s.t = t;
      s.orientation = top_down_orientation();
      s.gripper = kGripperOpen;
      s.position = Vec3(0.19, a == Arm::kLeft ? 0.11 : -0.11, t < 0.5 ? 0.08 : -0.0045);
      samples.push_back(s);
    }
    path.arm(a) = ArmTrajectory(samples, arm_name(a));
  }
  RobotController c(path, ro);
  EXPECT_TRUE(c.hand_half_turned(Arm::kLeft));
  EXPECT_FALSE(c.hand_half_turned(Arm::kRight));
  EXPECT_LT(c.ik_max_tilt(), 1e-3) << "the hands point straight down";
  const auto& js = c.trajectory().left.samples();
  for (size_t k = 1; k < js.size(); ++k) EXPECT_LT(std::abs(js[k].joints[5] - js[k - 1].joints[5]), 0.2) << k;
  // The fingers close along the same line either way round: the pads' centres lie on the world x
  // axis through the hand, 2 x 3.5 cm apart when open.
  const auto pads = c.finger_poses(Arm::kLeft, js.back().joints, kGripperOpen);
  const Vec3 across = pads[0].translation() - pads[1].translation();
  EXPECT_NEAR(std::abs(across.x()), 0.07, 2e-3);
  EXPECT_LT(std::hypot(across.y(), across.z()), 2e-3);
}

// Given joints and the URDF's limits: recorded ones (a real arm's) are clamped and counted, a
// command beyond them (the service's) is refused naming the joint; within the slack both are
// clamped quietly.
TEST(RobotArms, JointsOutsideTheUrdfLimitsAreClampedWhenRecordedAndRefusedWhenCommanded) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  RobotOptions ro;
  ro.urdf = piper_urdf();
  const RobotController solved(lift_trajectory(), ro);
  const robot::ArmModel& m = solved.arm_model();
  const std::vector<robot::JointLimits>& lim = m.arm_limits();
  DualArmTrajectory rec = solved.trajectory();  // every sample with joints, as a recording
  std::vector<ArmSample> s = rec.left.samples();
  s[1].joints[2] = lim[2].upper + 0.2;                                   // far out: clamped, counted
  s[3].joints[0] = lim[0].lower - 0.5 * RobotController::kJointLimitSlack;  // within the slack: clamped only
  rec.left = ArmTrajectory(s, "left");
  const RobotController c(rec, ro);
  EXPECT_EQ(c.ik_solved(), 0);
  EXPECT_EQ(c.joints_clamped(), 1);
  EXPECT_NEAR(c.joint_clamp_max(), 0.2, 1e-12);
  EXPECT_DOUBLE_EQ(c.trajectory().left.samples()[1].joints[2], lim[2].upper);
  EXPECT_DOUBLE_EQ(c.trajectory().left.samples()[3].joints[0], lim[0].lower);
  // A command: beyond the slack refused, naming the joint, its value and the limits.
  ArmSample cmd = s[1];
  try {
    c.resolve(Arm::kLeft, cmd, s[0].joints);
    ADD_FAILURE() << "a joint beyond its limit was accepted";
  } catch (const sim::InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(m.arm_joint_names()[2]), std::string::npos) << what;
    EXPECT_NE(what.find("outside the URDF's limits"), std::string::npos) << what;
  }
  cmd.joints = s[3].joints;
  EXPECT_DOUBLE_EQ(c.resolve(Arm::kLeft, cmd, s[0].joints).joints[0], lim[0].lower);
}

// --- The arm's links ---------------------------------------------------------------------------

namespace links {

/// The test arm (robot/urdf_test_util.h) whose first link carries `geometry` centred 15 cm along
/// it: with the joints at 0, a horizontal beam along world x at the arm's base y, 10 cm above the
/// table.
std::string beam_urdf(const std::string& geometry) {
  return robot::testing::two_joint_arm_urdf(R"(
  <link name="base_link"/>
  <link name="l1"><collision><origin xyz="0.15 0 0" rpy="0 0 0"/><geometry>)" + geometry + R"(</geometry></collision></link>
  <link name="l2"/><link name="hand"/><link name="fa"/><link name="fb"/>)");
}

struct Landing {
  double max_z = 0;         ///< m: the cloth's highest point after it has fallen
  double inside_beam = 0;   ///< vertices strictly inside the beam's box
  int intersecting = 0;     ///< most intersecting triangle pairs after any step
  int link_colliders = 0;
};

/// A 10 x 10 cm cotton square dropped from 20 cm onto the left arm's beam (4 cm tall, its top at
/// 12 cm), the arms still, for 0.6 s.
Landing drop_on_beam(const std::string& geometry, const std::vector<std::string>& package_paths, bool link_colliders,
                     const Vec3& shift = Vec3::Zero()) {
  sim::Mesh m = sim::make_rect(0.1, 0.1, 0.01);
  for (Vec3& p : m.x) p = Vec3(0.15 + p.x() - 0.05, base_offset(Arm::kLeft).y() + p.y() - 0.05, 0.2) + shift;
  sim::SceneOptions o = task_options();
  o.dt = 0.005;
  o.self_contact = true;
  auto scene = make_scene(m, o);
  RobotOptions ro;
  ro.urdf = "beam.urdf";
  ro.arm.ee_link = "hand";
  ro.arm.finger_joints = {"fj1", "fj2"};
  ro.arm.package_paths = package_paths;
  ro.link_colliders = link_colliders;
  auto model = std::make_shared<const robot::ArmModel>(robot::ArmModel::from_string(beam_urdf(geometry), "beam", ro.arm));
  std::vector<ArmSample> still;
  for (const double t : {0.0, 1.0}) {
    ArmSample s;
    s.t = t;
    s.joints = {0.0, 0.0};
    s.gripper = 0.02;
    still.push_back(s);
  }
  DualArmTrajectory traj;
  traj.left = ArmTrajectory(still, "left");
  traj.right = ArmTrajectory(still, "right");
  RobotController c(traj, ro, model);
  Landing out;
  EXPECT_TRUE(run_until(*scene, c, 0.6, [&](const sim::StepStats& st) {
    out.intersecting = std::max(out.intersecting, st.intersecting_pairs);
  }));
  out.link_colliders = static_cast<int>(c.state(Arm::kLeft).link_colliders.size() + c.state(Arm::kRight).link_colliders.size());
  const auto x = scene->positions();
  out.max_z = testing::max_z(x);
  for (const Vec3& p : x) {  // the beam: x 0..0.3, y 0.22..0.28, z 0.08..0.12
    const Vec3 q = p - Vec3(0.15, base_offset(Arm::kLeft).y(), 0.1);
    if (std::abs(q.x()) < 0.15 && std::abs(q.y()) < 0.03 && std::abs(q.z()) < 0.02) out.inside_beam += 1;
  }
  return out;
}

}  // namespace links

TEST(RobotArms, ClothFallingOnAnArmsLinkRestsOnItAsABoxOrAsAnStlMesh) {
  namespace fs = std::filesystem;
  const fs::path d = fs::temp_directory_path() / ("gd_beam_" + std::to_string(::getpid()));
  fs::create_directories(d / "beam_description");
  robot::testing::write_box_stl(d / "beam_description" / "beam.stl", Vec3(0.15, 0.03, 0.02));
  const std::string box = R"(<box size="0.3 0.06 0.04"/>)";
  const std::string mesh = R"(<mesh filename="package://beam_description/beam.stl"/>)";
  // The square centred over the beam, and 1 cm off along and across it.
  for (const Vec3& shift : {Vec3(0, 0, 0), Vec3(0.01, -0.01, 0)}) {
    std::vector<double> heights;
    for (const std::string& geometry : {box, mesh}) {
      SCOPED_TRACE(::testing::Message() << geometry << " shift " << shift.transpose());
      const links::Landing l = links::drop_on_beam(geometry, {d.string()}, true, shift);
      EXPECT_EQ(l.link_colliders, 2);  // one beam per arm
      // Draped over the beam: the middle rests on its top (12 cm, within the contact distance),
      // the sides hang; nothing went into the beam or through itself.
      EXPECT_GT(l.max_z, 0.12);
      EXPECT_LT(l.max_z, 0.125);
      EXPECT_EQ(l.inside_beam, 0);
      EXPECT_EQ(l.intersecting, 0);
      std::printf("%s shift (%g, %g): highest point %.2f mm\n", geometry.c_str(), shift.x(), shift.y(), 1e3 * l.max_z);
      heights.push_back(l.max_z);
    }
    // The STL box's hull collides as the box does (its CCD bound the convex one too).
    EXPECT_NEAR(heights[1], heights[0], 1e-4);
  }
  // Without the links (or without the mesh on the package path) the square falls to the table.
  const links::Landing pads_only = links::drop_on_beam(box, {d.string()}, false);
  EXPECT_EQ(pads_only.link_colliders, 0);
  EXPECT_LT(pads_only.max_z, 0.01);
  const links::Landing no_mesh = links::drop_on_beam(mesh, {}, true);
  EXPECT_EQ(no_mesh.link_colliders, 0);
  EXPECT_LT(no_mesh.max_z, 0.01);
  fs::remove_all(d);
}

}  // namespace
}  // namespace gd::tasks
