#include "sim/energy/inertia.h"

#include <gtest/gtest.h>

#include <random>

#include "sim/fd_check.h"

namespace gd::sim {
namespace {

TEST(InertiaEnergy, GradientAndHessianMatchFiniteDifferences) {
  std::mt19937 rng(2);
  for (const auto& fab : test::kFabrics) {
    for (Real h : {1.0 / 60, 1e-3}) {
      for (int it = 0; it < 10; ++it) {
        const Real mass = fab.density * 2e-4;
        const Vec3 xhat = test::random_vec3(rng);
        const Vec3 x = xhat + 0.01 * test::random_vec3(rng);
        Vec3 grad;
        Mat3 H;
        const Real E = inertia_energy(x, xhat, mass, h, &grad, &H);
        EXPECT_NEAR(E, mass / (2 * h * h) * (x - xhat).squaredNorm(), 1e-12 * E);
        auto f = [&](const Vec3& y) { return inertia_energy(y, xhat, mass, h, nullptr, nullptr); };
        auto gf = [&](const Vec3& y) {
          Vec3 g;
          inertia_energy(y, xhat, mass, h, &g, nullptr);
          return g;
        };
        const Real step = test::fd_step(0.01);
        EXPECT_TRUE(test::near_rel(grad, test::fd_gradient<3>(f, x, step), 1e-6));
        EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<3, 3>(gf, x, step), 1e-6));
        EXPECT_TRUE(test::near_rel(H, Mat3(mass / (h * h) * Mat3::Identity()), 1e-15));
        EXPECT_TRUE(test::is_psd(H));
      }
    }
  }
}

TEST(InertiaEnergy, MinimizerIsPrediction) {
  // Without other forces the implicit-Euler step lands on x_hat: zero gradient there.
  Vec3 g;
  EXPECT_EQ(inertia_energy(Vec3(1, 2, 3), Vec3(1, 2, 3), 0.01, 0.01, &g, nullptr), 0.0);
  EXPECT_EQ(g.norm(), 0.0);
}

}  // namespace
}  // namespace gd::sim
