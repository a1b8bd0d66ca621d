// A coarse pinch swept along the pads' faces at a fling's pace, with the pads in the solve (robot
// mode's default, SceneOptions::pad_stiffness): a 4 x 12 cm strip meshed at 2 cm, so that only
// two of its vertices lie between the pads, hangs from the left hand, which then moves 20 cm
// sideways (along the faces) in 0.2 s, with Newton run to newton_tol (the residual rule off). In
// these strokes the pads reach the end of their step's motion (s = 1) while the cloth still pulls
// them on by a hair; Newton used to keep them there by bounding the step length, to 0, and ran to
// its cap without moving: 34 such steps over these eight draws, one of them lost (docs/robot.md,
// "A hand at the end of its step"); likewise at s = 0 ("A hand at the other end of its step").
// Those strokes hold the strip's vertices alone out of the pads (SceneOptions::pad_samples off):
// robot mode's default since 2026-12-07 holds its surface samples out too, which fills the pads'
// faces with some 220 points of the strip instead of two vertices (the last test below).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "tasks/robot_arms.h"
#include "tasks/task_test_util.h"

namespace gd::tasks {
namespace pinch_stroke {

using testing::make_scene;
using testing::piper_urdf;
using testing::task_options;
using testing::two_arms;

constexpr double kX = 0.25, kY = 0.25, kTipZ = 0.05;  // the left hand's fingertips before the stroke, world
constexpr double kStroke = 0.2, kStrokeStart = 0.7, kStrokeTime = 0.2;

struct Swept {
  double moved = 0;     ///< m: the strip's mean displacement along the stroke
  double lost_at = -1;  ///< s: when the hand let go (< 0: held)
  int pinched = 0;      ///< vertices on the pads' inner faces before the stroke
  int stuck_steps = 0;  ///< steps that ran to the Newton cap and took a step of length 0
  bool failed = false;
};

/// The strip hanging in the plane x = kX (its top row pinned at z = 0.11 until 0.5 s), gripped by
/// the left hand (closed at 0.1 s), swept along -y by kStroke from kStrokeStart over kStrokeTime
/// (velocity (1 - cos) shaped, 2 m/s at its peak), measured 0.2 s after the stroke.
/// `to_tolerance`: Newton run to newton_tol (the residual rule off), else robot mode's default rule.
/// `self_contact`: the cloth's self-contact (robot mode's scenes have it; a user's may not).
/// `samples`: the cloth's surface samples held out of the pads (robot mode's default since
/// 2026-12-07); without them only the strip's vertices are, two of them between the pads.
Swept sweep(double finger_friction, const Vec3& hand_offset, bool to_tolerance = true, bool self_contact = true,
            bool samples = true) {
  sim::Mesh m = sim::make_rect(0.04, 0.12, 0.02);
  for (Vec3& p : m.x) p = Vec3(kX, kY - 0.02 + p.x(), 0.11 - p.y());
  sim::SceneOptions o = task_options();
  o.dt = 0.005;
  o.table = false;
  o.self_contact = self_contact;
  o.pad_stiffness = kDefaultPadStiffness;  // as robot mode's scenes take it
  o.pad_samples = samples;
  if (to_tolerance) o.newton_rtol = o.newton_atol = 0;  // Newton runs on past the pads' arrival at s = 1
  auto scene = make_scene(m, o);
  std::vector<int> top;
  for (int i = 0; i < scene->vertex_count(); ++i)
    if (m.x[i].z() > 0.11 - 1e-9) top.push_back(i);
  const int pins = scene->pin(top);
  std::vector<double> times;
  for (int k = 0; k <= 120; ++k) times.push_back(0.01 * k);
  auto at = [hand_offset](double t) -> Vec3 {
    const double u = std::clamp((t - kStrokeStart) / kStrokeTime, 0.0, 1.0);
    return Vec3(kX, kY - kStroke * (u - std::sin(2 * M_PI * u) / (2 * M_PI)), kTipZ) + hand_offset;
  };
  RobotOptions ro;
  ro.urdf = piper_urdf();
  ro.finger_friction = finger_friction;
  ro.pad_samples = samples;
  RobotController c(two_arms(times, at, [](double t) { return t < 0.1 ? kGripperOpen : 0.0; }), ro);
  Swept out;
  const auto count_stuck = [&](const sim::StepStats& st) {
    if (st.newton_iters >= o.grip_newton_max_iters && st.min_alpha == 0) ++out.stuck_steps;
  };
  auto mean_y = [&] {
    double y = 0;
    for (const Vec3& p : scene->positions()) y += p.y() / scene->vertex_count();
    return y;
  };
  out.failed = true;
  if (!run_until(*scene, c, 0.5, count_stuck)) return out;
  scene->release(pins);
  if (!run_until(*scene, c, kStrokeStart, count_stuck)) return out;
  out.pinched = c.state(Arm::kLeft).vertices_open;
  const double y0 = mean_y();
  if (!run_until(*scene, c, kStrokeStart + kStrokeTime + 0.2, count_stuck)) return out;
  out.failed = false;
  out.moved = y0 - mean_y();
  out.lost_at = c.state(Arm::kLeft).lost_at;
  return out;
}

TEST(PinchStroke, AHandAtTheEndOfItsStepNeverStallsNewton) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  // The cotton's friction and a higher one; the hand on the strip's midline and 1-3 mm off it.
  int stuck = 0;
  for (const double mu : {0.266, 0.8}) {
    for (const Vec3& offset : {Vec3(0, 0, 0), Vec3(0.001, 0.001, 0), Vec3(0.003, 0, 0), Vec3(-0.003, 0.003, 0)}) {
      SCOPED_TRACE(::testing::Message() << "friction " << mu << ", hand offset " << offset.transpose());
      const Swept s = sweep(mu, offset, true, true, false);
      std::printf("friction %.3f, offset (%g, %g): %d vertices on the pads, the strip moved %.1f mm of %.0f, "
                  "lost at %.3f s, %d stuck steps\n", mu, offset.x(), offset.y(), s.pinched, 1e3 * s.moved,
                  1e3 * kStroke, s.lost_at, s.stuck_steps);
      ASSERT_FALSE(s.failed);
      EXPECT_LE(s.pinched, 4) << "the pinch is not a coarse one: the test does not exercise it";
      EXPECT_LT(s.lost_at, 0) << "the hand let go";
      EXPECT_NEAR(s.moved, kStroke, 0.25 * kStroke);  // it went with the hand (the 12 cm strip swings)
      stuck += s.stuck_steps;
    }
  }
  // 34 without the active set at s = 1; one more (friction 0.266, offset (-3, 3) mm) until the
  // active set at s = 0 too (docs/robot.md, "A hand at the other end of its step").
  EXPECT_EQ(stuck, 0) << "steps ran to the Newton cap with a hand held at an end of its motion";
  const Swept frictionless = sweep(0.0, Vec3::Zero(), true, true, false);
  ASSERT_FALSE(frictionless.failed);
  std::printf("without friction: the strip moved %.1f mm, lost at %.3f s\n", 1e3 * frictionless.moved,
              frictionless.lost_at);
  EXPECT_LT(frictionless.moved, 0.5 * kStroke);  // it slid out: the hand holds nothing by itself
}

// The same strokes with the cloth's self-contact off (SceneOptions::self_contact = false): the
// predictor stopped pads in the solve only within its self-contact branch, so without it nothing
// stopped them, the projection left them out, and the first step that drove a pad into the strip
// had a vertex inside it (the energy not finite: the scene failed at 0.845 s).
TEST(PinchStroke, PadsInTheSolveHoldWithSelfContactOff) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  for (const double mu : {0.266, 0.8}) {
    SCOPED_TRACE(::testing::Message() << "friction " << mu);
    const Swept s = sweep(mu, Vec3::Zero(), true, false);
    std::printf("self-contact off, friction %.3f: %d vertices on the pads, the strip moved %.1f mm of %.0f, lost at "
                "%.3f s\n", mu, s.pinched, 1e3 * s.moved, 1e3 * kStroke, s.lost_at);
    ASSERT_FALSE(s.failed);
    EXPECT_LT(s.lost_at, 0) << "the hand let go";
    EXPECT_NEAR(s.moved, kStroke, 0.25 * kStroke);
  }
}

// The same strokes with robot mode's stopping rule, at sixteen draws (two frictions, eight hand
// offsets up to 3 mm): steps that ended on a line-search step cut to ~1e-4 of its direction were
// taken as converged, and 7 of the 16 draws let go of the strip (docs/robot.md, "Steps the line
// search cut short"); since such a step ends nothing (Solver::correction_measures), 3 of 16. Newton
// run to newton_tol loses 3 of these 16 too (other draws), so what is left is not the rule's
// looseness but the coarse pinch itself: the bound below is the count measured with a draw of margin.
TEST(PinchStroke, AStepTheLineSearchCutShortDoesNotEndNewton) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  int lost = 0, draws = 0;
  for (const double mu : {0.266, 0.8}) {
    for (const Vec3& offset : {Vec3(0, 0, 0), Vec3(0.001, 0.001, 0), Vec3(0.003, 0, 0), Vec3(-0.003, 0.003, 0),
                               Vec3(0.002, -0.002, 0), Vec3(-0.001, 0, 0), Vec3(0, 0.002, 0), Vec3(0.0015, 0.0025, 0)}) {
      SCOPED_TRACE(::testing::Message() << "friction " << mu << ", hand offset " << offset.transpose());
      const Swept s = sweep(mu, offset, false, true, false);
      std::printf("friction %.3f, offset (%g, %g): %d vertices on the pads, the strip moved %.1f mm, lost at %.3f s\n",
                  mu, offset.x(), offset.y(), s.pinched, 1e3 * s.moved, s.lost_at);
      ASSERT_FALSE(s.failed);
      EXPECT_LE(s.pinched, 4) << "the pinch is not a coarse one: the test does not exercise it";
      lost += s.lost_at >= 0;
      ++draws;
    }
  }
  std::printf("%d of %d draws let go\n", lost, draws);
  EXPECT_LE(lost, 4) << "steps ended on cut line-search steps again? (7 of 16 before)";
}

// Robot mode's defaults (the surface samples on, its stopping rule) on the same strokes: the pinch
// is no longer coarse (the strip's samples cover the pads' faces), and every draw holds, where the
// vertices alone let go of 3 of 16 (above). Without friction the strip slides out.
TEST(PinchStroke, SurfaceSamplesHoldTheStripInEveryDraw) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  for (const Vec3& offset : {Vec3(0, 0, 0), Vec3(0.001, 0.001, 0), Vec3(0.003, 0, 0), Vec3(-0.003, 0.003, 0),
                             Vec3(0.002, -0.002, 0), Vec3(-0.001, 0, 0), Vec3(0, 0.002, 0), Vec3(0.0015, 0.0025, 0)}) {
    SCOPED_TRACE(::testing::Message() << "hand offset " << offset.transpose());
    const Swept s = sweep(0.266, offset, false);
    std::printf("samples, offset (%g, %g): %d points on the pads, the strip moved %.1f mm, lost at %.3f s\n",
                offset.x(), offset.y(), s.pinched, 1e3 * s.moved, s.lost_at);
    ASSERT_FALSE(s.failed);
    EXPECT_GT(s.pinched, 50) << "the samples did not reach the pads' faces";
    EXPECT_LT(s.lost_at, 0) << "the hand let go";
    EXPECT_NEAR(s.moved, kStroke, 0.05 * kStroke);  // 199.6-200.1 mm measured
  }
  const Swept frictionless = sweep(0.0, Vec3::Zero(), false);
  ASSERT_FALSE(frictionless.failed);
  std::printf("samples, without friction: the strip moved %.1f mm, lost at %.3f s\n", 1e3 * frictionless.moved,
              frictionless.lost_at);
  EXPECT_LT(frictionless.moved, 0.5 * kStroke);
}

}  // namespace pinch_stroke
}  // namespace gd::tasks
