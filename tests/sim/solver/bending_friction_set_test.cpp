// Internal friction in bending through the solver (Solver::slip_bending_friction, predictor.h):
// a fold held and let go keeps a set where the elastic moment meets the friction limit, and the
// energy never grows once the hand is gone.
#include <gtest/gtest.h>

#include <cmath>

#include "sim/energy/bending.h"
#include "sim/scene.h"

namespace gd::sim {
namespace friction_set_test {

// One hinge: the edge x0-x1 along y, wing a (x0, x1, x2) at x < 0, wing b (x1, x0, x3) at x > 0.
constexpr double kL = 0.02, kA = 0.015;
Mesh one_hinge() {
  Mesh m;
  m.x = {Vec3(0, 0, 0.5), Vec3(0, kL, 0.5), Vec3(-kA, 0.5 * kL, 0.5), Vec3(kA, 0.5 * kL, 0.5)};
  m.tris = {Eigen::Vector3i(0, 2, 1), Eigen::Vector3i(0, 1, 3)};
  return m;
}

// Wing b turned down by `angle` about the edge (θ = +angle).
Vec3 x3_at(double angle) { return Vec3(kA * std::cos(angle), 0.5 * kL, 0.5 - kA * std::sin(angle)); }

double angle_of(const Scene& s) {
  const auto x = s.positions();
  return dihedral_angle(x[0], x[1], x[2], x[3]);
}

SceneOptions still_options() {
  SceneOptions o;
  o.table = false;
  o.gravity = Vec3::Zero();
  o.air_density = 0;
  return o;
}

// Cotton with linear bending and, unless 2HB is 0, internal friction whose limit moment is
// `ratio` times the rigidity (the set's curvature, 1/m).
Material cotton_with_friction(double ratio) {
  Material m = MaterialLibrary::load_default().get("cotton");
  m.bend_kappa_n = 1e6;
  m.bend_friction_warp = ratio * m.bend_warp;
  m.bend_friction_weft = ratio * m.bend_weft;
  return m;
}

// Wing a held, wing b turned to 1 rad and held there, then let go and relaxed (quasi-static
// steps): the hinge comes back until its elastic moment G κ equals the friction's limit M, so it
// keeps κ = M/G (the hinge on a held wing: κ = sqrt(3) |e| / A_b θ, clamped_hinges_test.cpp).
// Without friction it comes back flat.
TEST(BendingFrictionSet, AFoldLetGoKeepsTheCurvatureWhereBendingMeetsTheFrictionLimit) {
  const Mesh mesh = one_hinge();
  const double coef = std::sqrt(3.0) * kL / (0.5 * kL * kA);  // wing b's area alone
  for (const double ratio : {0.0, 30.0, 60.0}) {
    const Material mat = cotton_with_friction(ratio);
    auto s = Scene::create(mesh, mat, still_options());
    s->pin({0, 1, 2});
    const int hand = s->set_targets({3}, {x3_at(1.0)});
    ASSERT_TRUE(s->step(20));
    EXPECT_NEAR(angle_of(*s), 1.0, 1e-3);
    s->release(hand);
    ASSERT_GT(s->relax(400, 1e-9), 0);
    const double kappa = coef * angle_of(*s);
    // The hinge's rigidity is the material's along the edge's direction; the edge runs along y,
    // so G = bend_warp (and M the warp's limit).
    const double expected = ratio;  // M / G
    EXPECT_NEAR(kappa, expected, 0.02 * std::max(expected, 1.0)) << "2HB/2 = " << ratio << " G";
  }
}

// Let go dynamically (implicit Euler, no damping but the integrator's and the friction's): the
// total energy, the friction spring's stored part included, never grows after the release, and
// the hinge ends between flat and the set the quasi-static release keeps.
TEST(BendingFrictionSet, EnergyNeverGrowsAfterTheRelease) {
  const Mesh mesh = one_hinge();
  const double coef = std::sqrt(3.0) * kL / (0.5 * kL * kA);
  const Material mat = cotton_with_friction(30.0);
  auto s = Scene::create(mesh, mat, still_options());
  s->pin({0, 1, 2});
  const int hand = s->set_targets({3}, {x3_at(1.0)});
  ASSERT_TRUE(s->step(20));
  s->release(hand);
  // From the first step after the release on: until then the hinge had both wings held and was
  // not a clamped one (ClampedHinges), so its energy was measured another way.
  ASSERT_TRUE(s->step());
  const double e0 = s->energies().total();
  double e_prev = e0;
  double kappa_min = 1e9;
  for (int k = 0; k < 300; ++k) {
    ASSERT_TRUE(s->step());
    const double e = s->energies().total();
    EXPECT_LE(e, e_prev + 1e-6 * e0) << "step " << k;  // Newton's tolerance
    e_prev = e;
    kappa_min = std::min(kappa_min, coef * angle_of(*s));
  }
  const double kappa = coef * angle_of(*s);
  EXPECT_LT(kappa, 30.0 * 1.02);
  EXPECT_GT(kappa_min, -30.0 * 1.02);  // never swings past the opposite set
}

}  // namespace friction_set_test
}  // namespace gd::sim
