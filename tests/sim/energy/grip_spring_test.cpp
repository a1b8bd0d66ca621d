#include "sim/energy/grip_spring.h"

#include <gtest/gtest.h>

#include <random>

#include "sim/fd_check.h"

namespace gd::sim {
namespace {

// Stiffness as the solver sets it for a held vertex: 30 x (m / h^2 + k_membrane).
constexpr Real kK = 3e4;

TEST(GripSpringEnergy, GradientAndHessianMatchFiniteDifferencesOnBothBranches) {
  std::mt19937 rng(7);
  for (const Real f_max : {Real(0.5), Real(5), Real(INFINITY)}) {
    for (int it = 0; it < 40; ++it) {
      const Vec3 target = Real(0.01) * test::random_vec3(rng);  // small: x - target keeps its digits
      // Offsets from 1e-6 m (inside any limit) to 1 cm (beyond 0.5 N / 3e4 N/m = 17 um).
      const Vec3 x = target + test::random_vec3(rng) * std::pow(Real(10), Real(-6 + it % 5));
      Vec3 g;
      Mat3 H;
      grip_spring_energy(x, target, kK, f_max, &g, &H);
      const Real h = Real(1e-4) * (x - target).norm();
      auto E = [&](const Vec3& y) { return grip_spring_energy(y, target, kK, f_max, nullptr, nullptr); };
      auto G = [&](const Vec3& y) {
        Vec3 gy;
        grip_spring_energy(y, target, kK, f_max, &gy, nullptr);
        return gy;
      };
      EXPECT_TRUE(test::near_rel(g, test::fd_gradient<3>(E, x, h), 1e-6));
      EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<3, 3>(G, x, h), 1e-5));
      EXPECT_TRUE(test::is_psd(H));
      EXPECT_LE(g.norm(), f_max * (1 + 1e-12));
      EXPECT_NEAR(g.norm(), grip_spring_force(x, target, kK, f_max), 1e-12 * g.norm());
    }
  }
}

TEST(GripSpringEnergy, PlainSpringInsideTheLimitConstantPullBeyond) {
  const Vec3 t(0.1, -0.2, 0.3);
  const Real f_max = 3;  // r0 = 1e-4 m
  Vec3 g;
  // 50 um: a plain spring, E = k r^2 / 2, pull k r = 1.5 N.
  EXPECT_NEAR(grip_spring_energy(t + Vec3(0, 0, 5e-5), t, kK, f_max, &g, nullptr), 0.5 * kK * 2.5e-9, 1e-15);
  EXPECT_NEAR(g.z(), 1.5, 1e-12);
  // 1 cm: pulls with exactly f_max, and the energy grows linearly (f_max per metre).
  const Real e1 = grip_spring_energy(t + Vec3(0.01, 0, 0), t, kK, f_max, &g, nullptr);
  const Real e2 = grip_spring_energy(t + Vec3(0.02, 0, 0), t, kK, f_max, nullptr, nullptr);
  EXPECT_NEAR(g.x(), f_max, 1e-12);
  EXPECT_NEAR(e2 - e1, f_max * 0.01, 1e-12);
  // Continuous at r0 from both sides.
  const Real r0 = f_max / kK;
  EXPECT_NEAR(grip_spring_energy(t + Vec3(r0 * (1 - 1e-9), 0, 0), t, kK, f_max, nullptr, nullptr),
              grip_spring_energy(t + Vec3(r0 * (1 + 1e-9), 0, 0), t, kK, f_max, nullptr, nullptr),
              2e-9 * r0 * f_max * 1.01);  // what the 2e-9 r0 step costs, no jump
  // Without a limit it is the plain spring at any distance.
  EXPECT_NEAR(grip_spring_energy(t + Vec3(0.01, 0, 0), t, kK, INFINITY, &g, nullptr), 0.5 * kK * 1e-4, 1e-12);
  EXPECT_NEAR(g.x(), kK * 0.01, 1e-9);
}

}  // namespace
}  // namespace gd::sim
