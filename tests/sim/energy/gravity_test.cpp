#include "sim/energy/gravity.h"

#include <gtest/gtest.h>

#include <random>

#include "sim/fd_check.h"

namespace gd::sim {
namespace {

TEST(GravityEnergy, ValueGradientAndForce) {
  std::mt19937 rng(1);
  for (const auto& fab : test::kFabrics) {
    for (int it = 0; it < 20; ++it) {
      const Real mass = fab.density * 1e-4 * (1 + it);  // vertex share of a few cm² of cloth
      const Vec3 g = (it % 2) ? Vec3(0, 0, -kGravity) : Vec3(test::random_vec3(rng) * kGravity);
      const Vec3 x = test::random_vec3(rng);
      Vec3 grad;
      const Real E = gravity_energy(x, mass, g, &grad);
      EXPECT_NEAR(E, -mass * g.dot(x), 1e-15);
      auto f = [&](const Vec3& y) { return gravity_energy(y, mass, g, nullptr); };
      EXPECT_TRUE(test::near_rel(grad, test::fd_gradient<3>(f, x, 1e-6), 1e-8));
      EXPECT_TRUE(test::near_rel(Vec3(-grad), Vec3(mass * g), 1e-15));  // force = m g
    }
  }
  // Raising a 1 kg mass by 1 m against standard gravity costs kGravity joules.
  EXPECT_NEAR(gravity_energy(Vec3(0, 0, 1), 1.0, Vec3(0, 0, -kGravity), nullptr) -
                  gravity_energy(Vec3(0, 0, 0), 1.0, Vec3(0, 0, -kGravity), nullptr),
              kGravity, 1e-12);
}

}  // namespace
}  // namespace gd::sim
