// Internal friction in bending (sim/energy/bending_friction.h): the incremental potential's
// derivatives, the slider's slip, and the moment-curvature loop of KES's pure bending test.
#include "sim/energy/bending_friction.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "sim/fd_check.h"

namespace gd::sim {
namespace friction_test {

using test::fd_gradient;
using test::fd_jacobian;
using test::fd_step;
using test::is_psd;
using test::near_rel;
using test::seg;
using test::stack4;

// A hinge of size L: edge (0,0,0)-(L,0,0), wing x2 in the xy plane, wing x3 turned by `fold`
// about the edge (θ = fold).
Vec12 hinge_at(Real L, Real fold) {
  const Vec3 x0(0, 0, 0), x1(L, 0, 0), x2(0.3 * L, 0.9 * L, 0);
  const Vec3 x3(0.6 * L, -1.1 * L * std::cos(fold), -1.1 * L * std::sin(fold));
  return stack4(x0, x1, x2, x3);
}

// Cotton-like rest data with internal friction: M = 2HB/2 for 2HB = 0.05 gf·cm/cm, the spring
// M / 20 m⁻¹.
HingeRest rest_with_friction(Real L) {
  HingeRest r;
  r.theta0 = 0;
  r.coef = hinge_rest_coef(Vec3(0, 0, 0), Vec3(L, 0, 0), Vec3(0.3 * L, 0.9 * L, 0), Vec3(0.6 * L, -1.1 * L, 0),
                           &r.area);
  r.stiffness = 2.8e-6;
  r.kappa_n = 0;  // linear bending
  r.friction_moment = 0.5 * 0.05 * 9.80665e-3;
  r.friction_stiffness = r.friction_moment / 20;
  return r;
}

Real theta_of(const Vec12& x) { return dihedral_angle(seg(x, 0), seg(x, 1), seg(x, 2), seg(x, 3)); }

Real friction_energy(const Vec12& y, const HingeRest& r, Real theta_f, Vec12* g, Mat12* H, HessianKind kind) {
  return bending_friction_energy(seg(y, 0), seg(y, 1), seg(y, 2), seg(y, 3), r, theta_f, g, H, kind);
}

// Random hinges; the slider placed so the spring sticks (|δ| < δy/2) or slips (|δ| > 2δy): away
// from the kink at |δ| = δy, where the potential is C¹ only.
TEST(BendingFriction, GradientAndHessianMatchFiniteDifferencesStickingAndSlipping) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<Real> u(-1, 1);
  int stick = 0, slip = 0;
  for (int it = 0; it < 40; ++it) {
    const Real L = 0.01 * (1 + 0.5 * u(rng));
    const HingeRest r = rest_with_friction(L);
    const Mat3 R = test::random_rotation(rng);
    Vec12 x = hinge_at(L, 1.2 * u(rng));
    for (int k = 0; k < 4; ++k) x.segment<3>(3 * k) = R * x.segment<3>(3 * k) + 0.1 * test::random_vec3(rng);
    const Real theta = theta_of(x);
    const Real dy = r.friction_moment / r.friction_stiffness;
    const bool sticks = it % 2 == 0;
    const Real delta = sticks ? 0.45 * dy * u(rng) : (2 + std::abs(u(rng))) * dy * (u(rng) < 0 ? -1 : 1);
    const Real theta_f = theta - delta / r.coef;
    auto f = [&](const Vec12& y) { return friction_energy(y, r, theta_f, nullptr, nullptr, HessianKind::kNone); };
    auto gf = [&](const Vec12& y) {
      Vec12 g;
      friction_energy(y, r, theta_f, &g, nullptr, HessianKind::kNone);
      return g;
    };
    Vec12 g;
    Mat12 He, Hp;
    const Real E = friction_energy(x, r, theta_f, &g, &He, HessianKind::kExact);
    friction_energy(x, r, theta_f, nullptr, &Hp, HessianKind::kProjected);
    // Value against the closed form.
    const Real k = r.friction_stiffness, M = r.friction_moment;
    const Real expected = sticks ? r.area * 0.5 * k * delta * delta : r.area * (M * std::abs(delta) - 0.5 * M * dy);
    EXPECT_NEAR(E, expected, 1e-9 * std::abs(expected)) << it;
    const Real h = fd_step(L);
    EXPECT_TRUE(near_rel(g, fd_gradient<12>(f, x, h), 1e-5)) << it;
    EXPECT_TRUE(near_rel(He, fd_jacobian<12, 12>(gf, x, h), 1e-5, 1e-12 * g.norm() / L)) << it;
    EXPECT_TRUE(is_psd(Hp)) << it;
    if (!sticks) EXPECT_EQ(Hp.norm(), 0.0) << "a slipping slider adds no stiffness";
    (sticks ? stick : slip)++;
  }
  EXPECT_EQ(stick, 20);
  EXPECT_EQ(slip, 20);
}

TEST(BendingFriction, NoFrictionMomentNoTerm) {
  HingeRest r = rest_with_friction(0.01);
  r.friction_moment = 0;
  Vec12 g;
  Mat12 H;
  EXPECT_EQ(friction_energy(hinge_at(0.01, 0.7), r, 0.0, &g, &H, HessianKind::kExact), 0.0);
  EXPECT_EQ(g.norm(), 0.0);
  EXPECT_EQ(H.norm(), 0.0);
  EXPECT_EQ(bending_friction_slip(r, 0.7, 0.1), 0.1);
}

// The slider slips only as far as leaves the spring at its limit, and the spring's moment then
// is the potential's slope (the step's implicit friction force).
TEST(BendingFriction, TheSliderSlipsToTheLimitMoment) {
  const HingeRest r = rest_with_friction(0.01);
  const Real dy = r.friction_moment / r.friction_stiffness;
  for (const Real delta : {0.3 * dy, -0.9 * dy, 1.5 * dy, -7 * dy}) {
    const Real theta = 0.4, theta_f = theta - delta / r.coef;
    const Real after = bending_friction_slip(r, theta, theta_f);
    const Real spring = r.friction_stiffness * r.coef * (theta - after);  // moment per unit length, N
    Real dE, d2E;
    detail::bending_friction_of_theta(r, theta, theta_f, &dE, &d2E);
    EXPECT_NEAR(spring, dE / (r.area * r.coef), 1e-12 * r.friction_moment) << delta / dy;
    if (std::abs(delta) <= dy) {
      EXPECT_EQ(after, theta_f);
    } else {
      EXPECT_NEAR(std::abs(spring), r.friction_moment, 1e-12 * r.friction_moment);
    }
  }
}

// KES-FB2's pure bending test on one hinge: curvature driven 0 -> +K -> -K -> +K in small
// increments, the slider slipping after each; the moment per unit length on the way up and on
// the way down at the same curvature differs by 2M = 2HB, and the branches' slope is the
// bending rigidity G.
TEST(BendingFriction, PureBendingLoopIsTwoHbWide) {
  const Real L = 0.01;
  const HingeRest r = rest_with_friction(L);
  const Real K = 250;  // 1/m (2.5 cm⁻¹, KES's turning curvature)
  const int n = 2000;
  std::vector<Real> path;
  for (int i = 0; i <= n; ++i) path.push_back(K * i / n);
  for (int i = 1; i <= 2 * n; ++i) path.push_back(K - K * i / n);
  for (int i = 1; i <= 2 * n; ++i) path.push_back(-K + K * i / n);
  Real theta_f = 0;
  auto moment_at = [&](Real kappa) {  // total moment per unit length at hinge curvature κ, N
    const Real theta = kappa / r.coef;
    Real dB, d2B, dF, d2F;
    detail::bending_of_theta(r, theta, &dB, &d2B);
    detail::bending_friction_of_theta(r, theta, theta_f, &dF, &d2F);
    const Real m = (dB + dF) / (r.area * r.coef);
    theta_f = bending_friction_slip(r, theta, theta_f);
    return m;
  };
  std::vector<Real> moments;
  for (const Real kappa : path) moments.push_back(moment_at(kappa));
  // At κ = ±0.5 and ±1.5 cm⁻¹ (KES reads 2HB there): the descending branch (second leg) against
  // the ascending one (third leg).
  auto at = [&](int leg_start, int leg_len, Real kappa) {
    for (int i = leg_start; i < leg_start + leg_len; ++i)
      if (std::abs(path[i] - kappa) < 0.5 * K / n) return moments[i];
    ADD_FAILURE() << "no sample at " << kappa;
    return Real(0);
  };
  for (const Real kappa : {-150.0, -50.0, 50.0, 150.0}) {
    const Real down = at(n + 1, 2 * n, kappa), up = at(3 * n + 1, 2 * n, kappa);
    EXPECT_NEAR(up - down, 2 * r.friction_moment, 1e-9 * r.friction_moment) << kappa;
    EXPECT_NEAR(0.5 * (up + down), r.stiffness * kappa, 1e-9 * r.stiffness * K) << kappa;
  }
}

}  // namespace friction_test
}  // namespace gd::sim
