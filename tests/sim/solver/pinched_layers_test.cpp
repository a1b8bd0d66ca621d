// Two layers of cloth pinched between two box pads (a gripper holding a fold): the pads squeeze
// the stack with less room than a contact distance per layer, then carry it up. The predictor
// moves cloth out of the pads' end poses; lifting a pressed layer off its pad to dhat/2 moved
// it that far towards the layer beneath and through it, which only the untangling fail-safe then
// repaired (docs/robot.md, "Pinched layers"). Cloth a pad presses now keeps its clearance.
#include <gtest/gtest.h>

#include <cmath>

#include "sim/mesh.h"
#include "sim/scene.h"
#include "sim/solver/two_layers.h"

namespace gd::sim {
namespace {

struct PinchRun {
  int steps = 0, found = 0, untangled = 0;
  double rise = 0;  // mean rise of the layers, m
  bool failed = false;
};

// Two 4 x 6 cm layers hanging in the xz plane (the first at y = +gap/2, the second at -gap/2),
// their top 2 cm between pads whose faces stand `clearance` off each layer; after 0.05 s at rest
// the pads rise at `speed` (ramped in over 0.05 s) until t = `seconds`.
PinchRun pinch_and_lift(double gap_in_dhat, double clearance_in_dhat, double speed, double seconds) {
  const Material cotton = MaterialLibrary::load_default().get("cotton");
  const SceneOptions o = testing_layers::pinch_options();
  const double dhat = effective_contact_distance(o, cotton.thickness);
  const double W = 0.04, L = 0.06, grip = 0.02, gap = gap_in_dhat * dhat;
  const Mesh mesh = testing_layers::two_hanging_layers(W, L, gap);
  auto scene = Scene::create(mesh, cotton, o);
  const double half_opening = 0.5 * gap + clearance_in_dhat * dhat;
  const double start = 0.05, ramp = 0.05;
  for (const double side : {-1.0, 1.0}) {
    Collider pad = Collider::box(Vec3(W, 0.005, 0.5 * grip));
    const Vec3 c(0.5 * W, side * (half_opening + 0.005), 0.5 + L - 0.5 * grip);
    pad.set_pose([=](double t) {
      // Rise s(t): 0 until `start`, accelerating over `ramp`, then at `speed`.
      const double u = std::max(0.0, t - start);
      const double rise = u < ramp ? 0.5 * speed * u * u / ramp : speed * (u - 0.5 * ramp);
      return Eigen::Isometry3d(Eigen::Translation3d(c + Vec3(0, 0, rise)));
    });
    pad.set_friction(1.5);
    pad.set_stiffness_scale(20);  // a squeeze of ~20 times the weight under a pad, as robot mode sets it
    scene->add_collider(pad);
  }
  const auto x0 = scene->positions();
  PinchRun r;
  while (scene->time() < seconds - 1e-9 && !scene->failed()) {
    scene->step();
    const StepStats& st = scene->last_stats();
    r.found = std::max(r.found, st.intersecting_found);
    r.untangled += st.untangled;
    ++r.steps;
  }
  r.failed = scene->failed();
  const auto x = scene->positions();
  for (size_t i = 0; i < x.size(); ++i) r.rise += (x[i].z() - x0[i].z()) / static_cast<double>(x.size());
  return r;
}

// Opening 0.8 dhat for two layers 0.3 dhat apart: before the fix, the first step put both layers
// dhat/2 off their pads, one through the other. Now no step finds an intersecting pair, the
// fail-safe never runs, and friction carries the stack up with the pads (0.2 m/s for 0.3 s: 5.5
// cm), for several squeezes and speeds.
TEST(PinchedLayers, StayApartWithoutTheFailSafeWhileThePadsCarryThemUp) {
  for (const auto& [clearance, speed] : {std::pair{0.25, 0.2}, {0.15, 0.2}, {0.25, 0.1}, {0.35, 0.3}}) {
    const double seconds = 0.4;
    const PinchRun r = pinch_and_lift(0.3, clearance, speed, seconds);
    SCOPED_TRACE(testing::Message() << "clearance " << clearance << " dhat, speed " << speed << " m/s");
    EXPECT_FALSE(r.failed);
    EXPECT_EQ(r.found, 0) << "an intersecting pair after some step";
    EXPECT_EQ(r.untangled, 0);
    const double pad_rise = speed * (seconds - 0.05 - 0.025);
    EXPECT_GT(r.rise, 0.8 * pad_rise) << "the stack slipped out (pads rose " << pad_rise << " m)";
    EXPECT_LT(r.rise, 1.05 * pad_rise);
  }
}

}  // namespace
}  // namespace gd::sim
