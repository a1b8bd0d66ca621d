#include "sim/energy/drag.h"

#include <gtest/gtest.h>

#include <random>

#include "sim/fd_check.h"

namespace gd::sim {
namespace drag_test {

Vec9 stack(const Vec3& a, const Vec3& b, const Vec3& c) {
  Vec9 v;
  v << a, b, c;
  return v;
}

TEST(DragEnergy, GradientAndHessianMatchFiniteDifferences) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<Real> u01(0, 1);
  int count = 0;
  for (const auto& fab : test::kFabrics) {
    for (int it = 0; it < 20; ++it) {
      const Real L = 0.01 + 0.02 * u01(rng);
      const Vec3 p0 = test::random_vec3(rng);
      const Vec3 p1 = p0 + L * test::random_vec3(rng), p2 = p0 + L * test::random_vec3(rng);
      const Vec3 n = (p1 - p0).cross(p2 - p0).normalized();
      const Real area = 0.5 * (p1 - p0).cross(p2 - p0).norm();
      const Real h = (it % 2) ? 1.0 / 60 : 1e-3;
      const Vec3 v = 2 * test::random_vec3(rng);  // m/s
      const Real cn = drag_normal_coefficient(1.2, 1.2, std::abs(v.dot(n)), 0.01 * fab.density);
      const Real ct = 0.02 * cn;
      const Vec3 cprev = (p0 + p1 + p2) / 3;
      Vec9 x = stack(p0, p1, p2);
      for (int i = 0; i < 3; ++i) x.segment<3>(3 * i) += h * (v + 0.2 * test::random_vec3(rng));
      auto f = [&](const Vec9& y) {
        return drag_energy(y.segment<3>(0), y.segment<3>(3), y.segment<3>(6), cprev, n, area, cn, ct,
                           h, nullptr, nullptr);
      };
      auto gf = [&](const Vec9& y) {
        Vec9 g;
        drag_energy(y.segment<3>(0), y.segment<3>(3), y.segment<3>(6), cprev, n, area, cn, ct, h, &g,
                    nullptr);
        return g;
      };
      Vec9 g;
      Mat9 H;
      const Real E = drag_energy(x.segment<3>(0), x.segment<3>(3), x.segment<3>(6), cprev, n, area,
                                 cn, ct, h, &g, &H);
      EXPECT_GE(E, 0);
      const Real step = test::fd_step(L);
      EXPECT_TRUE(test::near_rel(g, test::fd_gradient<9>(f, x, step), 1e-5));
      EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<9, 9>(gf, x, step), 1e-5));
      EXPECT_TRUE(test::is_psd(H));  // constant PSD: exact = projected
      ++count;
    }
  }
  EXPECT_GE(count, 60);
}

TEST(DragEnergy, ForceOpposesVelocity) {
  // A triangle translating with velocity v feels -area (c_n v_n + c_t v_t), a third per vertex.
  const Vec3 p0(0, 0, 0), p1(0.02, 0, 0), p2(0, 0.02, 0);
  const Vec3 n(0, 0, 1);
  const Real area = 2e-4, h = 0.01;
  const Vec3 v(0.3, -0.2, -1.5);
  const Real cn = drag_normal_coefficient(1.2, 1.0, 1.5, 0.0);
  EXPECT_NEAR(cn, 0.5 * 1.2 * 1.0 * 1.5, 1e-15);
  const Real ct = 0.05;
  const Vec3 c = (p0 + p1 + p2) / 3;
  Vec9 g;
  const Real E = drag_energy(p0 + h * v, p1 + h * v, p2 + h * v, c, n, area, cn, ct, h, &g, nullptr);
  const Vec3 expected_force = -area * (cn * Vec3(0, 0, v.z()) + ct * Vec3(v.x(), v.y(), 0));
  for (int i = 0; i < 3; ++i)
    EXPECT_TRUE(test::near_rel(Vec3(-g.segment<3>(3 * i)), Vec3(expected_force / 3), 1e-12));
  // Dissipation potential: E = h/2 * (power dissipated) = h/2 * area (c_n v_n² + c_t v_t²).
  EXPECT_NEAR(E, h / 2 * area * (cn * v.z() * v.z() + ct * (v.x() * v.x() + v.y() * v.y())), 1e-15);
  // Resting triangle: no drag.
  EXPECT_EQ(drag_energy(p0, p1, p2, c, n, area, cn, ct, h, &g, nullptr), 0.0);
  EXPECT_EQ(g.norm(), 0.0);
}

}  // namespace drag_test
}  // namespace gd::sim
