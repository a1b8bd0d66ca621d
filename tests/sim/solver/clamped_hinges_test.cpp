// Bending at the edge of a clamped region (Solver::clamp_hinges, predictor.h): a hinge between a
// held wing and a free one stands for the free wing's area alone.
#include <gtest/gtest.h>

#include <cmath>

#include "sim/scene.h"

namespace gd::sim {
namespace {

// One hinge: the edge x0-x1 along y, wing a (x0, x1, x2) at x < 0, wing b (x1, x0, x3) at x > 0,
// wing b `ratio` times as wide as wing a.
Mesh one_hinge(double ratio) {
  Mesh m;
  const double L = 0.02, a = 0.015;
  m.x = {Vec3(0, 0, 0.5), Vec3(0, L, 0.5), Vec3(-a, 0.5 * L, 0.5), Vec3(ratio * a, 0.5 * L, 0.5)};
  m.tris = {Eigen::Vector3i(0, 2, 1), Eigen::Vector3i(0, 1, 3)};
  return m;
}

// Wing b turned by `angle` about the edge.
std::vector<Vec3> bent(const Mesh& m, double angle) {
  std::vector<Vec3> x = m.x;
  const double r = x[3].x();
  x[3] = Vec3(r * std::cos(angle), x[3].y(), 0.5 + r * std::sin(angle));
  return x;
}

double bending_energy_at(Scene& s, const Mesh& m, double angle) {
  s.set_state(bent(m, angle), std::vector<Vec3>(m.x.size(), Vec3::Zero()));
  return s.energies().bending;
}

SceneOptions still_options() {
  SceneOptions o;
  o.table = false;
  o.gravity = Vec3::Zero();
  o.air_density = 0;
  return o;
}

// Bending as good as linear (the quartic term ~1e-8 of the energy at these curvatures), so
// energies scale with area * coef^2 alone.
Material linear_cotton() {
  Material m = MaterialLibrary::load_default().get("cotton");
  m.bend_kappa_n = 1e6;
  return m;
}

TEST(ClampedHinges, AHingeOnAClampedEdgeStandsForItsFreeWingAlone) {
  const Material cotton = linear_cotton();
  for (const double ratio : {1.0, 2.0}) {
    const Mesh m = one_hinge(ratio);
    auto s = Scene::create(m, cotton, still_options());
    ASSERT_TRUE(s->step());
    const double free_energy = bending_energy_at(*s, m, 0.3);
    ASSERT_GT(free_energy, 0);
    // Wing a held: the hinge's area is wing b's alone, (A_a + A_b) / A_b times the energy.
    const int g = s->pin({0, 1, 2});
    s->set_state(m.x, std::vector<Vec3>(m.x.size(), Vec3::Zero()));
    ASSERT_TRUE(s->step());
    EXPECT_NEAR(bending_energy_at(*s, m, 0.3) / free_energy, (1 + ratio) / ratio, 1e-6) << "ratio " << ratio;
    // Released, the hinge is an interior one again.
    s->release(g);
    s->set_state(m.x, std::vector<Vec3>(m.x.size(), Vec3::Zero()));
    ASSERT_TRUE(s->step());
    EXPECT_NEAR(bending_energy_at(*s, m, 0.3) / free_energy, 1.0, 1e-12);
    // Wing b held: the area is wing a's.
    s->pin({0, 1, 3});
    s->set_state(m.x, std::vector<Vec3>(m.x.size(), Vec3::Zero()));
    ASSERT_TRUE(s->step());
    EXPECT_NEAR(bending_energy_at(*s, m, 0.3) / free_energy, 1 + ratio, 1e-6) << "ratio " << ratio;
  }
}

TEST(ClampedHinges, AnEdgeHeldWithoutAWholeWingIsNotClamped) {
  const Material cotton = linear_cotton();
  const Mesh m = one_hinge(1.0);
  auto s = Scene::create(m, cotton, still_options());
  ASSERT_TRUE(s->step());
  const double free_energy = bending_energy_at(*s, m, 0.3);
  s->pin({0, 1});  // the edge alone: both wings can still turn about it
  s->set_state(m.x, std::vector<Vec3>(m.x.size(), Vec3::Zero()));
  ASSERT_TRUE(s->step());
  EXPECT_NEAR(bending_energy_at(*s, m, 0.3) / free_energy, 1.0, 1e-12);
}

}  // namespace
}  // namespace gd::sim
