#include "sim/contact/distance.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>

#include "sim/fd_check.h"

namespace gd::sim {
namespace {

using V12 = VecN<12>;

using test::stack4;

// Brute force: min over a barycentric lattice of spacing 1/N (includes the boundary). Any point of
// the triangle is within max_edge/N of a lattice point.
Real brute_point_triangle(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2, int N) {
  Real best = INFINITY;
  for (int i = 0; i <= N; ++i)
    for (int j = 0; i + j <= N; ++j) {
      const Real b1 = Real(i) / N, b2 = Real(j) / N;
      const Vec3 c = t0 + b1 * (t1 - t0) + b2 * (t2 - t0);
      best = std::min(best, (p - c).norm());
    }
  return best;
}

Real brute_edge_edge(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1, int N) {
  Real best = INFINITY;
  for (int i = 0; i <= N; ++i) {
    const Vec3 ca = a0 + (Real(i) / N) * (a1 - a0);
    for (int j = 0; j <= N; ++j) {
      const Vec3 cb = b0 + (Real(j) / N) * (b1 - b0);
      best = std::min(best, (ca - cb).squaredNorm());
    }
  }
  return std::sqrt(best);
}

TEST(ContactDistance, PointTriangleMatchesBruteForceInEveryRegion) {
  std::mt19937 rng(101);
  std::uniform_real_distribution<Real> u(-3, 3);
  std::array<int, 7> hits{};
  const int N = 160;
  for (int it = 0; it < 400; ++it) {
    const Vec3 t0 = test::random_vec3(rng), t1 = test::random_vec3(rng), t2 = test::random_vec3(rng);
    Vec3 p(u(rng), u(rng), u(rng));
    if (it % 4 == 0) {  // bias some samples towards the face region: above an interior point
      const Vec3 n = (t1 - t0).cross(t2 - t0).normalized();
      p = (t0 + t1 + t2) / 3 + 0.2 * (t1 - t0) * (u(rng) / 3) + n * u(rng);
    }
    Vec3 bary;
    const PointTriangleRegion r = point_triangle_closest_feature(p, t0, t1, t2, &bary);
    hits[static_cast<int>(r)]++;
    const Real d = std::sqrt(point_triangle_distance2(p, t0, t1, t2, nullptr, nullptr));
    const Real L = std::max({(t1 - t0).norm(), (t2 - t1).norm(), (t0 - t2).norm()});
    const Real db = brute_point_triangle(p, t0, t1, t2, N);
    EXPECT_LE(d, db + 1e-12) << "region " << int(r);
    EXPECT_GE(d, db - L / N) << "region " << int(r);
    // The barycentric closest point realises the distance.
    EXPECT_NEAR((p - (bary[0] * t0 + bary[1] * t1 + bary[2] * t2)).norm(), d, 1e-12);
    EXPECT_NEAR(bary.sum(), 1.0, 1e-14);
    EXPECT_GE(bary.minCoeff(), -1e-15);
  }
  for (int k = 0; k < 7; ++k) EXPECT_GE(hits[k], 10) << "region " << k;
}

TEST(ContactDistance, EdgeEdgeMatchesBruteForceInEveryRegion) {
  std::mt19937 rng(103);
  std::array<int, 9> hits{};
  const int N = 300;
  for (int it = 0; it < 300; ++it) {
    Vec3 a0 = test::random_vec3(rng), a1 = test::random_vec3(rng);
    Vec3 b0 = test::random_vec3(rng), b1 = test::random_vec3(rng);
    if (it % 10 == 1) {  // exactly parallel, overlapping or not
      const Vec3 off = 0.3 * test::random_vec3(rng);
      const Real s = 2.0 * (std::uniform_real_distribution<Real>(-1, 1)(rng));
      b0 = a0 + off + s * (a1 - a0);
      b1 = a1 + off + s * (a1 - a0) * 0.5;
    }
    if (it % 10 == 2) {  // nearly parallel
      b0 = a0 + 0.2 * test::random_vec3(rng);
      b1 = b0 + (a1 - a0) + 1e-9 * test::random_vec3(rng);
    }
    if (it % 10 == 3) b1 = b0;  // zero-length edge
    Real sa, sb;
    const EdgeEdgeRegion r = edge_edge_closest_feature(a0, a1, b0, b1, &sa, &sb);
    hits[static_cast<int>(r)]++;
    const Real d = std::sqrt(edge_edge_distance2(a0, a1, b0, b1, nullptr, nullptr));
    const Real L = std::max((a1 - a0).norm(), (b1 - b0).norm());
    const Real db = brute_edge_edge(a0, a1, b0, b1, N);
    EXPECT_LE(d, db + 1e-9) << "region " << int(r) << " it " << it;
    EXPECT_GE(d, db - L / N) << "region " << int(r) << " it " << it;
    EXPECT_GE(sa, 0);
    EXPECT_LE(sa, 1);
    EXPECT_GE(sb, 0);
    EXPECT_LE(sb, 1);
    const Vec3 ca = a0 + sa * (a1 - a0), cb = b0 + sb * (b1 - b0);
    EXPECT_NEAR((ca - cb).norm(), d, 1e-9) << "region " << int(r) << " it " << it;
  }
  for (int k = 0; k < 9; ++k) EXPECT_GE(hits[k], 2) << "region " << k;
}

TEST(ContactDistance, ParallelAndDegenerateEdgesExact) {
  // Parallel, overlapping: distance is the line separation.
  const Vec3 a0(0, 0, 0), a1(1, 0, 0);
  EXPECT_NEAR(edge_edge_distance2(a0, a1, Vec3(0.5, 0.3, 0), Vec3(1.5, 0.3, 0), nullptr, nullptr), 0.09,
              1e-15);
  // Parallel, disjoint along the line: endpoint to endpoint.
  EXPECT_NEAR(edge_edge_distance2(a0, a1, Vec3(2, 0.3, 0), Vec3(3, 0.3, 0), nullptr, nullptr),
              1 + 0.09, 1e-15);
  // Collinear overlapping: zero.
  EXPECT_EQ(edge_edge_distance2(a0, a1, Vec3(0.5, 0, 0), Vec3(2, 0, 0), nullptr, nullptr), 0.0);
  // Anti-parallel with a tiny angle: still the right value, finite derivatives.
  V12 g;
  MatN<12> H;
  const Real d2 = edge_edge_distance2(a0, a1, Vec3(0.2, 0.1, 0), Vec3(-0.8, 0.1, 1e-13), &g, &H);
  EXPECT_NEAR(d2, 0.01, 1e-12);
  EXPECT_TRUE(g.allFinite());
  EXPECT_TRUE(H.allFinite());
  // Both degenerate: point-point.
  EXPECT_NEAR(edge_edge_distance2(a0, a0, a1, a1, nullptr, nullptr), 1.0, 1e-15);
  // Crossing segments (interior): distance is the offset along the common normal.
  EXPECT_EQ(edge_edge_closest_feature(Vec3(-1, 0, 0), Vec3(1, 0, 0), Vec3(0, -1, 0.25), Vec3(0, 1, 0.25)),
            EdgeEdgeRegion::kInterior);
  EXPECT_NEAR(edge_edge_distance2(Vec3(-1, 0, 0), Vec3(1, 0, 0), Vec3(0, -1, 0.25), Vec3(0, 1, 0.25),
                                  nullptr, nullptr),
              0.0625, 1e-15);
  // Degenerate (collinear) triangle: no face region, the distance is to the segment.
  const Vec3 p(0.5, 1, 0);
  EXPECT_NE(point_triangle_closest_feature(p, a0, a1, Vec3(2, 0, 0)), PointTriangleRegion::kFace);
  EXPECT_NEAR(point_triangle_distance2(p, a0, a1, Vec3(2, 0, 0), nullptr, nullptr), 1.0, 1e-15);
  // Point-segment basics.
  EXPECT_EQ(point_segment_closest_feature(Vec3(-1, 1, 0), a0, a1), PointSegmentRegion::kVertex0);
  EXPECT_EQ(point_segment_closest_feature(Vec3(2, 1, 0), a0, a1), PointSegmentRegion::kVertex1);
  EXPECT_EQ(point_segment_closest_feature(Vec3(0.5, 1, 0), a0, a1), PointSegmentRegion::kInterior);
  EXPECT_NEAR(point_segment_distance2(Vec3(0.5, 1, 2), a0, a1, nullptr, nullptr), 5.0, 1e-15);
  EXPECT_NEAR(point_segment_distance2(Vec3(3, 0, 0), a0, a0, nullptr, nullptr), 9.0, 1e-15);
}

// FD check of a 12-coordinate squared distance at x, provided the classification is the same at
// every stencil point (away from region boundaries). Returns false when skipped.
template <class F, class R>
bool fd_check12(const F& dist2, const R& region_of, const V12& x, Real h, const char* what) {
  const auto r0 = region_of(x);
  for (int i = 0; i < 12; ++i)
    for (Real sgn : {-1.0, 1.0}) {
      V12 y = x;
      y[i] += sgn * h;
      if (region_of(y) != r0) return false;
    }
  V12 g;
  MatN<12> H;
  dist2(x, &g, &H);
  auto f = [&](const V12& y) { return dist2(y, nullptr, nullptr); };
  auto gf = [&](const V12& y) {
    V12 gg;
    dist2(y, &gg, nullptr);
    return gg;
  };
  EXPECT_TRUE(test::near_rel(g, test::fd_gradient<12>(f, x, h), 1e-6, 1e-9)) << what << " region " << int(r0);
  EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<12, 12>(gf, x, h), 1e-5, 1e-7))
      << what << " region " << int(r0);
  EXPECT_LT((H - H.transpose()).norm(), 1e-12 * (1 + H.norm()));
  return true;
}

TEST(ContactDistance, PointTriangleDerivativesMatchFiniteDifferences) {
  std::mt19937 rng(107);
  std::uniform_real_distribution<Real> u(-2.5, 2.5);
  std::array<int, 7> checked{};
  for (int it = 0; it < 300; ++it) {
    const Vec3 t0 = test::random_vec3(rng), t1 = test::random_vec3(rng), t2 = test::random_vec3(rng);
    Vec3 p(u(rng), u(rng), u(rng));
    if (it % 3 == 0) p = (t0 + t1 + t2) / 3 + (t1 - t0).cross(t2 - t0).normalized() * u(rng);
    const V12 x = stack4(p, t0, t1, t2);
    auto dist2 = [](const V12& y, V12* g, MatN<12>* H) {
      return point_triangle_distance2(y.segment<3>(0), y.segment<3>(3), y.segment<3>(6), y.segment<3>(9), g, H);
    };
    auto region = [](const V12& y) {
      return point_triangle_closest_feature(y.segment<3>(0), y.segment<3>(3), y.segment<3>(6), y.segment<3>(9));
    };
    const PointTriangleRegion r = region(x);
    if (fd_check12(dist2, region, x, 1e-5, "point-triangle")) checked[static_cast<int>(r)]++;
  }
  for (int k = 0; k < 7; ++k) EXPECT_GE(checked[k], 5) << "region " << k;
}

TEST(ContactDistance, EdgeEdgeDerivativesMatchFiniteDifferences) {
  std::mt19937 rng(109);
  std::array<int, 9> checked{};
  for (int it = 0; it < 400; ++it) {
    const V12 x = stack4(test::random_vec3(rng), test::random_vec3(rng), test::random_vec3(rng),
                         test::random_vec3(rng));
    auto dist2 = [](const V12& y, V12* g, MatN<12>* H) {
      return edge_edge_distance2(y.segment<3>(0), y.segment<3>(3), y.segment<3>(6), y.segment<3>(9), g, H);
    };
    auto region = [](const V12& y) {
      return edge_edge_closest_feature(y.segment<3>(0), y.segment<3>(3), y.segment<3>(6), y.segment<3>(9));
    };
    const EdgeEdgeRegion r = region(x);
    if (fd_check12(dist2, region, x, 1e-5, "edge-edge")) checked[static_cast<int>(r)]++;
  }
  for (int k = 0; k < 9; ++k) EXPECT_GE(checked[k], 5) << "region " << k;
}

TEST(ContactDistance, PointSegmentAndPointPointDerivatives) {
  std::mt19937 rng(113);
  int checked[3] = {0, 0, 0};
  for (int it = 0; it < 200; ++it) {
    VecN<9> x;
    x << 1.5 * test::random_vec3(rng), test::random_vec3(rng), test::random_vec3(rng);
    auto f = [](const VecN<9>& y) {
      return point_segment_distance2(y.segment<3>(0), y.segment<3>(3), y.segment<3>(6), nullptr, nullptr);
    };
    auto gf = [](const VecN<9>& y) {
      VecN<9> g;
      point_segment_distance2(y.segment<3>(0), y.segment<3>(3), y.segment<3>(6), &g, nullptr);
      return g;
    };
    auto reg = [](const VecN<9>& y) {
      return point_segment_closest_feature(y.segment<3>(0), y.segment<3>(3), y.segment<3>(6));
    };
    const Real h = 1e-5;
    bool stable = true;
    for (int i = 0; i < 9 && stable; ++i)
      for (Real s : {-h, h}) {
        VecN<9> y = x;
        y[i] += s;
        stable = stable && reg(y) == reg(x);
      }
    if (!stable) continue;
    VecN<9> g;
    MatN<9> H;
    point_segment_distance2(x.segment<3>(0), x.segment<3>(3), x.segment<3>(6), &g, &H);
    EXPECT_TRUE(test::near_rel(g, test::fd_gradient<9>(f, x, h), 1e-6, 1e-9));
    EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<9, 9>(gf, x, h), 1e-5, 1e-7));
    checked[static_cast<int>(reg(x))]++;
  }
  for (int k = 0; k < 3; ++k) EXPECT_GE(checked[k], 10) << k;

  const Vec3 p(0.3, -0.2, 0.7), q(-0.1, 0.4, 0.2);
  VecN<6> g;
  MatN<6> H;
  EXPECT_NEAR(point_point_distance2(p, q, &g, &H), (p - q).squaredNorm(), 1e-15);
  VecN<6> ge;
  ge << 2 * (p - q), -2 * (p - q);
  EXPECT_TRUE(test::near_rel(g, ge, 1e-15));
  EXPECT_NEAR(H(0, 0), 2, 0);
  EXPECT_NEAR(H(0, 3), -2, 0);
  EXPECT_NEAR(H(1, 0), 0, 0);
}

TEST(ContactDistance, ClothScaleFaceDistanceIsAccurate) {
  // A point 0.1 mm above the interior of a 1 cm triangle placed 1 m from the origin: the squared
  // distance keeps ~1e-12 relative accuracy (no cancellation) and the gradient is 2 d n.
  const Vec3 o(1.0, -0.7, 0.4);
  const Vec3 t0 = o, t1 = o + Vec3(0.01, 0, 0), t2 = o + Vec3(0.002, 0.009, 0);
  const Vec3 p = o + Vec3(0.004, 0.003, 1e-4);
  V12 g;
  MatN<12> H;
  EXPECT_EQ(point_triangle_closest_feature(p, t0, t1, t2), PointTriangleRegion::kFace);
  const Real d2 = point_triangle_distance2(p, t0, t1, t2, &g, &H);
  EXPECT_NEAR(d2, 1e-8, 1e-19);
  EXPECT_TRUE(test::near_rel(Vec3(g.segment<3>(0)), Vec3(0, 0, 2e-4), 1e-9));
  EXPECT_TRUE(test::near_rel(Vec3(g.segment<3>(3) + g.segment<3>(6) + g.segment<3>(9)), Vec3(0, 0, -2e-4), 1e-9));
}

}  // namespace
}  // namespace gd::sim
