#include "sim/energy/damping.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "sim/fd_check.h"

namespace gd::sim {
namespace {

StretchShearRest make_rest(const Vec2& X0, const Vec2& X1, const Vec2& X2, Real kw, Real kf, Real ks) {
  StretchShearRest r;
  Mat2 Dm;
  Dm.col(0) = X1 - X0;
  Dm.col(1) = X2 - X0;
  r.Dm_inv = Dm.inverse();
  r.area = 0.5 * std::abs(Dm.determinant());
  r.k_warp = kw;
  r.k_weft = kf;
  r.k_shear = ks;
  return r;
}

struct MembraneCase {
  StretchShearRest rest;
  Vec3 X[3];  // rest positions embedded at z = 0
};

MembraneCase random_membrane(std::mt19937& rng, Real L, Real k) {
  std::uniform_real_distribution<Real> u(-1, 1);
  for (;;) {
    const Vec2 X0(L * u(rng), L * u(rng)), X1(L * u(rng), L * u(rng)), X2(L * u(rng), L * u(rng));
    Mat2 Dm;
    Dm.col(0) = X1 - X0;
    Dm.col(1) = X2 - X0;
    if (std::abs(Dm.determinant()) < 0.3 * L * L) continue;
    MembraneCase c{make_rest(X0, X1, X2, k, 0.6 * k, 0.1 * k), {}};
    c.X[0] = Vec3(X0.x(), X0.y(), 0);
    c.X[1] = Vec3(X1.x(), X1.y(), 0);
    c.X[2] = Vec3(X2.x(), X2.y(), 0);
    return c;
  }
}

Real membrane_of(const Vec9& y, const Vec3& wu, const Vec3& wv, const StretchShearRest& r, Real beta,
                 Real h, Vec9* g = nullptr, Mat9* H = nullptr) {
  return membrane_damping_energy(y.segment<3>(0), y.segment<3>(3), y.segment<3>(6), wu, wv, r, beta,
                                 h, g, H);
}

TEST(DampingEnergy, MembraneGradientAndHessianMatchFiniteDifferences) {
  std::mt19937 rng(17);
  int count = 0;
  for (const auto& fab : test::kFabrics) {
    for (int it = 0; it < 20; ++it) {
      const Real L = 0.02;
      const MembraneCase c = random_membrane(rng, L, fab.stretch);
      const Mat3 R = test::random_rotation(rng);
      Vec9 xt, x;
      for (int i = 0; i < 3; ++i) {
        xt.segment<3>(3 * i) = R * c.X[i] + 0.2 * L * test::random_vec3(rng);
        x.segment<3>(3 * i) = xt.segment<3>(3 * i) + 0.05 * L * test::random_vec3(rng);
      }
      Vec3 wu, wv;
      deformation_columns(xt.segment<3>(0), xt.segment<3>(3), xt.segment<3>(6), c.rest.Dm_inv, &wu, &wv);
      const Real beta = 2e-3, h = (it % 2) ? 1.0 / 60 : 1e-3;
      Vec9 g;
      Mat9 H;
      const Real E = membrane_of(x, wu, wv, c.rest, beta, h, &g, &H);
      EXPECT_GT(E, 0);
      auto f = [&](const Vec9& y) { return membrane_of(y, wu, wv, c.rest, beta, h); };
      auto gf = [&](const Vec9& y) {
        Vec9 gg;
        membrane_of(y, wu, wv, c.rest, beta, h, &gg);
        return gg;
      };
      const Real step = test::fd_step(L);
      EXPECT_TRUE(test::near_rel(g, test::fd_gradient<9>(f, x, step), 1e-5)) << fab.name << it;
      EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<9, 9>(gf, x, step), 1e-5)) << fab.name << it;
      EXPECT_TRUE(test::is_psd(H));
      Vec3 fsum = Vec3::Zero();
      for (int i = 0; i < 3; ++i) fsum += g.segment<3>(3 * i);
      EXPECT_LE(fsum.norm(), 1e-11 * g.norm());
      // No dissipation without motion, nor for a rigid translation over the step.
      Vec9 g0;
      EXPECT_EQ(membrane_of(xt, wu, wv, c.rest, beta, h, &g0), 0.0);
      EXPECT_EQ(g0.norm(), 0.0);
      Vec9 xtr = xt;
      const Vec3 T = 0.01 * test::random_vec3(rng);
      for (int i = 0; i < 3; ++i) xtr.segment<3>(3 * i) += T;
      EXPECT_LE(membrane_of(xtr, wu, wv, c.rest, beta, h), 1e-24 * fab.stretch);
      // An infinitesimal rigid rotation is undamped to first order: its damping energy is
      // O(angle^4), far below that of a deformation of the same size.
      const Real ang = 1e-4;
      const Mat3 Rs = Eigen::AngleAxis<Real>(ang, test::random_vec3(rng).normalized()).toRotationMatrix();
      Vec9 xrot, xdef;
      const Vec3 ctr = (xt.segment<3>(0) + xt.segment<3>(3) + xt.segment<3>(6)) / 3;
      for (int i = 0; i < 3; ++i) {
        xrot.segment<3>(3 * i) = ctr + Rs * (xt.segment<3>(3 * i) - ctr);
        xdef.segment<3>(3 * i) = xt.segment<3>(3 * i) + ang * L * test::random_vec3(rng);
      }
      EXPECT_LT(membrane_of(xrot, wu, wv, c.rest, beta, h),
                1e-4 * membrane_of(xdef, wu, wv, c.rest, beta, h));
      ++count;
    }
  }
  EXPECT_GE(count, 60);
}

// The solver sums the membrane terms in (w_u, w_v) space: membrane_damping_energy_w's derivatives
// there against finite differences.
TEST(DampingEnergy, MembraneDerivativesInDeformationSpaceMatchFiniteDifferences) {
  std::mt19937 rng(29);
  for (const auto& fab : test::kFabrics) {
    for (int it = 0; it < 10; ++it) {
      const MembraneCase c = random_membrane(rng, 0.02, fab.stretch);
      VecN<6> w, wt;
      for (int k = 0; k < 2; ++k) {
        wt.segment<3>(3 * k) = test::random_vec3(rng);
        w.segment<3>(3 * k) = wt.segment<3>(3 * k) + 0.1 * test::random_vec3(rng);
      }
      const Real beta = 3e-3, h = 5e-3;
      auto f = [&](const VecN<6>& y) {
        return membrane_damping_energy_w(y.segment<3>(0), y.segment<3>(3), wt.segment<3>(0), wt.segment<3>(3), c.rest,
                                         beta, h, nullptr, nullptr);
      };
      auto gf = [&](const VecN<6>& y) {
        VecN<6> g;
        membrane_damping_energy_w(y.segment<3>(0), y.segment<3>(3), wt.segment<3>(0), wt.segment<3>(3), c.rest, beta,
                                  h, &g, nullptr);
        return g;
      };
      VecN<6> g;
      MatN<6> H;
      membrane_damping_energy_w(w.segment<3>(0), w.segment<3>(3), wt.segment<3>(0), wt.segment<3>(3), c.rest, beta, h,
                                &g, &H);
      EXPECT_TRUE(test::near_rel(g, test::fd_gradient<6>(f, w, 1e-6), 1e-5)) << fab.name << " " << it;
      EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<6, 6>(gf, w, 1e-6), 1e-5)) << fab.name << " " << it;
      EXPECT_TRUE(test::is_psd(H));
    }
  }
}

TEST(DampingEnergy, MembraneHessianIsBetaOverHTimesStiffnessAtRest) {
  // Stiffness-proportional damping: at an undeformed state x^t, the damping Hessian is
  // beta/h times the (projected) membrane stiffness.
  std::mt19937 rng(5);
  for (const auto& fab : test::kFabrics) {
    const MembraneCase c = random_membrane(rng, 0.01, fab.stretch);
    const Mat3 R = test::random_rotation(rng);
    Vec3 x[3];
    for (int i = 0; i < 3; ++i) x[i] = R * c.X[i] + Vec3(0.1, 0.2, 0.3);
    Vec3 wu, wv;
    deformation_columns(x[0], x[1], x[2], c.rest.Dm_inv, &wu, &wv);
    const Real beta = 1e-3, h = 1e-2;
    Mat9 Hd, Hs;
    membrane_damping_energy(x[0], x[1], x[2], wu, wv, c.rest, beta, h, nullptr, &Hd);
    stretch_shear_energy(x[0], x[1], x[2], c.rest, nullptr, &Hs, HessianKind::kProjected);
    EXPECT_TRUE(test::near_rel(Hd, Mat9(beta / h * Hs), 1e-10));
  }
}

Vec12 random_damping_hinge(std::mt19937& rng, Real L) {
  std::uniform_real_distribution<Real> u(-1, 1);
  const Real fold = 2.0 * u(rng);
  Vec12 x;
  x << Vec3(0, 0, 0), Vec3(L, 0, 0), Vec3(L * (0.5 + 0.4 * u(rng)), L * (1 + 0.3 * u(rng)), 0),
      Vec3(L * (0.5 + 0.4 * u(rng)), -L * std::cos(fold), -L * std::sin(fold));
  const Mat3 R = test::random_rotation(rng);
  const Vec3 T = test::random_vec3(rng);
  for (int i = 0; i < 4; ++i) x.segment<3>(3 * i) = R * x.segment<3>(3 * i) + T;
  return x;
}

TEST(DampingEnergy, BendingGradientAndHessianMatchFiniteDifferences) {
  std::mt19937 rng(23);
  int count = 0;
  for (const auto& fab : test::kFabrics) {
    for (int it = 0; it < 20; ++it) {
      const Real L = 0.01;
      const Vec12 xt = random_damping_hinge(rng, L);
      Vec12 x = xt;
      for (int i = 0; i < 12; ++i) x[i] += 0.05 * L * test::random_vec3(rng)[0];
      Vec12 gth;
      const Real th_t = dihedral_angle_derivatives(xt.segment<3>(0), xt.segment<3>(3), xt.segment<3>(6),
                                                   xt.segment<3>(9), &gth, nullptr);
      HingeRest r{0.0, 0.0, 0.0, fab.bending, 0.0};
      r.coef = hinge_rest_coef(Vec2(0, 0), Vec2(L, 0), Vec2(0.5 * L, L), Vec2(0.5 * L, -L), &r.area);
      const Real beta = 5e-3, h = (it % 2) ? 1.0 / 60 : 1e-3;
      Vec12 g;
      Mat12 H;
      const Real E = bending_damping_energy(x, xt, gth, r, beta, h, &g, &H);
      auto f = [&](const Vec12& y) { return bending_damping_energy(y, xt, gth, r, beta, h, nullptr, nullptr); };
      auto gf = [&](const Vec12& y) {
        Vec12 gg;
        bending_damping_energy(y, xt, gth, r, beta, h, &gg, nullptr);
        return gg;
      };
      const Real step = test::fd_step(L);
      EXPECT_TRUE(test::near_rel(g, test::fd_gradient<12>(f, x, step), 1e-5));
      EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<12, 12>(gf, x, step), 1e-5));
      EXPECT_TRUE(test::is_psd(H));
      Vec3 fsum = Vec3::Zero();
      for (int i = 0; i < 4; ++i) fsum += g.segment<3>(3 * i);
      EXPECT_LE(fsum.norm(), 1e-11 * g.norm());
      // For a small motion, E ≈ beta/(2h) area G coef² (Δθ)².
      const Vec12 xs = xt + 1e-6 * (x - xt);
      const Real dth = dihedral_angle(xs.segment<3>(0), xs.segment<3>(3), xs.segment<3>(6), xs.segment<3>(9)) - th_t;
      const Real Es = bending_damping_energy(xs, xt, gth, r, beta, h, nullptr, nullptr);
      EXPECT_NEAR(Es, beta / (2 * h) * r.area * fab.bending * r.coef * r.coef * dth * dth, 1e-3 * Es);
      EXPECT_GE(E, 0);
      EXPECT_EQ(bending_damping_energy(xt, xt, gth, r, beta, h, nullptr, nullptr), 0.0);
      // The factored form the solver assembles: H = bending_damping_coef ∇θ^t ∇θ^tᵀ.
      const Mat12 Hf = bending_damping_coef(r, beta, h) * gth * gth.transpose();
      EXPECT_TRUE(test::near_rel(H, Hf, 1e-14));
      ++count;
    }
  }
  EXPECT_GE(count, 60);
}

}  // namespace
}  // namespace gd::sim
