#include "sim/contact/ccd.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "sim/contact/distance.h"
#include "sim/fd_check.h"

namespace gd::sim {
namespace {

TEST(ContactCcd, ConservativeStepBound) {
  EXPECT_EQ(conservative_step_bound(1e-3, 0.0), 1.0);
  EXPECT_EQ(conservative_step_bound(1e-3, 1e-4), 1.0);
  EXPECT_NEAR(conservative_step_bound(1e-3, 1e-2), 0.09, 1e-15);
  EXPECT_NEAR(conservative_step_bound(1e-3, 1e-2, 0.5), 0.05, 1e-15);
  EXPECT_EQ(conservative_step_bound(0.0, 1e-2), 0.0);
  EXPECT_EQ(conservative_step_bound(-1e-4, 1e-2), 0.0);
}

struct Motion {
  Vec3 x[4], dx[4];
};

Real gap_at(const Motion& m, Real a, Real offset, bool vf) {
  Vec3 y[4];
  for (int i = 0; i < 4; ++i) y[i] = m.x[i] + a * m.dx[i];
  const Real d2 = vf ? point_triangle_distance2(y[0], y[1], y[2], y[3], nullptr, nullptr)
                     : edge_edge_distance2(y[0], y[1], y[2], y[3], nullptr, nullptr);
  return std::sqrt(d2) - offset;
}

Real ccd(const Motion& m, Real offset, bool vf, Real s = kCcdGapFraction) {
  return vf ? point_triangle_ccd(m.x[0], m.x[1], m.x[2], m.x[3], m.dx[0], m.dx[1], m.dx[2], m.dx[3], offset, s)
            : edge_edge_ccd(m.x[0], m.x[1], m.x[2], m.x[3], m.dx[0], m.dx[1], m.dx[2], m.dx[3], offset, s);
}

TEST(ContactCcd, RandomMotionsNeverCloserThanOffset) {
  std::mt19937 rng(501);
  std::uniform_real_distribution<Real> u01(0, 1);
  const Real offset = 2.6e-4;  // cotton thickness
  int limited = 0, total = 0;
  for (int it = 0; it < 400; ++it) {
    const bool vf = it % 2 == 0;
    // cm-sized primitives about a few mm apart, moving by up to a few cm (often through each
    // other), with random rotation and translation components.
    Motion m;
    const Vec3 c = 0.1 * test::random_vec3(rng);
    for (int i = 0; i < 4; ++i) m.x[i] = c + 0.01 * test::random_vec3(rng);
    const Vec3 sep = 0.003 * test::random_vec3(rng);
    m.x[0] += sep;
    if (!vf) m.x[1] += sep;
    const Vec3 common = 0.05 * test::random_vec3(rng);
    const Real scale = 0.03 * std::pow(10.0, -2 * u01(rng));
    for (int i = 0; i < 4; ++i) m.dx[i] = common + scale * test::random_vec3(rng);
    if (it % 5 == 0) {  // head-on: push the first primitive through the second
      const Vec3 target = vf ? Vec3((m.x[1] + m.x[2] + m.x[3]) / 3) : Vec3(0.5 * (m.x[2] + m.x[3]));
      const Vec3 src = vf ? m.x[0] : Vec3(0.5 * (m.x[0] + m.x[1]));
      m.dx[0] = m.dx[1] = 2 * (target - src);
      m.dx[2] = m.dx[3] = Vec3::Zero();
      if (vf) m.dx[1] = Vec3::Zero();
    }
    const Real g0 = gap_at(m, 0, offset, vf);
    if (g0 <= 0) continue;
    const Real s = it % 3 == 0 ? 0.5 : kCcdGapFraction;
    const Real a = ccd(m, offset, vf, s);
    ++total;
    ASSERT_GE(a, 0);
    ASSERT_LE(a, 1);
    EXPECT_GT(a, 0);
    limited += a < 1;
    // Dense sampling of the motion up to alpha: never at or below the offset.
    Real gmin = INFINITY;
    const int n = 2000;
    for (int k = 0; k <= n; ++k) gmin = std::min(gmin, gap_at(m, a * k / n, offset, vf));
    EXPECT_GT(gmin, 0) << "it " << it << " alpha " << a;
    EXPECT_GE(gmin, 0.1 * (1 - s) * g0 * (1 - 1e-9)) << "it " << it;
    EXPECT_GE(gap_at(m, a, offset, vf), (1 - s) * g0 * (1 - 1e-9)) << "it " << it;
  }
  EXPECT_GE(total, 300);
  EXPECT_GE(limited, 60);  // many motions are actually stopped
}

TEST(ContactCcd, FarOrRigidPairsTakeTheFullStep) {
  std::mt19937 rng(503);
  const Real offset = 1e-4;
  for (int it = 0; it < 100; ++it) {
    const bool vf = it % 2 == 0;
    Motion m;
    for (int i = 0; i < 4; ++i) m.x[i] = 0.01 * test::random_vec3(rng);
    m.x[0] += Vec3(0, 0, 0.05);
    if (!vf) m.x[1] += Vec3(0, 0, 0.05);
    // Small relative motion: far from touching.
    for (int i = 0; i < 4; ++i) m.dx[i] = 1e-3 * test::random_vec3(rng);
    EXPECT_EQ(ccd(m, offset, vf), 1.0);
    // Large common translation (plus tiny relative motion) is fine too.
    const Vec3 t = test::random_vec3(rng);
    for (int i = 0; i < 4; ++i) m.dx[i] = t;
    EXPECT_EQ(ccd(m, offset, vf), 1.0);
  }
  // Already inside the offset: no motion allowed.
  Motion m;
  m.x[0] = Vec3(0.2, 0.2, 5e-5);
  m.x[1] = Vec3(0, 0, 0);
  m.x[2] = Vec3(1, 0, 0);
  m.x[3] = Vec3(0, 1, 0);
  for (auto& d : m.dx) d = Vec3(0.1, 0, 0);
  m.dx[0] = Vec3(0, 0, 1);
  EXPECT_EQ(ccd(m, offset, true), 0.0);
}

TEST(ContactCcd, HeadOnApproachIsNotOverlyConservative) {
  // A vertex falling straight onto a face: the gap closes at alpha* = g0/|dp|; conservative
  // advancement is exact in the approach speed here and stops at alpha = s alpha*.
  const Vec3 t0(0, 0, 0), t1(0.01, 0, 0), t2(0, 0.01, 0);
  const Real offset = 2e-4;
  const Vec3 p(0.003, 0.003, 1.2e-3);
  const Vec3 dp(0, 0, -3e-3);
  const Real alpha_star = (1.2e-3 - offset) / 3e-3;
  const Real a = point_triangle_ccd(p, t0, t1, t2, dp, Vec3::Zero(), Vec3::Zero(), Vec3::Zero(), offset);
  EXPECT_GT(a, 0.85 * alpha_star);
  EXPECT_LT(a, alpha_star);
  // Crossing edges approaching each other.
  const Real b = edge_edge_ccd(Vec3(-0.01, 0, 1.2e-3), Vec3(0.01, 0, 1.2e-3), Vec3(0, -0.01, 0), Vec3(0, 0.01, 0),
                               Vec3(0, 0, -1.5e-3), Vec3(0, 0, -1.5e-3), Vec3(0, 0, 1.5e-3), Vec3(0, 0, 1.5e-3), offset);
  EXPECT_GT(b, 0.85 * alpha_star);
  EXPECT_LT(b, alpha_star);
}

// Ten Newton iterations pushing two crossing edges (and a point onto a triangle) straight into
// each other: without a floor each CCD call hands out 90% of what is left and the gap falls
// geometrically to ~1e-13 m, where rounding decides whether the exact test sees a crossing; with
// the solver's floor (1e-3 dhat) it stays above 1e-8 m.
TEST(ContactCcd, FloorStopsTheGapShrinkingGeometrically) {
  const Real dhat = 1e-3, floor = kCcdFloorFraction * dhat;
  EXPECT_EQ(ccd_floor_offset(1e-3, floor), floor);
  EXPECT_EQ(ccd_floor_offset(1.5 * floor, floor), 0.75 * floor);  // close: half the distance
  for (bool vf : {true, false}) {
    for (bool with_floor : {false, true}) {
      Motion m;
      if (vf) {
        m.x[0] = Vec3(0.01, 0.01, 1e-3);  // point above the triangle
        m.x[1] = Vec3(0, 0, 0);
        m.x[2] = Vec3(0.05, 0, 0);
        m.x[3] = Vec3(0, 0.05, 0);
      } else {
        m.x[0] = Vec3(-0.02, 0, 1e-3);  // edge along x above an edge along y (nearly crossing)
        m.x[1] = Vec3(0.02, 0.001, 1e-3);
        m.x[2] = Vec3(0, -0.02, 0);
        m.x[3] = Vec3(0, 0.02, 0);
      }
      for (int i = 0; i < 4; ++i) m.dx[i] = Vec3::Zero();
      m.dx[0] = m.dx[1] = Vec3(0, 0, -0.01);  // 1 cm down per iteration: far through
      if (vf) m.dx[1] = Vec3::Zero();
      Real gap = gap_at(m, 0, 0, vf);
      for (int it = 0; it < 10; ++it) {
        const Real a = vf ? point_triangle_ccd(m.x[0], m.x[1], m.x[2], m.x[3], m.dx[0], m.dx[1], m.dx[2], m.dx[3], 0.0,
                                               kCcdGapFraction, kCcdMaxIterations, with_floor ? floor : 0.0)
                          : edge_edge_ccd(m.x[0], m.x[1], m.x[2], m.x[3], m.dx[0], m.dx[1], m.dx[2], m.dx[3], 0.0,
                                          kCcdGapFraction, kCcdMaxIterations, with_floor ? floor : 0.0);
        for (int i = 0; i < 4; ++i) m.x[i] += a * m.dx[i];
        gap = gap_at(m, 0, 0, vf);
        ASSERT_GT(gap, 0.0) << vf << with_floor << it;
      }
      if (with_floor) {
        // Three iterations bring it to the floor (1e-3 -> 1e-4 -> 1e-5 -> ~2e-6); from there it
        // closes by at most 45% per iteration: 5 orders of magnitude above the unfloored gap.
        EXPECT_GT(gap, 1e-8) << (vf ? "vf" : "ee");
        EXPECT_LT(gap, 2 * floor) << (vf ? "vf" : "ee");
      } else {
        EXPECT_LT(gap, 1e-11) << (vf ? "vf" : "ee");
      }
    }
  }
}

}  // namespace
}  // namespace gd::sim

