// pair_distance2_lower_bound: never above the exact distance, tight where cloth lies in layers,
// no bound where it would be ill-conditioned; and the CCD's shortcut through it (ccd.h
// whole_step_by_bound) answers exactly what the full advancement answers.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "sim/contact/ccd.h"
#include "sim/contact/distance.h"
#include "sim/fd_check.h"

namespace gd::sim {
namespace {

Real exact_distance2(const Vec3 (&x)[4], int type) {
  return type == 0 ? point_triangle_distance2(x[0], x[1], x[2], x[3], nullptr, nullptr)
                   : edge_edge_distance2(x[0], x[1], x[2], x[3], nullptr, nullptr);
}

/// Cloth-scale pairs: a 7 mm element somewhere in a 0.5 m garment, its partner within a few mm,
/// every orientation, a fifth of them near-parallel or sliver.
void random_pair(std::mt19937& rng, int type, Vec3 (&x)[4]) {
  std::uniform_real_distribution<Real> u(0, 1);
  const Vec3 origin = 0.25 * test::random_vec3(rng);
  for (auto& p : x) p = origin + 0.007 * test::random_vec3(rng);
  if (u(rng) < 0.2) {  // nearly degenerate: a sliver triangle or nearly parallel edges
    const Vec3 dir = test::random_vec3(rng).normalized();
    const Real eps = std::pow(10.0, -2 - 8 * u(rng));
    if (type == 0) {
      x[2] = x[1] + 0.007 * dir + eps * 0.007 * test::random_vec3(rng);
      x[3] = x[1] + 0.014 * dir + eps * 0.007 * test::random_vec3(rng);
    } else {
      x[1] = x[0] + 0.007 * dir + eps * 0.007 * test::random_vec3(rng);
      x[3] = x[2] + 0.007 * dir + eps * 0.007 * test::random_vec3(rng);
    }
  }
}

TEST(ContactDistanceLowerBound, NeverAboveTheDistance) {
  std::mt19937 rng(71);
  int bounded = 0;
  for (int it = 0; it < 200000; ++it) {
    const int type = it % 2;
    Vec3 x[4];
    random_pair(rng, type, x);
    const Real lower = pair_distance2_lower_bound(x[0], x[1], x[2], x[3], type);
    const Real d2 = exact_distance2(x, type);
    ASSERT_GE(lower, 0.0);
    ASSERT_LE(lower, d2 * (1 + 1e-12) + 1e-30) << "it " << it << " type " << type;
    if (lower > 0) ++bounded;
    // What the solver asks: beyond a reach of 1 mm per the bound means beyond it exactly.
    if (pair_certainly_beyond(x[0], x[1], x[2], x[3], type, 1e-3)) ASSERT_GT(std::sqrt(d2), 1e-3) << "it " << it;
  }
  EXPECT_GT(bounded, 150000);  // most pairs get a bound
}

TEST(ContactDistanceLowerBound, ExactForLayersAndZeroWhereIllConditioned) {
  // A point 1.5 mm above a triangle's interior: the plane's distance is the distance.
  const Vec3 t0(0.1, 0.2, 0.3), t1(0.107, 0.2, 0.3), t2(0.1, 0.207, 0.3), p(0.102, 0.202, 0.3015);
  EXPECT_NEAR(pair_distance2_lower_bound(p, t0, t1, t2, 0), 1.5e-3 * 1.5e-3, 1e-18);
  EXPECT_TRUE(pair_certainly_beyond(p, t0, t1, t2, 0, 1e-3));
  EXPECT_FALSE(pair_certainly_beyond(p, t0, t1, t2, 0, 2e-3));
  // Crossing edges 2 mm apart: the lines' distance is the distance.
  const Vec3 a0(0, 0, 0), a1(0.007, 0, 0), b0(0.0035, -0.0035, 0.002), b1(0.0035, 0.0035, 0.002);
  EXPECT_NEAR(pair_distance2_lower_bound(a0, a1, b0, b1, 1), 4e-6, 1e-18);
  // Parallel edges and a sliver triangle: no bound (rounding would decide it).
  EXPECT_EQ(pair_distance2_lower_bound(a0, a1, a0 + Vec3(0, 0, 0.002), a1 + Vec3(1e-9, 0, 0.002), 1), 0.0);
  EXPECT_EQ(pair_distance2_lower_bound(p, t0, t1, Vec3(0.114, 0.2 + 1e-9, 0.3), 0), 0.0);
  // A point beside the triangle: far from the plane's distance, and still below the distance.
  const Vec3 q(0.12, 0.2, 0.3002);
  EXPECT_LT(pair_distance2_lower_bound(q, t0, t1, t2, 0), point_triangle_distance2(q, t0, t1, t2, nullptr, nullptr));
}

TEST(ContactDistanceLowerBound, CcdShortcutAnswersAsTheAdvancement) {
  // point_triangle_ccd / edge_edge_ccd take the whole step from the bound alone where it
  // suffices; the advancement from the measured distance must give the same answer everywhere.
  std::mt19937 rng(72);
  std::uniform_real_distribution<Real> u(0, 1);
  int shortcuts = 0;
  for (int it = 0; it < 100000; ++it) {
    const int type = it % 2;
    Vec3 x[4], dx[4];
    random_pair(rng, type, x);
    const Real scale = std::pow(10.0, -5 + 3 * u(rng));  // motions of 10 um to 10 mm
    for (auto& d : dx) d = scale * test::random_vec3(rng);
    const Real floor = it % 3 == 0 ? 0.0 : 1e-6, offset = it % 5 == 0 ? 1e-4 : 0.0;
    const Real alpha = type == 0 ? point_triangle_ccd(x[0], x[1], x[2], x[3], dx[0], dx[1], dx[2], dx[3], offset,
                                                      kCcdGapFraction, kCcdMaxIterations, floor)
                                 : edge_edge_ccd(x[0], x[1], x[2], x[3], dx[0], dx[1], dx[2], dx[3], offset,
                                                 kCcdGapFraction, kCcdMaxIterations, floor);
    // The advancement itself, as the functions run it without the shortcut.
    const Vec3 mean = 0.25 * (dx[0] + dx[1] + dx[2] + dx[3]);
    Vec3 w[4];
    for (int k = 0; k < 4; ++k) w[k] = dx[k] - mean;
    const Real l = type == 0 ? w[0].norm() + std::max({w[1].norm(), w[2].norm(), w[3].norm()})
                             : std::max(w[0].norm(), w[1].norm()) + std::max(w[2].norm(), w[3].norm());
    auto dist = [&](Real a) {
      Vec3 y[4];
      for (int k = 0; k < 4; ++k) y[k] = x[k] + a * w[k];
      return std::sqrt(exact_distance2(y, type));
    };
    const Real reference = contact_detail::advance_pair(dist, offset, l, kCcdGapFraction, kCcdMaxIterations, floor);
    ASSERT_EQ(alpha, reference) << "it " << it;
    if (contact_detail::whole_step_by_bound(pair_distance2_lower_bound(x[0], x[1], x[2], x[3], type), offset, l,
                                            kCcdGapFraction, floor))
      ++shortcuts;
  }
  EXPECT_GT(shortcuts, 20000);  // the shortcut is taken, and agrees
}

}  // namespace
}  // namespace gd::sim
