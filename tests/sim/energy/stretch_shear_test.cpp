#include "sim/energy/stretch_shear.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "sim/fd_check.h"

namespace gd::sim {
namespace stretch_shear_test {

using test::fd_gradient;
using test::fd_jacobian;
using test::fd_step;
using test::is_psd;
using test::kFabrics;
using test::near_rel;

struct Tri {
  Vec2 X[3];  // pattern coordinates, m
  StretchShearRest rest;
};

Tri make_rest(const Vec2& X0, const Vec2& X1, const Vec2& X2, Real k_warp, Real k_weft,
              Real k_shear) {
  Tri t{{X0, X1, X2}, {}};
  Mat2 Dm;
  Dm.col(0) = X1 - X0;
  Dm.col(1) = X2 - X0;
  t.rest.Dm_inv = Dm.inverse();
  t.rest.area = 0.5 * std::abs(Dm.determinant());
  t.rest.k_warp = k_warp;
  t.rest.k_weft = k_weft;
  t.rest.k_shear = k_shear;
  return t;
}

// A random, reasonably shaped pattern triangle of size ~L.
Tri random_rest(std::mt19937& rng, Real L, Real k_warp, Real k_weft, Real k_shear) {
  std::uniform_real_distribution<Real> u(-1, 1);
  for (;;) {
    Vec2 X0(u(rng), u(rng)), X1(u(rng), u(rng)), X2(u(rng), u(rng));
    X0 *= L;
    X1 *= L;
    X2 *= L;
    Mat2 Dm;
    Dm.col(0) = X1 - X0;
    Dm.col(1) = X2 - X0;
    if (std::abs(Dm.determinant()) > 0.3 * L * L) return make_rest(X0, X1, X2, k_warp, k_weft, k_shear);
  }
}

Vec3 embed(const Vec2& X) { return Vec3(X.x(), X.y(), 0); }

Vec9 stack(const Vec3& a, const Vec3& b, const Vec3& c) {
  Vec9 v;
  v << a, b, c;
  return v;
}

Real energy_of(const Vec9& x, const StretchShearRest& r) {
  return stretch_shear_energy(x.segment<3>(0), x.segment<3>(3), x.segment<3>(6), r, nullptr,
                              nullptr, HessianKind::kNone);
}
Vec9 grad_of(const Vec9& x, const StretchShearRest& r) {
  Vec9 g;
  stretch_shear_energy(x.segment<3>(0), x.segment<3>(3), x.segment<3>(6), r, &g, nullptr,
                       HessianKind::kNone);
  return g;
}

TEST(StretchShearEnergy, GradientAndHessianMatchFiniteDifferences) {
  std::mt19937 rng(1234);
  std::uniform_real_distribution<Real> u01(0, 1);
  int count = 0;
  for (const auto& fab : kFabrics) {
    for (int it = 0; it < 25; ++it) {
      const Real L = 0.005 + 0.05 * u01(rng);
      Tri t = random_rest(rng, L, fab.stretch, 0.6 * fab.stretch, 0.15 * fab.stretch);
      t.rest.compression_ratio = (it % 2 == 0) ? 1.0 : 0.05;  // symmetric and buckling models
      const Mat3 R = test::random_rotation(rng);
      const Vec3 T = 0.5 * test::random_vec3(rng);
      const Real amp = (it % 3 == 0) ? 0.05 : 0.4;  // mild and large (incl. compressed) states
      Vec9 x;
      for (int i = 0; i < 3; ++i)
        x.segment<3>(3 * i) = R * embed(t.X[i]) + T + amp * L * test::random_vec3(rng);
      Vec9 g;
      Mat9 He, Hp;
      const Real E = stretch_shear_energy(x.segment<3>(0), x.segment<3>(3), x.segment<3>(6),
                                          t.rest, &g, &He, HessianKind::kExact);
      const Real E2 = stretch_shear_energy(x.segment<3>(0), x.segment<3>(3), x.segment<3>(6),
                                           t.rest, nullptr, &Hp, HessianKind::kProjected);
      EXPECT_EQ(E, E2);
      EXPECT_GE(E, 0.0);
      const Real h = fd_step(L);
      auto f = [&](const Vec9& y) { return energy_of(y, t.rest); };
      auto gf = [&](const Vec9& y) { return grad_of(y, t.rest); };
      EXPECT_TRUE(near_rel(g, fd_gradient<9>(f, x, h), 1e-5)) << fab.name << " it " << it;
      EXPECT_TRUE(near_rel(He, fd_jacobian<9, 9>(gf, x, h), 1e-5)) << fab.name << " it " << it;
      EXPECT_TRUE(is_psd(Hp)) << fab.name << " it " << it;
      // Translation invariance: forces sum to zero; rotation invariance: no net torque.
      Vec3 fsum = Vec3::Zero(), torque = Vec3::Zero();
      for (int i = 0; i < 3; ++i) {
        fsum += g.segment<3>(3 * i);
        torque += x.segment<3>(3 * i).cross(g.segment<3>(3 * i));
      }
      EXPECT_LE(fsum.norm(), 1e-10 * g.norm());
      EXPECT_LE(torque.norm(), 1e-10 * g.norm() * (x.norm() + L));
      ++count;
    }
  }
  EXPECT_GE(count, 60);
}

// The solver sums the membrane terms in (w_u, w_v) space: stretch_shear_energy_w's derivatives
// there against finite differences, stretched, compressed and sheared.
TEST(StretchShearEnergy, DerivativesInDeformationSpaceMatchFiniteDifferences) {
  std::mt19937 rng(4321);
  for (const auto& fab : kFabrics) {
    for (int it = 0; it < 12; ++it) {
      Tri t = random_rest(rng, 0.02, fab.stretch, 0.6 * fab.stretch, 0.15 * fab.stretch);
      t.rest.compression_ratio = (it % 2 == 0) ? 1.0 : 0.05;
      VecN<6> w;
      const Real stretch[3] = {0.8, 1.15, 1.4};  // compressed and stretched, away from the kink at |w_u| = 1
      w.segment<3>(0) = stretch[it % 3] * test::random_vec3(rng).normalized();
      w.segment<3>(3) = 0.3 * w.segment<3>(0).cross(test::random_vec3(rng)) + 0.2 * test::random_vec3(rng);
      auto f = [&](const VecN<6>& y) {
        return stretch_shear_energy_w(y.segment<3>(0), y.segment<3>(3), t.rest, nullptr, nullptr, HessianKind::kNone);
      };
      auto gf = [&](const VecN<6>& y) {
        VecN<6> g;
        stretch_shear_energy_w(y.segment<3>(0), y.segment<3>(3), t.rest, &g, nullptr, HessianKind::kNone);
        return g;
      };
      VecN<6> g;
      MatN<6> He, Hp;
      stretch_shear_energy_w(w.segment<3>(0), w.segment<3>(3), t.rest, &g, &He, HessianKind::kExact);
      stretch_shear_energy_w(w.segment<3>(0), w.segment<3>(3), t.rest, nullptr, &Hp, HessianKind::kProjected);
      EXPECT_TRUE(near_rel(g, fd_gradient<6>(f, w, 1e-6), 1e-5)) << fab.name << " it " << it;
      EXPECT_TRUE(near_rel(He, fd_jacobian<6, 6>(gf, w, 1e-6), 1e-5)) << fab.name << " it " << it;
      EXPECT_TRUE(is_psd(Hp)) << fab.name << " it " << it;
    }
  }
}

TEST(StretchShearEnergy, ProjectedEqualsExactWhenStretchedAndUnsheared) {
  // |w| >= 1 in both directions and w_u . w_v = 0: the exact Hessian is already PSD.
  std::mt19937 rng(7);
  const Tri t = random_rest(rng, 0.02, 1000, 800, 100);
  const Mat3 R = test::random_rotation(rng);
  Mat9 He, Hp;
  Vec3 x[3];
  for (int i = 0; i < 3; ++i) x[i] = R * Vec3(1.2 * t.X[i].x(), 1.1 * t.X[i].y(), 0);
  stretch_shear_energy(x[0], x[1], x[2], t.rest, nullptr, &He, HessianKind::kExact);
  stretch_shear_energy(x[0], x[1], x[2], t.rest, nullptr, &Hp, HessianKind::kProjected);
  EXPECT_TRUE(near_rel(He, Hp, 1e-12));
  EXPECT_TRUE(is_psd(He));
}

TEST(StretchShearEnergy, ZeroAtRestAndUnderRigidMotion) {
  std::mt19937 rng(99);
  for (int it = 0; it < 20; ++it) {
    const Tri t = random_rest(rng, 0.03, 1000, 1000, 300);
    const Mat3 R = test::random_rotation(rng);
    const Vec3 T = test::random_vec3(rng);
    Vec9 g;
    Mat9 H;
    const Real E0 = stretch_shear_energy(embed(t.X[0]), embed(t.X[1]), embed(t.X[2]), t.rest, &g,
                                         nullptr, HessianKind::kNone);
    EXPECT_NEAR(E0, 0.0, 1e-20);
    EXPECT_LE(g.norm(), 1e-10);
    const Real E1 = stretch_shear_energy(R * embed(t.X[0]) + T, R * embed(t.X[1]) + T,
                                         R * embed(t.X[2]) + T, t.rest, &g, &H,
                                         HessianKind::kExact);
    EXPECT_NEAR(E1, 0.0, 1e-20);
    EXPECT_LE(g.norm(), 1e-10);
    // At rest the Hessian is PSD with exactly 6 zero modes (3 translations + 3 rotations).
    EXPECT_TRUE(is_psd(H));
    Eigen::SelfAdjointEigenSolver<Mat9> es(H);
    int zeros = 0;
    for (int i = 0; i < 9; ++i) zeros += es.eigenvalues()[i] < 1e-9 * H.norm();
    EXPECT_EQ(zeros, 6);
  }
}

TEST(StretchShearEnergy, UniaxialStretchGivesQuadraticEnergy) {
  std::mt19937 rng(5);
  for (const auto& fab : kFabrics) {
    const Real kw = fab.stretch, kf = 0.5 * fab.stretch, ks = 0.1 * fab.stretch;
    const Tri t = random_rest(rng, 0.02, kw, kf, ks);
    for (Real eps : {-0.05, 0.001, 0.01, 0.1, 0.3}) {
      Vec3 x[3], y[3];
      for (int i = 0; i < 3; ++i) {
        x[i] = Vec3((1 + eps) * t.X[i].x(), t.X[i].y(), 0);  // warp (pattern axis 0)
        y[i] = Vec3(t.X[i].x(), (1 + eps) * t.X[i].y(), 0);  // weft (pattern axis 1)
      }
      const Real Ew = stretch_shear_energy(x[0], x[1], x[2], t.rest, nullptr, nullptr, HessianKind::kNone);
      const Real Ef = stretch_shear_energy(y[0], y[1], y[2], t.rest, nullptr, nullptr, HessianKind::kNone);
      EXPECT_NEAR(Ew, t.rest.area * kw / 2 * eps * eps, 1e-9 * t.rest.area * kw * eps * eps);
      EXPECT_NEAR(Ef, t.rest.area * kf / 2 * eps * eps, 1e-9 * t.rest.area * kf * eps * eps);
      Real eu, ev, s;
      triangle_strains(x[0], x[1], x[2], t.rest.Dm_inv, &eu, &ev, &s);
      EXPECT_NEAR(eu, eps, 1e-12);
      EXPECT_NEAR(ev, 0, 1e-12);
      EXPECT_NEAR(s, 0, 1e-12);
    }
  }
}

TEST(StretchShearEnergy, CompressionUsesTheCompressionRatio) {
  // Uniaxial compression along warp or weft: E = area k ratio eps^2 / 2; stretch keeps k.
  std::mt19937 rng(11);
  const Real kw = 1000, kf = 600, ratio = 0.1;
  Tri t = random_rest(rng, 0.02, kw, kf, 100);
  t.rest.compression_ratio = ratio;
  for (Real eps : {-0.2, -0.05, -1e-3, 1e-3, 0.05}) {
    Vec3 x[3], y[3];
    for (int i = 0; i < 3; ++i) {
      x[i] = Vec3((1 + eps) * t.X[i].x(), t.X[i].y(), 0);
      y[i] = Vec3(t.X[i].x(), (1 + eps) * t.X[i].y(), 0);
    }
    const Real f = eps < 0 ? ratio : 1.0;
    const Real Ew = stretch_shear_energy(x[0], x[1], x[2], t.rest, nullptr, nullptr, HessianKind::kNone);
    const Real Ef = stretch_shear_energy(y[0], y[1], y[2], t.rest, nullptr, nullptr, HessianKind::kNone);
    EXPECT_NEAR(Ew, t.rest.area * kw * f / 2 * eps * eps, 1e-9 * t.rest.area * kw * eps * eps) << eps;
    EXPECT_NEAR(Ef, t.rest.area * kf * f / 2 * eps * eps, 1e-9 * t.rest.area * kf * eps * eps) << eps;
  }
  EXPECT_EQ(effective_stretch_stiffness(kw, 0.99, ratio), kw * ratio);
  EXPECT_EQ(effective_stretch_stiffness(kw, 1.0, ratio), kw);
}

TEST(StretchShearEnergy, CompressionRatioKeepsForcesContinuousAtRestLength) {
  // The two branches meet with zero force at |w| = 1: the force just below and just above the
  // rest length both tend to 0 (C1 energy), so Newton sees no jump in the gradient.
  const Tri base = make_rest(Vec2(0, 0), Vec2(0.02, 0), Vec2(0, 0.02), 1000, 1000, 100);
  for (Real ratio : {1.0, 0.3, 0.01}) {
    Tri t = base;
    t.rest.compression_ratio = ratio;
    Real prev = 0;
    for (Real eps : {-1e-4, -1e-6, 1e-6, 1e-4}) {
      Vec3 x[3];
      for (int i = 0; i < 3; ++i) x[i] = Vec3((1 + eps) * t.X[i].x(), t.X[i].y(), 0);
      Vec9 g;
      stretch_shear_energy(x[0], x[1], x[2], t.rest, &g, nullptr, HessianKind::kNone);
      const Real fx = g[3];  // force on x1 along warp (x1 = (0.02, 0))
      EXPECT_NEAR(fx, t.rest.area * 1000 * (eps < 0 ? ratio : 1.0) * eps / 0.02, 1e-9) << ratio << " " << eps;
      if (eps > 0) EXPECT_GT(fx, prev);  // monotone through 0
      prev = fx;
    }
  }
}

TEST(StretchShearEnergy, SimpleShear) {
  const Tri t = make_rest(Vec2(0, 0), Vec2(0.01, 0), Vec2(0, 0.01), 1000, 700, 50);
  for (Real gam : {0.01, 0.2}) {
    Vec3 x[3];
    for (int i = 0; i < 3; ++i) x[i] = Vec3(t.X[i].x() + gam * t.X[i].y(), t.X[i].y(), 0);
    Vec3 wu, wv;
    deformation_columns(x[0], x[1], x[2], t.rest.Dm_inv, &wu, &wv);
    EXPECT_TRUE(near_rel(wu, Vec3(1, 0, 0), 1e-12));
    EXPECT_TRUE(near_rel(wv, Vec3(gam, 1, 0), 1e-12));
    const Real dv = std::sqrt(1 + gam * gam) - 1;
    const Real expected = t.rest.area / 2 * (700 * dv * dv + 50 * gam * gam);
    EXPECT_NEAR(stretch_shear_energy(x[0], x[1], x[2], t.rest, nullptr, nullptr, HessianKind::kNone),
                expected, 1e-12 * expected);
    Real s;
    triangle_strains(x[0], x[1], x[2], t.rest.Dm_inv, nullptr, nullptr, &s);
    EXPECT_NEAR(s, gam, 1e-12);
  }
}

TEST(StretchShearEnergy, CollapsedTriangleIsFinite) {
  const Tri t = make_rest(Vec2(0, 0), Vec2(0.01, 0), Vec2(0, 0.01), 1000, 700, 50);
  const Vec3 p(0.1, 0.2, 0.3);
  Vec9 g;
  Mat9 H;
  for (HessianKind k : {HessianKind::kExact, HessianKind::kProjected}) {
    const Real E = stretch_shear_energy(p, p, p, t.rest, &g, &H, k);
    EXPECT_NEAR(E, t.rest.area / 2 * (1000 + 700), 1e-12);
    EXPECT_TRUE(g.allFinite());
    EXPECT_TRUE(H.allFinite());
  }
}

}  // namespace stretch_shear_test
}  // namespace gd::sim
