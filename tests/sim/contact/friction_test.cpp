#include "sim/contact/friction.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "sim/contact/distance.h"
#include "sim/fd_check.h"

namespace gd::sim {
namespace {

using V12 = VecN<12>;
using M12 = MatN<12>;
using Mat32 = Eigen::Matrix<Real, 3, 2>;

using test::stack4;

using test::seg;

void expect_frame_ok(const ContactFrictionFrame& f, const V12& x, Real dist) {
  EXPECT_NEAR(f.w.sum(), 0.0, 1e-14);
  EXPECT_NEAR(f.n.norm(), 1.0, 1e-14);
  EXPECT_TRUE(test::near_rel(Eigen::Matrix<Real, 2, 2>(f.T.transpose() * f.T),
                             Eigen::Matrix<Real, 2, 2>(Eigen::Matrix<Real, 2, 2>::Identity()), 1e-14));
  EXPECT_LT((f.T.transpose() * f.n).norm(), 1e-14);
  // Σ w_i x_i is the separation vector: length = distance, along n.
  Vec3 sep = Vec3::Zero();
  for (int i = 0; i < 4; ++i) sep += f.w[i] * seg(x, i);
  EXPECT_NEAR(sep.norm(), dist, 1e-12);
  if (dist > 1e-9) EXPECT_NEAR(sep.dot(f.n), dist, 1e-12);
}

TEST(ContactFriction, FramesFromPositions) {
  std::mt19937 rng(301);
  for (int it = 0; it < 100; ++it) {
    const V12 x = stack4(2 * test::random_vec3(rng), test::random_vec3(rng), test::random_vec3(rng),
                         test::random_vec3(rng));
    const Real dvf = std::sqrt(point_triangle_distance2(seg(x, 0), seg(x, 1), seg(x, 2), seg(x, 3), nullptr, nullptr));
    expect_frame_ok(vf_friction_frame(seg(x, 0), seg(x, 1), seg(x, 2), seg(x, 3)), x, dvf);
    const Real dee = std::sqrt(edge_edge_distance2(seg(x, 0), seg(x, 1), seg(x, 2), seg(x, 3), nullptr, nullptr));
    expect_frame_ok(ee_friction_frame(seg(x, 0), seg(x, 1), seg(x, 2), seg(x, 3)), x, dee);
  }
  // Touching point: the normal falls back to the triangle normal / edge cross product.
  const ContactFrictionFrame f =
      vf_friction_frame(Vec3(0.2, 0.2, 0), Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0));
  EXPECT_NEAR(std::abs(f.n.z()), 1.0, 1e-15);
  EXPECT_TRUE(test::near_rel(f.w, VecN<4>(1, -0.6, -0.2, -0.2), 1e-14));
  const ContactFrictionFrame e =
      ee_friction_frame(Vec3(-1, 0, 0), Vec3(1, 0, 0), Vec3(0, -1, 0), Vec3(0, 1, 0));
  EXPECT_NEAR(std::abs(e.n.z()), 1.0, 1e-15);
  EXPECT_TRUE(test::near_rel(e.w, VecN<4>(0.5, 0.5, -0.5, -0.5), 1e-14));
  // Touching parallel edges: some unit normal orthogonal to the edges.
  const ContactFrictionFrame p =
      ee_friction_frame(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0.5, 0, 0), Vec3(2, 0, 0));
  EXPECT_NEAR(p.n.norm(), 1.0, 1e-15);
  EXPECT_NEAR(p.n.x(), 0.0, 1e-15);
}

TEST(ContactFriction, GradientAndHessianMatchFiniteDifferences) {
  std::mt19937 rng(303);
  std::uniform_real_distribution<Real> u01(0, 1);
  int count = 0;
  for (int it = 0; it < 120; ++it) {
    // Step-start configuration of a pair about a cloth thickness apart, cm-sized elements.
    const Vec3 o = test::random_vec3(rng);
    const V12 geo = stack4(o + 0.01 * test::random_vec3(rng), o + 0.01 * test::random_vec3(rng),
                           o + 0.01 * test::random_vec3(rng), o + 0.01 * test::random_vec3(rng));
    const bool vf = it % 2 == 0;
    const ContactFrictionFrame f = vf ? vf_friction_frame(seg(geo, 0), seg(geo, 1), seg(geo, 2), seg(geo, 3))
                                      : ee_friction_frame(seg(geo, 0), seg(geo, 1), seg(geo, 2), seg(geo, 3));
    const Real h = 1e-2, eps = 1e-3 * h;
    const Real mu = 0.2 + 0.5 * u01(rng);
    const Real lambda = 1e-3 * (0.1 + u01(rng));
    // Vertex displacements over the step: slips from deep in the smoothing zone to well beyond.
    const Real slip = eps * std::pow(10.0, -2 + 3 * u01(rng));
    V12 dx, xt;
    for (int i = 0; i < 12; ++i) dx[i] = slip * (u01(rng) - 0.5);
    // The energy depends on x - x_t only; x_t of the order of the slip keeps the central
    // differences free of cancellation (the frame came from the cm-sized geometry above).
    for (int i = 0; i < 12; ++i) xt[i] = slip * (u01(rng) - 0.5);
    const V12 x = xt + dx;
    V12 g;
    M12 H;
    const Real E = contact_friction_energy(x, xt, f.w, f.T, mu, lambda, eps, &g, &H);
    EXPECT_GT(E, 0);
    auto fe = [&](const V12& y) { return contact_friction_energy(y, xt, f.w, f.T, mu, lambda, eps, nullptr, nullptr); };
    auto ge = [&](const V12& y) {
      V12 gg;
      contact_friction_energy(y, xt, f.w, f.T, mu, lambda, eps, &gg, nullptr);
      return gg;
    };
    Vec3 delta = Vec3::Zero();
    for (int i = 0; i < 4; ++i) delta += f.w[i] * seg(dx, i);
    const Real y = (f.T.transpose() * delta).norm();
    if (std::abs(y - eps) < 1e-3 * eps) continue;  // the C² kink of f0 at eps
    // E carries the constant mu lambda eps/3 at small slip: a relative step of 1e-4 keeps the
    // central difference well above its rounding (truncation error ~1e-8).
    const Real step = 1e-4 * std::min(y, std::abs(y - eps));
    EXPECT_TRUE(test::near_rel(g, test::fd_gradient<12>(fe, x, step), 1e-5)) << y / eps;
    EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<12, 12>(ge, x, step), 1e-4)) << y / eps;
    EXPECT_TRUE(test::is_psd(H));
    // Internal force: blocks sum to zero.
    EXPECT_LT((seg(g, 0) + seg(g, 1) + seg(g, 2) + seg(g, 3)).norm(), 1e-12 * g.norm() + 1e-30);
    ++count;
  }
  EXPECT_GE(count, 100);
}

TEST(ContactFriction, SlidingForceIsMuLambda) {
  std::mt19937 rng(307);
  std::uniform_real_distribution<Real> u01(0, 1);
  for (int it = 0; it < 40; ++it) {
    const Vec3 t0(0, 0, 0), t1(0.01, 0, 0), t2(0, 0.01, 0);
    const Vec3 p(0.003, 0.002, 3e-4);
    const ContactFrictionFrame f = vf_friction_frame(p, t0, t1, t2);
    const V12 xt = stack4(p, t0, t1, t2);
    const Real eps = 1e-5, mu = 0.4, lambda = 2e-3;
    // The vertex slides by 5 eps in-plane (plus a normal motion that friction ignores); the
    // triangle moves rigidly by a random in-plane amount too.
    const Vec3 slide = Vec3(u01(rng) - 0.5, u01(rng) - 0.5, 0).normalized() * (5 * eps);
    const Vec3 tri_move = Vec3(u01(rng) - 0.5, u01(rng) - 0.5, u01(rng) - 0.5) * eps;
    V12 x = xt;
    x.segment<3>(0) += slide + tri_move + Vec3(0, 0, 1e-5);
    for (int i = 1; i < 4; ++i) x.segment<3>(3 * i) += tri_move;
    V12 g;
    contact_friction_energy(x, xt, f.w, f.T, mu, lambda, eps, &g, nullptr);
    const Vec3 fp = -seg(g, 0);
    EXPECT_NEAR(fp.norm(), mu * lambda, 1e-12);
    EXPECT_NEAR(fp.dot(slide.normalized()), -mu * lambda, 1e-12);  // opposes the slip
    EXPECT_NEAR(fp.z(), 0.0, 1e-15);                                  // tangential only
    // Reaction on the triangle vertices: barycentric shares of the opposite force.
    EXPECT_LT((seg(g, 1) + seg(g, 2) + seg(g, 3) + seg(g, 0)).norm(), 1e-15);
  }
  // Edge-edge: the force on edge a has magnitude mu lambda when sliding.
  const Vec3 a0(-0.01, 0, 3e-4), a1(0.01, 0, 3e-4), b0(0, -0.01, 0), b1(0, 0.01, 0);
  const ContactFrictionFrame f = ee_friction_frame(a0, a1, b0, b1);
  const V12 xt = stack4(a0, a1, b0, b1);
  V12 x = xt;
  x.segment<3>(0) += Vec3(1e-3, 2e-3, 0);
  x.segment<3>(3) += Vec3(1e-3, 2e-3, 0);
  V12 g;
  contact_friction_energy(x, xt, f.w, f.T, 0.3, 1.0, 1e-5, &g, nullptr);
  EXPECT_NEAR((seg(g, 0) + seg(g, 1)).norm(), 0.3, 1e-12);
}

}  // namespace
}  // namespace gd::sim
