#include "sim/energy/table_barrier.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "sim/fd_check.h"

namespace gd::sim {
namespace {

TEST(TableBarrierEnergy, GradientAndHessianMatchFiniteDifferences) {
  std::mt19937 rng(31);
  std::uniform_real_distribution<Real> u01(0, 1);
  int count = 0;
  for (const auto& fab : test::kFabrics) {
    const Real dhat = 2 * fab.thickness;     // contact gap of the order of the cloth thickness
    const Real kappa = 1e2 * fab.stretch;    // N/m
    for (int it = 0; it < 20; ++it) {
      const Vec3 n = test::random_vec3(rng).normalized();
      const Real offset = 0.5 * u01(rng) - 0.25;
      const Real d = dhat * (0.001 + 0.99 * u01(rng));
      const Vec3 r = test::random_vec3(rng);
      const Vec3 x = (offset + d) * n + (r - n.dot(r) * n);
      const Real dd = n.dot(x) - offset;
      Vec3 g;
      Mat3 H;
      const Real E = plane_barrier_energy(x, n, offset, dhat, kappa, &g, &H);
      EXPECT_GT(E, 0);
      auto f = [&](const Vec3& y) { return plane_barrier_energy(y, n, offset, dhat, kappa, nullptr, nullptr); };
      auto gf = [&](const Vec3& y) {
        Vec3 gg;
        plane_barrier_energy(y, n, offset, dhat, kappa, &gg, nullptr);
        return gg;
      };
      const Real step = 1e-6 * dd;
      EXPECT_TRUE(test::near_rel(g, test::fd_gradient<3>(f, x, step), 1e-5)) << d / dhat;
      EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<3, 3>(gf, x, step), 1e-5)) << d / dhat;
      EXPECT_TRUE(test::is_psd(H));  // b'' >= 0: the exact Hessian is the projected one
      EXPECT_LT(g.dot(n), 0);        // energy decreases away from the table: pushes the vertex out
      EXPECT_NEAR(plane_barrier_force_magnitude(dd, dhat, kappa), -g.dot(n), 1e-10 * g.norm());
      ++count;
    }
  }
  EXPECT_GE(count, 60);
}

TEST(TableBarrierEnergy, InfiniteAtContactZeroBeyondDhat) {
  const Vec3 n(0, 0, 1);
  const Real dhat = 1e-3, kappa = 1e3;
  Vec3 g;
  Mat3 H;
  for (Real z : {-1.0, -1e-9, 0.0}) {
    const Real E = plane_barrier_energy(Vec3(0.3, 0.1, z), n, 0.0, dhat, kappa, &g, &H);
    EXPECT_TRUE(std::isinf(E) && E > 0) << z;
    EXPECT_TRUE(g.allFinite());
    EXPECT_TRUE(H.allFinite());
    EXPECT_TRUE(std::isinf(plane_barrier_force_magnitude(z, dhat, kappa)));
  }
  for (Real z : {dhat, 1.0001 * dhat, 0.5}) {
    EXPECT_EQ(plane_barrier_energy(Vec3(0.3, 0.1, z), n, 0.0, dhat, kappa, &g, &H), 0.0);
    EXPECT_EQ(g.norm(), 0.0);
    EXPECT_EQ(H.norm(), 0.0);
    EXPECT_EQ(plane_barrier_force_magnitude(z, dhat, kappa), 0.0);
  }
  // Positive and growing without bound as d -> 0; the offset shifts the plane.
  Real prev = 0;
  for (Real d : {0.9e-3, 0.5e-3, 1e-4, 1e-6, 1e-9}) {
    const Real E = plane_barrier_energy(Vec3(0, 0, 0.2 + d), n, 0.2, dhat, kappa, nullptr, nullptr);
    EXPECT_GT(E, prev);
    prev = E;
  }
  // Logarithmic blow-up: b(d) ~ kappa dhat² ln(dhat/d) as d -> 0.
  EXPECT_NEAR(prev / (kappa * dhat * dhat * std::log(dhat / 1e-9)), 1.0, 1e-5);
  // Closed form at d = dhat/2: -kappa (dhat/2)² ln(1/2).
  EXPECT_NEAR(plane_barrier_energy(Vec3(0, 0, 0.5e-3), n, 0.0, dhat, kappa, nullptr, nullptr),
              kappa * 0.25e-6 * std::log(2.0), 1e-15);
}

TEST(TableBarrierEnergy, SmoothAtDhat) {
  // b, b' and b'' all vanish as d -> dhat from below (C² activation).
  const Real dhat = 1e-3, kappa = 1e4;
  Real db, d2b;
  const Real d = dhat * (1 - 1e-6);
  const Real b = plane_barrier_function(d, dhat, kappa, &db, &d2b);
  EXPECT_LT(b, 1e-18);
  EXPECT_LT(std::abs(db), 1e-11 * kappa * dhat);  // O((1 - d/dhat)²)
  EXPECT_LT(std::abs(d2b), 1e-3 * kappa);
  EXPECT_GT(plane_barrier_force_magnitude(0.5 * dhat, dhat, kappa), 0);
}

}  // namespace
}  // namespace gd::sim
