// A gripper pad that closes on two pinched layers faster than the predictor can move the stack:
// the predictor moves cloth out of a collider one vertex at a time, so the layer under the pad
// went onto the layer beneath (pinched layers met at 1e-17 m and the untangling fail-safe ran).
// A yielding collider stops short instead, where the step's starting guess keeps half the
// clearance it had from the pad at the step's start; its
// owner (here the test, in robot mode tasks::RobotController) starts the next step from there.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "sim/mesh.h"
#include "sim/scene.h"
#include "sim/solver/two_layers.h"

namespace gd::sim {
namespace {

using testing_layers::PadMotion;

struct SqueezeRun {
  int found = 0, untangled = 0, stopped = 0, newton = 0;
  int partner_stopped = 0;    // steps the still pad reported less than its whole motion (grouped)
  double max_disagree = 0;    // largest difference of the two pads' reached fractions in a step (grouped)
  double min_reached = 1;
  double min_gap = std::numeric_limits<double>::infinity();  // the layers' least distance, m
  bool failed = false;
};

// The two layers between the pads as in carry_sideways; the +y pad then closes on the -y one (which
// stands still) at `speed` until their faces would be 0.2 dhat apart, and holds. With `grouped` the
// still pad yields too and both are one yield group (one hand: Collider::set_yield_group).
SqueezeRun squeeze(bool yielding, double speed, double seconds, bool grouped = false) {
  const Material cotton = MaterialLibrary::load_default().get("cotton");
  const SceneOptions o = testing_layers::pinch_options();
  const double dhat = effective_contact_distance(o, cotton.thickness);
  const double W = 0.04, L = 0.06, grip = 0.02, gap = 0.3 * dhat, thick = 0.005;
  const Mesh mesh = testing_layers::two_hanging_layers(W, L, gap);
  auto scene = Scene::create(mesh, cotton, o);
  const double half_opening = 0.5 * gap + 0.25 * dhat, z = 0.5 + L - 0.5 * grip;
  const double y_start = half_opening + thick, y_end = -half_opening + 0.2 * dhat + thick;
  auto target = [=](double t) { return Vec3(0.5 * W, std::max(y_end, y_start - speed * t), z); };
  auto moving = std::make_shared<PadMotion>();
  moving->from = moving->to = target(0);
  const auto [still, id] =
      testing_layers::add_squeeze_pads(*scene, moving, W, thick, grip, y_start, z, yielding, grouped, grouped, 1.5);

  SqueezeRun r;
  while (scene->time() < seconds - 1e-9 && !scene->failed()) {
    moving->next(scene->collider_reached({id})[0], scene->time(), o.dt, target(scene->time() + o.dt));
    scene->step();
    const StepStats& st = scene->last_stats();
    r.found = std::max(r.found, st.intersecting_found);
    r.untangled += st.untangled;
    r.newton += st.newton_iters;
    r.min_gap = std::min(r.min_gap, st.min_self_distance);
    const std::vector<double> got = scene->collider_reached({id, still});
    const double s = got[0];
    r.stopped += s < 1.0;
    r.min_reached = std::min(r.min_reached, s);
    r.partner_stopped += got[1] < 1.0;
    r.max_disagree = std::max(r.max_disagree, std::abs(got[1] - got[0]));
  }
  r.failed = scene->failed();
  return r;
}

// A pad closing on the pinched stack at 0.1-0.4 m/s (0.5-2 mm per step, against layers 0.3 dhat
// apart): CCD cuts the predictor's motion back, the pad stops short of its pose (it reports less
// than its whole motion) where the guess keeps half its clearance, and no step finds an
// intersecting pair; the layers stay apart. A pad that does not yield reaches its pose every step
// and the predictor moves the cloth out of it, onto the layer beneath; the comparison is printed
// (Newton iterations, how close the layers came).
TEST(YieldingCollider, APadClosingFasterThanTheStackCanMoveStopsShort) {
  for (const double speed : {0.1, 0.4}) {
    SCOPED_TRACE(testing::Message() << "speed " << speed << " m/s");
    const SqueezeRun r = squeeze(true, speed, 0.05);
    const SqueezeRun fixed = squeeze(false, speed, 0.05);
    std::printf("closing at %.1f m/s: yielding: stopped %d times (least fraction %.3f), %d Newton iterations, "
                "layers %.2e m apart at least, intersecting found %d; not yielding: %d Newton iterations, "
                "layers %.2e m apart, intersecting found %d\n",
                speed, r.stopped, r.min_reached, r.newton, r.min_gap, r.found, fixed.newton, fixed.min_gap, fixed.found);
    EXPECT_FALSE(r.failed);
    EXPECT_GT(r.stopped, 0) << "the pad never stopped short: the test does not exercise the stop";
    EXPECT_LT(r.min_reached, 1.0);
    EXPECT_GE(r.min_reached, 0.0);
    EXPECT_EQ(r.found, 0);
    EXPECT_EQ(r.untangled, 0);
    // The barrier keeps the layers apart (measured 7e-5 to 9e-5 m). With a pad that does not
    // yield they were pressed onto each other (1e-20 m and closer): one step from a crossing.
    EXPECT_GT(r.min_gap, 1e-6);
    EXPECT_EQ(fixed.stopped, 0);  // a collider that does not yield always makes its whole motion
  }
}

// The same squeeze with the two pads one yield group (one hand whose one finger closes on the
// stack, the other holding still): where the closing pad stops short, its partner is stopped with
// it at the same fraction of the step's motion (predictor.h, stop_yielding_colliders: a group stops
// at the fraction the least advanced member reached), the still pad reports it (collider_reached),
// and the pinch stays apart as with one yielding pad. Without the group the still pad, which does
// not yield, always reports its whole motion (the test above).
TEST(YieldingCollider, AGroupedPadStopsWithItsPartner) {
  const SqueezeRun r = squeeze(true, 0.4, 0.05, true);
  std::printf("one hand closing at 0.4 m/s: the closing pad stopped %d times (least fraction %.3f), the still one "
              "%d times, the pads' fractions %.3g apart at most; layers %.2e m apart at least, intersecting "
              "found %d\n",
              r.stopped, r.min_reached, r.partner_stopped, r.max_disagree, r.min_gap, r.found);
  EXPECT_FALSE(r.failed);
  EXPECT_GT(r.stopped, 0) << "the closing pad never stopped short: the test does not exercise the group";
  EXPECT_EQ(r.partner_stopped, r.stopped) << "the still pad did not stop with its partner";
  EXPECT_EQ(r.max_disagree, 0.0) << "the pads of one group stopped at different fractions";
  EXPECT_EQ(r.found, 0);
  EXPECT_EQ(r.untangled, 0);
  EXPECT_GT(r.min_gap, 1e-6);
}

struct CarryRun {
  int found = 0, untangled = 0, stopped = 0;
  int max_newton = 0;  // most Newton iterations in one step
  double min_reached = 1;
  double shift = 0;  // mean sideways motion of the layers, m (the pads' is -speed * seconds)
  double max_widening = 0;  // most the pads stood farther apart than they started, m
  bool failed = false;
};

// Two 4 x 6 cm layers 0.3 dhat apart hanging in the xz plane, their top 2 cm between pads whose
// faces stand 0.25 dhat off each layer. Both pads then move sideways (-y) at `speed`: the +y pad
// pushes its layer towards the other, which only that layer's barrier can push in turn.
// With `group` the two pads are one yield group (Collider::set_yield_group): one hand.
CarryRun carry_sideways(bool yielding, double speed, double seconds,
                        const SceneOptions& o = testing_layers::pinch_options(), double friction = 1.5,
                        bool group = false) {
  const Material cotton = MaterialLibrary::load_default().get("cotton");
  const double dhat = effective_contact_distance(o, cotton.thickness);
  const double W = 0.04, L = 0.06, grip = 0.02, gap = 0.3 * dhat, thick = 0.005;
  const Mesh mesh = testing_layers::two_hanging_layers(W, L, gap);
  auto scene = Scene::create(mesh, cotton, o);
  const double half_opening = 0.5 * gap + 0.25 * dhat;
  const double z = 0.5 + L - 0.5 * grip;
  const std::vector<double> y0 = {-(half_opening + thick), half_opening + thick};
  testing_layers::Pads pads(*scene, {Vec3(0.5 * W, y0[0], z), Vec3(0.5 * W, y0[1], z)}, Vec3(W, thick, 0.5 * grip),
                            yielding, group, friction);
  const std::vector<int>& ids = pads.ids;
  const auto& motion = pads.motion;
  const auto x0 = scene->positions();
  CarryRun r;
  while (scene->time() < seconds - 1e-9 && !scene->failed()) {
    pads.advance(*scene, o.dt, [&](size_t k, double t1) { return Vec3(0.5 * W, y0[k] - speed * t1, z); });
    scene->step();
    const StepStats& st = scene->last_stats();
    r.found = std::max(r.found, st.intersecting_found);
    r.untangled += st.untangled;
    r.max_newton = std::max(r.max_newton, st.newton_iters);
    const std::vector<double> got = scene->collider_reached(ids);
    for (const double s : got) {
      r.stopped += s < 1.0;
      r.min_reached = std::min(r.min_reached, s);
    }
    const double apart = motion[1]->at(motion[1]->t0 + got[1] * (motion[1]->t1 - motion[1]->t0)).translation().y() -
                         motion[0]->at(motion[0]->t0 + got[0] * (motion[0]->t1 - motion[0]->t0)).translation().y();
    r.max_widening = std::max(r.max_widening, apart - (y0[1] - y0[0]));
  }
  r.failed = scene->failed();
  const auto x = scene->positions();
  for (size_t i = 0; i < x.size(); ++i) r.shift += (x[i].y() - x0[i].y()) / static_cast<double>(x.size());
  return r;
}

// The pads carry the pinch sideways at 0.06-0.2 m/s (0.3-1 dhat per step at dhat = 1 mm, against
// 0.3 dhat between the layers). Moving along its face, neither pad presses the cloth harder, so
// neither needs to stop (in these runs neither does), no step finds an intersecting pair,
// the fail-safe never runs, and the stack goes along as it does with pads that do not yield.
TEST(YieldingCollider, PadsCarryingAPinchSidewaysTakeTheStackAlongWithoutCrossings) {
  for (const double speed : {0.06, 0.1, 0.2}) {
    SCOPED_TRACE(testing::Message() << "speed " << speed << " m/s");
    const double seconds = 0.1;
    const CarryRun r = carry_sideways(true, speed, seconds);
    std::printf("yielding, %.2f m/s: stopped %d times (least fraction %.3f), stack moved %.2f mm (pads' target %.2f), "
                "intersecting found %d, untangled %d\n",
                speed, r.stopped, r.min_reached, 1e3 * r.shift, -1e3 * speed * seconds, r.found, r.untangled);
    EXPECT_FALSE(r.failed);
    EXPECT_EQ(r.found, 0) << "an intersecting pair after some step";
    EXPECT_EQ(r.untangled, 0);
    EXPECT_LT(r.shift, -0.5 * speed * seconds) << "the stack did not go along with the pads";
  }
  const CarryRun fixed = carry_sideways(false, 0.2, 0.1);
  std::printf("not yielding, 0.20 m/s: failed %d, intersecting found %d, untangled %d, stack moved %.2f mm\n",
              fixed.failed, fixed.found, fixed.untangled, 1e3 * fixed.shift);
  EXPECT_EQ(fixed.found, 0);
}

// A hand sweeping across its pads' faces (a fling's stroke: up to 1 m/s, 5 mm per step) faster
// than the predictor's inertial guess keeps up with: the trailing pad drove into the pinched stack,
// CCD cut the guess back, and that pad alone stopped short, fell behind its partner and opened the
// pinch by the lag (the T-shirt's fling lost both hands at the stroke's start: docs/robot.md,
// "Pads that stop together"). As one yield group (one hand) the pads carry the pinched stack in
// the predictor's guess and stop, if at all, together: they stand as far apart as they started
// (to rounding), no step finds an intersecting pair, and the stack goes along. Pads of no group,
// at 1 m/s, part by millimetres (the comparison printed).
TEST(YieldingCollider, PadsOfOneHandCarryThePinchAndKeepItClosed) {
  for (const double speed : {0.5, 1.0}) {
    SCOPED_TRACE(testing::Message() << "speed " << speed << " m/s");
    const double seconds = 0.05;
    const CarryRun hand = carry_sideways(true, speed, seconds, testing_layers::pinch_options(), 1.5, true);
    const CarryRun apart = carry_sideways(true, speed, seconds, testing_layers::pinch_options(), 1.5, false);
    std::printf("%.1f m/s: one hand: stopped %d times, pads %.3g mm wider at most, stack moved %.2f mm (pads' target "
                "%.2f); pads of no group: stopped %d times, %.3g mm wider at most, stack moved %.2f mm\n",
                speed, hand.stopped, 1e3 * hand.max_widening, 1e3 * hand.shift, -1e3 * speed * seconds, apart.stopped,
                1e3 * apart.max_widening, 1e3 * apart.shift);
    EXPECT_FALSE(hand.failed);
    EXPECT_LT(hand.max_widening, 1e-9) << "the hand's pads parted";
    EXPECT_EQ(hand.found, 0);
    EXPECT_EQ(hand.untangled, 0);
    EXPECT_LT(hand.shift, -0.5 * speed * seconds) << "the stack did not go along with the pads";
    if (speed >= 1.0) EXPECT_GT(apart.max_widening, 1e-3) << "pads of no group kept together: nothing to compare";
  }
}

// Cloth held in a pinch by friction slips out when the pinch's steps end unconverged (a T-shirt
// lifted by its shoulders lost both hands at 8 Newton iterations and held at 30: docs/robot.md,
// "Converged pinches"), so a step with a yielding collider that has friction (a finger pad) runs
// to SceneOptions::grip_newton_max_iters instead of newton_max_iters. Here newton_max_iters is 1
// and the pads carry the pinch sideways (steps that need several iterations): the cap rises with
// yielding pads that have friction, and only with them.
TEST(YieldingCollider, FingerPadsWithFrictionRaiseTheNewtonCap) {
  SceneOptions o = testing_layers::pinch_options();
  o.newton_max_iters = 1;
  o.grip_newton_max_iters = 30;
  const CarryRun fingers = carry_sideways(true, 0.2, 0.05, o);
  const CarryRun rigid = carry_sideways(false, 0.2, 0.05, o);
  const CarryRun frictionless = carry_sideways(true, 0.2, 0.05, o, 0.0);
  std::printf("most Newton iterations in a step: yielding pads with friction %d, rigid pads %d, frictionless "
              "yielding pads %d\n", fingers.max_newton, rigid.max_newton, frictionless.max_newton);
  EXPECT_GT(fingers.max_newton, 1) << "the steps converged in one iteration: the test does not exercise the cap";
  EXPECT_LE(fingers.max_newton, 30);
  EXPECT_EQ(rigid.max_newton, 1);
  EXPECT_EQ(frictionless.max_newton, 1);
  EXPECT_EQ(fingers.found, 0);
}

}  // namespace
}  // namespace gd::sim
