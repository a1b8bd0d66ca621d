#include "sim/energy/table_friction.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "sim/fd_check.h"

namespace gd::sim {
namespace {

using Mat32 = Eigen::Matrix<Real, 3, 2>;

TEST(TableFrictionEnergy, TangentBasisIsOrthonormal) {
  std::mt19937 rng(41);
  for (int it = 0; it < 50; ++it) {
    Vec3 n = test::random_vec3(rng).normalized();
    if (it == 0) n = Vec3(1, 0, 0);
    if (it == 1) n = Vec3(0, 0, 1);
    if (it == 2) n = Vec3(0, -1, 0);
    Mat32 T;
    plane_tangent_basis(n, &T);
    EXPECT_TRUE(test::near_rel(Eigen::Matrix<Real, 2, 2>(T.transpose() * T),
                               Eigen::Matrix<Real, 2, 2>(Eigen::Matrix<Real, 2, 2>::Identity()), 1e-14));
    EXPECT_LT((T.transpose() * n).norm(), 1e-14);
    EXPECT_NEAR(T.col(0).cross(T.col(1)).dot(n), 1.0, 1e-14);  // right-handed (t1, t2, n)
  }
}

TEST(TableFrictionEnergy, GradientAndHessianMatchFiniteDifferences) {
  std::mt19937 rng(43);
  std::uniform_real_distribution<Real> u01(0, 1);
  int count = 0;
  for (const auto& fab : test::kFabrics) {
    for (int it = 0; it < 24; ++it) {
      const Vec3 n = test::random_vec3(rng).normalized();
      Mat32 T;
      plane_tangent_basis(n, &T);
      const Real h = 1e-2, eps = 1e-3 * h;  // eps_v = 1 mm/s
      const Real mu = 0.3 + 0.4 * u01(rng);
      const Real lambda = fab.density * 1e-4 * kGravity;  // weight of about a cm² of cloth, N
      // Slip from well inside the smoothing zone to well beyond it, plus a normal component.
      const Real slip = eps * std::pow(10.0, -2 + 3 * u01(rng));
      const Vec2 dir = Vec2(u01(rng) - 0.5, u01(rng) - 0.5).normalized();
      // x_t of the order of the slip keeps the central differences free of cancellation.
      const Vec3 xt = slip * test::random_vec3(rng);
      const Vec3 x = xt + T * (slip * dir) + slip * u01(rng) * n;
      Vec3 g;
      Mat3 H;
      const Real E = plane_friction_energy(x, xt, T, mu, lambda, eps, &g, &H);
      EXPECT_GT(E, 0);
      auto f = [&](const Vec3& y) { return plane_friction_energy(y, xt, T, mu, lambda, eps, nullptr, nullptr); };
      auto gf = [&](const Vec3& y) {
        Vec3 gg;
        plane_friction_energy(y, xt, T, mu, lambda, eps, &gg, nullptr);
        return gg;
      };
      const Real step = 1e-6 * std::min(slip, std::abs(slip - eps) + 1e-3 * eps);  // stay on one branch
      EXPECT_TRUE(test::near_rel(g, test::fd_gradient<3>(f, x, step), 1e-5)) << slip / eps;
      EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<3, 3>(gf, x, step), 1e-5)) << slip / eps;
      EXPECT_TRUE(test::is_psd(H));
      EXPECT_LT(std::abs(g.dot(n)), 1e-12 * g.norm() + 1e-30);  // purely tangential
      EXPECT_LE(g.norm(), mu * lambda * (1 + 1e-12));            // never exceeds the Coulomb bound
      ++count;
    }
  }
  EXPECT_GE(count, 60);
}

TEST(TableFrictionEnergy, SlidingForceIsMuLambda) {
  const Vec3 n(0, 0, 1);
  Mat32 T;
  plane_tangent_basis(n, &T);
  const Real mu = 0.5, lambda = 2.0, eps = 1e-5;
  const Vec3 xt(0.1, 0.2, 0.001);
  for (Real slip : {1.0001 * eps, 2 * eps, 1e-3, 0.1}) {
    const Vec3 d = Vec3(0.6, -0.8, 0) * slip;
    Vec3 g;
    const Real E = plane_friction_energy(xt + d, xt, T, mu, lambda, eps, &g, nullptr);
    EXPECT_NEAR(g.norm(), mu * lambda, 1e-12);
    EXPECT_TRUE(test::near_rel(Vec3(-g), Vec3(-mu * lambda * d.normalized()), 1e-12));  // opposes slip
    EXPECT_NEAR(E, mu * lambda * slip, 1e-12 * E);
  }
  // Inside the smoothing zone the force grows from 0 (static-like) to mu lambda at eps.
  Vec3 g0, g1;
  Mat3 H0;
  plane_friction_energy(xt, xt, T, mu, lambda, eps, &g0, &H0);
  EXPECT_EQ(g0.norm(), 0.0);
  EXPECT_TRUE(test::near_rel(H0, Mat3(mu * lambda * 2 / eps * T * T.transpose()), 1e-14));
  plane_friction_energy(xt + Vec3(0.5 * eps, 0, 0), xt, T, mu, lambda, eps, &g1, nullptr);
  EXPECT_NEAR(g1.norm(), mu * lambda * 0.75, 1e-12);  // f1(eps/2) = -1/4 + 1 = 3/4
  // Pure normal motion: no friction.
  plane_friction_energy(xt + Vec3(0, 0, 0.01), xt, T, mu, lambda, eps, &g1, nullptr);
  EXPECT_EQ(g1.norm(), 0.0);
  // The potential is C¹ at eps: value and force continuous.
  const Real Ein = plane_friction_energy(xt + Vec3(eps * (1 - 1e-9), 0, 0), xt, T, mu, lambda, eps, nullptr, nullptr);
  const Real Eout = plane_friction_energy(xt + Vec3(eps * (1 + 1e-9), 0, 0), xt, T, mu, lambda, eps, nullptr, nullptr);
  EXPECT_NEAR(Ein, Eout, 1.01 * mu * lambda * 2e-9 * eps);  // slope mu lambda times the gap
}

}  // namespace
}  // namespace gd::sim
