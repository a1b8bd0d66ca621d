// The predictor's guess in two legs where cloth is pinched (SceneOptions::pinch_first_guess): the
// pinched vertices first, the rest of the cloth after, each leg cut back by CCD on its own. Cut
// back as one motion, a contact anywhere in a garment held the pinch back while the hand's pads
// went on, the pads stopped short on it step after step, and at a fling's turn the squeeze read
// at the stopped pads rose to hundreds of newtons (docs/robot.md, "A guess that carries the pinch
// first"). Here a held sheet pressed onto another on the table stands in for that contact.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <utility>
#include <vector>

#include "sim/mesh.h"
#include "sim/scene.h"
#include "sim/solver/two_layers.h"

namespace gd::sim {
namespace {

// A 3 x 3 cm sheet on the table and a held one above it pressed down onto it at 0.5 m/s (its
// vertices attached to a descending pose, as a gripper pressing cloth onto the table): every
// step's guess moves the held sheet 2.5 mm into the one beneath, which CCD cuts back. Appended to
// `mesh` with its origin at `at`; `held` gets the held sheet's vertices.
void add_pressing_sheets(Mesh* mesh, const Vec3& at, double dhat, std::vector<int>* held) {
  const Mesh sheet = make_rect(0.03, 0.03, 0.004);
  for (const double z : {0.5 * dhat, 1.5 * dhat}) {
    const int n = static_cast<int>(mesh->x.size());
    for (size_t i = 0; i < sheet.x.size(); ++i) {
      if (z > dhat) held->push_back(n + static_cast<int>(i));
      mesh->x.push_back(at + Vec3(sheet.x[i].x(), sheet.x[i].y(), z));
    }
    mesh->uv.insert(mesh->uv.end(), sheet.uv.begin(), sheet.uv.end());
    for (const Eigen::Vector3i& t : sheet.tris) mesh->tris.push_back(t + Eigen::Vector3i::Constant(n));
  }
}

void press(Scene* scene, const std::vector<int>& held) {
  scene->attach(held, [](double t) { return Eigen::Isometry3d(Eigen::Translation3d(0, 0, -0.5 * t)); });
}

struct CarryRun {
  double min_reached = 1;  // the least fraction of its motion a pad made in a step
  int stopped = 0;         // steps a pad stopped short
  double shift = 0;        // mean motion of the pinched layers' vertices along -y, m
  int found = 0, untangled = 0;
  bool failed = false;
};

// Two 4 x 6 cm layers 0.3 dhat apart hang with their top 2 cm between the two pads of one hand
// (yielding, one yield group: robot mode's fingers), carried across the pads' faces (-y) at
// `speed` for `seconds`; with `pressing`, the pressing sheets half a metre away.
CarryRun carry(bool pinch_first, bool pressing, double speed, double seconds) {
  const Material cotton = MaterialLibrary::load_default().get("cotton");
  SceneOptions o = testing_layers::pinch_options();
  o.table = true;
  o.pinch_first_guess = pinch_first;
  const double dhat = effective_contact_distance(o, cotton.thickness);
  const double W = 0.04, L = 0.06, grip = 0.02, gap = 0.3 * dhat, thick = 0.005;
  Mesh mesh = testing_layers::two_hanging_layers(W, L, gap);
  const int pinch_vertices = static_cast<int>(mesh.x.size());
  std::vector<int> upper;
  if (pressing) add_pressing_sheets(&mesh, Vec3(0.5, 0, 0), dhat, &upper);
  auto scene = Scene::create(mesh, cotton, o);
  if (pressing) press(scene.get(), upper);
  const double half_opening = 0.5 * gap + 0.25 * dhat, z = 0.5 + L - 0.5 * grip;
  const std::vector<Vec3> start = {Vec3(0.5 * W, -(half_opening + thick), z), Vec3(0.5 * W, half_opening + thick, z)};
  testing_layers::Pads hand(*scene, start, Vec3(W, thick, 0.5 * grip), true, true, 1.5);
  const auto x0 = scene->positions();
  CarryRun r;
  while (scene->time() < seconds - 1e-9 && !scene->failed()) {
    hand.advance(*scene, o.dt, [&](size_t k, double t1) -> Vec3 { return start[k] - Vec3(0, speed * t1, 0); });
    scene->step();
    const StepStats& st = scene->last_stats();
    r.found = std::max(r.found, st.intersecting_found);
    r.untangled += st.untangled;
    for (const double s : scene->collider_reached(hand.ids)) {
      r.stopped += s < 1.0;
      r.min_reached = std::min(r.min_reached, s);
    }
  }
  r.failed = scene->failed();
  const auto x = scene->positions();
  for (int i = 0; i < pinch_vertices; ++i) r.shift -= (x[i].y() - x0[i].y()) / pinch_vertices;
  return r;
}

// The hand carries its pinch at 0.5 m/s (2.5 mm per step, against layers 0.3 mm apart) for 0.05 s.
// With nothing else in the scene its pads never stop short. With the pressing sheets and the guess
// cut back as one motion they stop short in most steps, at a small fraction of their motion; with
// the pinch's leg first they make their whole motion as without the sheets, the stack goes along
// as far, and no step finds an intersecting pair. The runs' numbers are printed.
TEST(PinchFirstGuess, AContactElsewhereNoLongerHoldsThePinchBack) {
  const double speed = 0.5, seconds = 0.05;
  const CarryRun alone = carry(true, false, speed, seconds);
  const CarryRun one_leg = carry(false, true, speed, seconds);
  const CarryRun two_legs = carry(true, true, speed, seconds);
  for (const auto& [name, r] : {std::pair<const char*, const CarryRun&>{"alone", alone}, {"one leg", one_leg},
                                {"two legs", two_legs}})
    std::printf("%s: pads stopped short %d times (least fraction %.3f), stack moved %.2f mm (pads %.2f), "
                "intersecting found %d, untangled %d\n",
                name, r.stopped, r.min_reached, 1e3 * r.shift, 1e3 * speed * seconds, r.found, r.untangled);
  for (const CarryRun* r : {&alone, &one_leg, &two_legs}) {
    EXPECT_FALSE(r->failed);
    EXPECT_EQ(r->found, 0);
    EXPECT_EQ(r->untangled, 0);
  }
  EXPECT_EQ(alone.stopped, 0) << "the pinch alone stops the pads: the scene does not isolate the contact elsewhere";
  EXPECT_GT(one_leg.stopped, 0) << "the pressing sheets never cut the guess back: nothing to compare";
  EXPECT_LT(one_leg.min_reached, 0.5);
  EXPECT_EQ(two_legs.stopped, 0) << "the contact elsewhere still held the pinch back";
  EXPECT_NEAR(two_legs.shift, alone.shift, 0.1 * alone.shift);
}

// Without a pinch the two-leg guess is never tried: a hand whose pads hold nothing and the same
// pressing sheets step exactly as with the option off.
TEST(PinchFirstGuess, NoPinchNoChange) {
  const Material cotton = MaterialLibrary::load_default().get("cotton");
  auto run = [&](bool pinch_first) {
    SceneOptions o = testing_layers::pinch_options();
    o.table = true;
    o.pinch_first_guess = pinch_first;
    const double dhat = effective_contact_distance(o, cotton.thickness);
    Mesh mesh;
    std::vector<int> upper;
    add_pressing_sheets(&mesh, Vec3::Zero(), dhat, &upper);
    auto scene = Scene::create(mesh, cotton, o);
    press(scene.get(), upper);
    testing_layers::Pads hand(*scene, {Vec3(0.3, -0.01, 0.2), Vec3(0.3, 0.01, 0.2)}, Vec3(0.02, 0.005, 0.01), true,
                              true, 1.5);
    for (int s = 0; s < 10; ++s) {
      hand.advance(*scene, o.dt, [&](size_t k, double t1) -> Vec3 {
        return Vec3(0.3, k == 0 ? -0.01 : 0.01, 0.2) - Vec3(0, 0.5 * t1, 0);
      });
      scene->step();
    }
    return scene->positions();
  };
  const auto a = run(false), b = run(true);
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) EXPECT_EQ(a[i], b[i]) << "vertex " << i;
}

}  // namespace
}  // namespace gd::sim
