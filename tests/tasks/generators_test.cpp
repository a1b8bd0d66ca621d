// Grasp / Fling / Fold generators: the shape of the trajectories, bad input, and the physical
// outcome of replaying them in pseudo-grasp mode on a small garment (no self-contact).
#include "tasks/generators.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numbers>

#include "sim/demand.h"
#include "tasks/grippers.h"
#include "tasks/task_test_util.h"

namespace gd::tasks {
namespace {

using sim::InputError;
using testing::extent;
using testing::max_z;
using testing::min_z;

garments::Garment small_garment() { return testing::rect_garment(0.4, 0.3, 0.025); }

/// Largest speed between consecutive samples, m/s.
double max_speed(const ArmTrajectory& t) {
  double v = 0;
  const auto& s = t.samples();
  for (size_t k = 1; k < s.size(); ++k) v = std::max(v, (s[k].position - s[k - 1].position).norm() / (s[k].t - s[k - 1].t));
  return v;
}

/// First time at which the gripper is closed (< 1 cm), or -1.
double first_closed(const ArmTrajectory& t) {
  for (const auto& s : t.samples())
    if (s.gripper < 0.01) return s.t;
  return -1;
}

// --- trajectory shapes -----------------------------------------------------------------------

TEST(Generators, GraspDescendsOntoTheShouldersClosesAndLiftsVertically) {
  const garments::Garment g = small_garment();
  const Eigen::Isometry3d T = default_garment_pose();
  const DualArmTrajectory t = make_grasp(g, T);
  EXPECT_EQ(t.master_start_time, 0.0);
  EXPECT_GE(t.end_time(), 8.0);  // like RGBench's captures
  EXPECT_LE(t.end_time(), 20.0);
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    const ArmTrajectory& arm = t.arm(a);
    const Vec3 shoulder = T * (a == Arm::kLeft ? g.landmarks.left_shoulder : g.landmarks.right_shoulder);
    const ArmSample first = arm.samples().front(), last = arm.samples().back();
    EXPECT_DOUBLE_EQ(first.gripper, kGripperOpen);
    EXPECT_LT((first.position - (shoulder + Vec3(0, 0, 0.08))).norm(), 1e-12);
    const double tc = first_closed(arm);
    ASSERT_GT(tc, 0);
    EXPECT_LT((arm.sample(tc).position - shoulder).norm(), 1e-9);  // closes on the shoulder
    EXPECT_DOUBLE_EQ(last.gripper, 0.0);
    EXPECT_LT((last.position - (shoulder + Vec3(0, 0, g.length + 0.1))).norm(), 1e-12);
    EXPECT_NEAR(last.orientation.angularDistance(top_down_orientation()), 0, 1e-12);
    EXPECT_LT(max_speed(arm), 0.3);  // smooth, no teleports
    for (const auto& s : arm.samples()) EXPECT_NEAR(s.position.y(), shoulder.y(), 1e-12);
  }
}

TEST(Generators, FlingSweepsForwardAndBackAtTheRequestedSpeedAndEndsSpread) {
  const garments::Garment g = small_garment();
  TaskParams p;
  p.fling_spread = 0.35;
  const DualArmTrajectory t = make_fling(g, default_garment_pose(), p);
  const Vec3 l0 = default_garment_pose() * g.landmarks.left_shoulder;
  double max_x = -1;
  for (const auto& s : t.left.samples()) max_x = std::max(max_x, s.position.x());
  EXPECT_NEAR(max_x, l0.x() + 0.25, 1e-9);
  EXPECT_NEAR(max_speed(t.left), 1.0, 0.05);
  const Vec3 el = t.left.samples().back().position, er = t.right.samples().back().position;
  EXPECT_NEAR(el.y() - er.y(), 0.35, 1e-9);
  EXPECT_NEAR(el.x(), l0.x(), 1e-9);
  EXPECT_NEAR(el.z(), l0.z() + g.length + 0.15, 1e-9);
  EXPECT_DOUBLE_EQ(t.left.samples().back().gripper, 0.0);
}

TEST(Generators, FoldCarriesTheShouldersToTheHemAndLetsGo) {
  const garments::Garment g = small_garment();
  const Eigen::Isometry3d T = default_garment_pose();
  TaskParams straight;
  straight.fold_arc = 0;  // the paper's level translation
  for (const TaskParams& p : {TaskParams(), straight}) {
  const DualArmTrajectory t = make_fold(g, T, p);
  const bool page = p.fold_arc != 0;
  const double radius = 0.5 * (g.length - 0.03);  // half the way from the shoulders to the hem - margin
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    const ArmTrajectory& arm = t.arm(a);
    const Vec3 shoulder = T * (a == Arm::kLeft ? g.landmarks.left_shoulder : g.landmarks.right_shoulder);
    const Vec3 fold_axis = shoulder + radius * Vec3::UnitX();  // garment +x is world +x here
    double max_z_closed = 0, open_again = -1, max_axis_error = 0;
    const double tc = first_closed(arm);
    for (const auto& s : arm.samples()) {
      if (s.t > tc && s.gripper < 0.01) {
        max_z_closed = std::max(max_z_closed, s.position.z() - shoulder.z());
        // Past the lift, a page turn keeps the gripper at the fold's radius from the fold axis.
        if (s.position.z() - shoulder.z() > 0.06 + 1e-9 || s.position.x() > shoulder.x() + 1e-9) {
          const Vec3 r = s.position - fold_axis;
          max_axis_error = std::max(max_axis_error, std::abs(std::hypot(r.x(), r.z()) - radius));
        }
      }
      if (s.t > tc && s.gripper >= 0.01 && open_again < 0) open_again = s.t;
    }
    if (page) {
      EXPECT_NEAR(max_z_closed, radius, 0.005);  // over the top of the half circle
      EXPECT_LT(max_axis_error, 0.03);           // on the circle to within half the lift height
    } else {
      EXPECT_NEAR(max_z_closed, 0.06, 1e-9);  // the level translation at the lift height
    }
    ASSERT_GT(open_again, 0);
    const Vec3 at_release = arm.sample(open_again).position;
    EXPECT_NEAR(at_release.x(), shoulder.x() + g.length - 0.03, 1e-9);
    EXPECT_NEAR(at_release.z(), shoulder.z() + 0.01, 1e-9);
    EXPECT_DOUBLE_EQ(arm.samples().back().gripper, kGripperOpen);
    EXPECT_GT(arm.samples().back().position.z(), at_release.z() + 0.05);  // retreated
    EXPECT_LT(max_speed(arm), 0.4);
  }
  }
}

/// Gripper closings and openings of one arm: (time, position) at each change.
std::vector<std::pair<bool, Vec3>> gripper_changes(const ArmTrajectory& arm) {
  std::vector<std::pair<bool, Vec3>> out;
  bool closed = false;
  for (const auto& s : arm.samples())
    if ((s.gripper < 0.01) != closed) {
      closed = !closed;
      out.emplace_back(closed, s.position);
    }
  return out;
}

TEST(Generators, FoldLaysAHoodOverOntoTheBodyThenBringsTheHemUpToTheShoulders) {
  // The small garment with a hood: its face corners at x = 0, the neck line at x = 0.12, the
  // shoulders beyond it, the hem at its far end.
  garments::Garment g = small_garment();
  auto& lm = g.landmarks;
  lm.has_hood = true;
  lm.left_hood = Vec3(0, 0.08, lm.left_shoulder.z());
  lm.right_hood = Vec3(0, -0.08, lm.left_shoulder.z());
  lm.hood_fold_x = 0.12;
  lm.left_shoulder.x() = lm.right_shoulder.x() = 0.14;
  const Eigen::Isometry3d T = default_garment_pose();
  const DualArmTrajectory t = make_fold(g, T);
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    const Vec3 hood = T * (a == Arm::kLeft ? lm.left_hood : lm.right_hood);
    const Vec3 shoulder = T * (a == Arm::kLeft ? lm.left_shoulder : lm.right_shoulder);
    const Vec3 hem = T * (a == Arm::kLeft ? lm.left_hem : lm.right_hem);
    ASSERT_GT(hem.x(), shoulder.x() + 0.1);
    const auto changes = gripper_changes(t.arm(a));
    ASSERT_EQ(changes.size(), 4u);  // close on the hood, open, close on the hem, open
    EXPECT_LT((changes[0].second - hood).norm(), 1e-9);
    // The face corner is put down at its mirror image about the neck line, the margin short.
    EXPECT_NEAR(changes[1].second.x(), hood.x() + 2 * 0.12 - 0.03, 1e-9);
    EXPECT_NEAR(changes[1].second.z(), hood.z() + 0.01, 1e-9);
    // The hem corner is put down the margin beyond the shoulder (its y kept), where the hood lies:
    // the hood ends between the halves and never rides on a moving flap.
    EXPECT_LT((changes[2].second - hem).norm(), 1e-9);
    EXPECT_NEAR(changes[3].second.x(), shoulder.x() + 0.03, 1e-9);
    EXPECT_NEAR(changes[3].second.y(), hem.y(), 1e-9);
    EXPECT_LT(max_speed(t.arm(a)), 0.4);
  }
  // tuck_hood = 0: straight to the shoulders.
  TaskParams p;
  set_task_param(p, "tuck_hood", 0);
  const auto changes = gripper_changes(make_fold(g, T, p).left);
  ASSERT_EQ(changes.size(), 2u);
  EXPECT_LT((changes[0].second - T * lm.left_shoulder).norm(), 1e-9);
  set_task_param(p, "tuck_hood", 0.5);
  EXPECT_THROW(make_fold(g, T, p), InputError);
  // A margin that puts the hem down beyond where it starts leaves no backward motion: refused,
  // naming the hem.
  TaskParams wide;
  set_task_param(wide, "fold_margin", 0.3);
  try {
    make_fold(g, T, wide);
    ADD_FAILURE() << "expected InputError";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("backward motion for the hem"), std::string::npos) << e.what();
  }
  // A fold line that is not beyond the face corners is refused.
  lm.hood_fold_x = -0.1;
  EXPECT_THROW(make_fold(g, T), InputError);
}

TEST(Generators, TimeScaleShortensTheQuasiStaticParts) {
  const garments::Garment g = small_garment();
  TaskParams p;
  const double full = make_fold(g, default_garment_pose(), p).end_time();
  p.time_scale = 0.5;
  EXPECT_NEAR(make_fold(g, default_garment_pose(), p).end_time(), 0.5 * full, 1e-9);
}

TEST(Generators, TaskParamsSetByNameChangeTheTask) {
  const garments::Garment g = small_garment();
  TaskParams p;
  const double full = make_fold(g, default_garment_pose(), p).end_time();
  set_task_param(p, "fold_duration", p.fold_duration + 2.0);
  EXPECT_NEAR(make_fold(g, default_garment_pose(), p).end_time(), full + 2.0, 1e-9);
  // Every listed name is a field: setting each to 7 leaves a different struct each time.
  ASSERT_EQ(task_param_names().size(), 29u);
  for (const std::string& name : task_param_names()) {
    TaskParams q;
    set_task_param(q, name, 7.0);
    int changed = 0;
    for (const std::string& other : task_param_names()) {
      TaskParams r;
      set_task_param(r, other, 7.0);
      changed += std::memcmp(&q, &r, sizeof(TaskParams)) == 0;
    }
    EXPECT_EQ(changed, 1) << name;
  }
  // task_param_values lists every field by name with its value.
  const auto values = task_param_values(p);
  ASSERT_EQ(values.size(), task_param_names().size());
  for (size_t k = 0; k < values.size(); ++k) EXPECT_EQ(values[k].first, task_param_names()[k]);
  EXPECT_EQ(std::find(values.begin(), values.end(), std::make_pair(std::string("fold_duration"), p.fold_duration)) -
                values.begin(),
            21);  // the 22nd name
  try {
    set_task_param(p, "fold_speed", 1.0);
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("fold_speed"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("fold_duration"), std::string::npos);  // the known names
  }
  set_task_param(p, "lift_duration", -1);  // the value is checked where the task is made
  EXPECT_THROW(make_grasp(g, default_garment_pose(), p), InputError);
}

// grasp_inset_side moves both grasp points (and the fold's hem corners) towards the centre line,
// for robot mode's fingers (docs/robot.md); past the centre line it is refused.
TEST(Generators, GraspInsetSideMovesTheGraspPointsTowardsTheCentreLine) {
  const garments::Garment g = small_garment();
  const Eigen::Isometry3d T = default_garment_pose();
  TaskParams p;
  set_task_param(p, "grasp_inset_side", 0.04);
  const DualArmTrajectory plain = make_fold(g, T), inset = make_fold(g, T, p);
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    const double toward = a == Arm::kLeft ? -0.04 : 0.04;
    const auto& ps = plain.arm(a).samples();
    const auto& is = inset.arm(a).samples();
    ASSERT_EQ(ps.size(), is.size());
    for (size_t k = 0; k < ps.size(); ++k) {  // the whole path, the shoulders and the hem corners alike
      EXPECT_NEAR(is[k].position.y() - ps[k].position.y(), toward, 1e-12) << k;
      EXPECT_NEAR(is[k].position.x(), ps[k].position.x(), 1e-12) << k;
    }
  }
  const double half = 0.5 * (g.landmarks.left_shoulder.y() - g.landmarks.right_shoulder.y());
  set_task_param(p, "grasp_inset_side", half + 0.01);
  try {
    make_grasp(g, T, p);
    FAIL() << "grasp points across the centre line were accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("grasp_inset_side"), std::string::npos) << e.what();
  }
}

// grasp_yaw turns the grippers about the vertical: the fingers (tool x) close along the garment's
// +x turned towards its +y, jaw still down, the same turn on every sample and the path unchanged;
// a garment lying turned turns the hands with it. Out of range it is refused.
TEST(Generators, GraspYawTurnsTheFingersAboutTheVerticalFromTheGarmentsLength) {
  const garments::Garment g = small_garment();
  const Eigen::Isometry3d T = default_garment_pose();
  TaskParams p;
  set_task_param(p, "grasp_yaw", 90);
  const DualArmTrajectory plain = make_fold(g, T), turned = make_fold(g, T, p);
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    const auto& ps = plain.arm(a).samples();
    const auto& ts = turned.arm(a).samples();
    ASSERT_EQ(ps.size(), ts.size());
    for (size_t k = 0; k < ps.size(); ++k) {
      EXPECT_LT((ts[k].position - ps[k].position).norm(), 1e-12) << k;
      EXPECT_LT((ps[k].orientation * Vec3::UnitX() - Vec3::UnitX()).norm(), 1e-12) << k;  // default: along +x
      EXPECT_LT((ts[k].orientation * Vec3::UnitX() - Vec3::UnitY()).norm(), 1e-12) << k;  // turned: along +y
      EXPECT_LT((ts[k].orientation * Vec3::UnitZ() + Vec3::UnitZ()).norm(), 1e-12) << k;  // jaw down
    }
  }
  // The garment lying turned by 30 degrees: the fingers follow its length, plus the yaw.
  Eigen::Isometry3d R = T;
  R.linear() = Eigen::AngleAxisd(std::numbers::pi / 6, Vec3::UnitZ()).toRotationMatrix();
  set_task_param(p, "grasp_yaw", 0);
  const ArmSample s0 = make_grasp(g, R, p).arm(Arm::kLeft).samples().front();
  EXPECT_LT((s0.orientation * Vec3::UnitX() - R.linear() * Vec3::UnitX()).norm(), 1e-12);
  set_task_param(p, "grasp_yaw", -45);
  const ArmSample s1 = make_grasp(g, R, p).arm(Arm::kLeft).samples().front();
  EXPECT_LT((s1.orientation * Vec3::UnitX() -
             Eigen::AngleAxisd(-std::numbers::pi / 12, Vec3::UnitZ()).toRotationMatrix() * Vec3::UnitX()).norm(),
            1e-12);
  for (double bad : {std::nan(""), 400.0}) {
    p.grasp_yaw = bad;
    try {
      make_grasp(g, T, p);
      FAIL() << "grasp_yaw " << bad << " was accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("grasp_yaw"), std::string::npos) << e.what();
    }
  }
}

TEST(Generators, BadInputIsAnInputError) {
  const garments::Garment g = small_garment();
  const Eigen::Isometry3d T = default_garment_pose();
  EXPECT_THROW(make_task("wave", g, T), InputError);
  EXPECT_NO_THROW(make_task("fold", g, T));
  TaskParams p;
  p.time_scale = 0;
  EXPECT_THROW(make_grasp(g, T, p), InputError);
  p = TaskParams();
  p.fold_margin = 1.0;  // beyond the garment
  EXPECT_THROW(make_fold(g, T, p), InputError);
  garments::Garment no_landmarks = g;
  no_landmarks.landmarks = garments::Landmarks();
  EXPECT_THROW(make_grasp(no_landmarks, T), InputError);
  garments::Garment swapped = g;
  std::swap(swapped.landmarks.left_shoulder, swapped.landmarks.right_shoulder);
  EXPECT_THROW(make_fling(swapped, T), InputError);
  garments::Garment flat = g;
  flat.length = 0;
  EXPECT_THROW(make_fold(flat, T), InputError);
}

// --- physical outcomes (pseudo grasp, no self-contact) ------------------------------------------

struct Outcome {
  std::vector<Vec3> x;
  double seconds = 0;
};

/// Replays `traj` on the small garment placed at RGBench's default pose, then `extra` seconds more.
Outcome replay(const DualArmTrajectory& traj, double extra = 0) {
  const auto t0 = std::chrono::steady_clock::now();
  auto scene = testing::make_scene(testing::placed(small_garment()));
  GripperController c(traj);
  EXPECT_TRUE(run_until(*scene, c, traj.end_time() + extra)) << scene->failure();
  Outcome o;
  o.x = scene->positions();
  o.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::printf("  %zu vertices, %.2f s simulated in %.2f s; x extent %.3f, y extent %.3f, z in [%.4f, %.4f]\n",
              o.x.size(), scene->time(), o.seconds, extent(o.x, 0), extent(o.x, 1), min_z(o.x), max_z(o.x));
  return o;
}

TEST(TaskOutcome, GraspLiftsTheGarmentClearOfTheTable) {
  TaskParams p;
  p.time_scale = 0.3;
  const Outcome o = replay(make_grasp(small_garment(), default_garment_pose(), p));
  EXPECT_GT(min_z(o.x), 0.01);
}

TEST(TaskOutcome, FoldLeavesItOnTheTableAtAboutHalfItsLength) {
  const garments::Garment g = small_garment();
  TaskParams p;
  p.time_scale = 0.5;
  const Outcome o = replay(make_fold(g, default_garment_pose(), p), 1.0);
  // Flat on the table except the fold's loop: an unpressed 180-degree fold of cotton (bending
  // length about 1.2 cm) stands 3-4 cm high at the fold line, so the bound on the highest point is
  // 4.5 cm; three in four vertices lie within 1 cm of the table (the rest are in the loop).
  EXPECT_LT(max_z(o.x), 0.045);
  std::vector<double> z;
  for (const Vec3& q : o.x) z.push_back(q.z());
  std::sort(z.begin(), z.end());
  EXPECT_LT(z[z.size() * 3 / 4], 0.01);
  EXPECT_GT(extent(o.x, 0), 0.4 * g.length);
  EXPECT_LT(extent(o.x, 0), 0.65 * g.length);
}

TEST(TaskOutcome, FlingEndsInTheAirSpread) {
  const garments::Garment g = small_garment();
  TaskParams p;
  p.time_scale = 0.3;
  const Outcome o = replay(make_fling(g, default_garment_pose(), p));
  EXPECT_GT(min_z(o.x), 0.01);
  EXPECT_GT(extent(o.x, 1), 0.6 * g.width);
}

}  // namespace
}  // namespace gd::tasks
