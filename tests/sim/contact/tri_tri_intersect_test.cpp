#include "sim/contact/tri_tri_intersect.h"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <array>
#include <cmath>
#include <random>

#include "sim/fd_check.h"

namespace gd::sim {
namespace {

using Corners = std::array<Vec3, 3>;

// Slow reference for a segment against a triangle in general position: solve
// s0 + t (s1 - s0) = t0 + u (t1 - t0) + v (t2 - t0) by LU.
bool ref_segment_triangle(const Vec3& s0, const Vec3& s1, const Corners& T, Real* t_out = nullptr) {
  Mat3 M;
  M.col(0) = s1 - s0;
  M.col(1) = -(T[1] - T[0]);
  M.col(2) = -(T[2] - T[0]);
  const Vec3 sol = M.fullPivLu().solve(Vec3(T[0] - s0));
  const Real t = sol[0], u = sol[1], v = sol[2];
  if (t_out) *t_out = t;
  return t >= 0 && t <= 1 && u >= 0 && v >= 0 && u + v <= 1;
}

// Reference for triangles in general position (not coplanar): they intersect iff one of the six
// edges crosses the other triangle.
bool ref_triangles(const Corners& A, const Corners& B) {
  for (int k = 0; k < 3; ++k) {
    if (ref_segment_triangle(A[k], A[(k + 1) % 3], B)) return true;
    if (ref_segment_triangle(B[k], B[(k + 1) % 3], A)) return true;
  }
  return false;
}

bool tt(const Corners& A, const Corners& B) { return triangles_intersect(A[0], A[1], A[2], B[0], B[1], B[2]); }

// Both argument orders and all cyclic/flipped vertex orders must agree.
void expect_tt(const Corners& A, const Corners& B, bool expected, const char* what) {
  const int perms[6][3] = {{0, 1, 2}, {1, 2, 0}, {2, 0, 1}, {0, 2, 1}, {2, 1, 0}, {1, 0, 2}};
  for (const auto& pa : perms)
    for (const auto& pb : {perms[0], perms[3], perms[4]}) {
      const Corners Ap = {A[pa[0]], A[pa[1]], A[pa[2]]};
      const Corners Bp = {B[pb[0]], B[pb[1]], B[pb[2]]};
      EXPECT_EQ(tt(Ap, Bp), expected) << what;
      EXPECT_EQ(tt(Bp, Ap), expected) << what << " (swapped)";
    }
}

const Corners kA = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};

TEST(ContactIntersect, KnownTriangleCases) {
  expect_tt(kA, {Vec3(0.2, 0.2, -0.5), Vec3(0.3, 0.2, 0.5), Vec3(0.2, 0.3, 0.5)}, true, "piercing");
  expect_tt(kA, {Vec3(-0.5, 0.3, -0.5), Vec3(1.5, 0.3, -0.5), Vec3(0.3, 0.3, 1)}, true, "crossing through two edges");
  expect_tt(kA, {Vec3(0.2, 0.2, 0.5), Vec3(0.3, 0.2, 1.5), Vec3(0.2, 0.3, 1.5)}, false, "separated above");
  expect_tt(kA, {Vec3(2, 0, -1), Vec3(2, 0, 1), Vec3(2, 1, 0)}, false, "plane crosses, segment outside");
  expect_tt(kA, {Vec3(0.6, 0.6, -1), Vec3(0.6, 0.6, 1), Vec3(2, 2, 0)}, false, "straddles the plane beyond the hypotenuse");
  expect_tt(kA, {Vec3(0.2, 0.2, 0), Vec3(0.3, 0.2, 1), Vec3(0.2, 0.3, 1)}, true, "vertex touching the face");
  expect_tt(kA, {Vec3(0.5, 0.5, 0), Vec3(1, 1, 1), Vec3(1, 0.5, 1)}, true, "vertex touching an edge");
  expect_tt(kA, {Vec3(0.2, -0.3, 0.0), Vec3(0.2, 0.5, 0.0), Vec3(0.2, 0.1, 1)}, true, "edge lying in the face");
  expect_tt(kA, {Vec3(0.5, -0.5, 0.0), Vec3(0.5, 0.5, 1e-6), Vec3(0.5, 0.1, 1)}, false, "only a vertex outside A lies on the plane");
  expect_tt(kA, {Vec3(0.2, 0.2, 1e-9), Vec3(0.3, 0.2, 1), Vec3(0.2, 0.3, 1)}, false, "vertex 1e-9 above the face");
  expect_tt(kA, {Vec3(0.2, 0.2, -1e-9), Vec3(0.3, 0.2, 1), Vec3(0.2, 0.3, 1)}, true, "vertex 1e-9 below the face");
  // Coplanar.
  expect_tt(kA, {Vec3(0.2, 0.2, 0), Vec3(1.2, 0.2, 0), Vec3(0.2, 1.2, 0)}, true, "coplanar overlapping");
  expect_tt(kA, {Vec3(1, 1, 0), Vec3(2, 1, 0), Vec3(1, 2, 0)}, false, "coplanar disjoint");
  expect_tt(kA, {Vec3(0.1, 0.1, 0), Vec3(0.2, 0.1, 0), Vec3(0.1, 0.2, 0)}, true, "coplanar B inside A");
  expect_tt(kA, {Vec3(-1, -1, 0), Vec3(3, -1, 0), Vec3(-1, 3, 0)}, true, "coplanar A inside B");
  expect_tt(kA, {Vec3(0.3, 0, 0), Vec3(0.6, 0, 0), Vec3(0.45, -0.5, 0)}, true, "coplanar touching along an edge");
  expect_tt(kA, {Vec3(0.3, -1e-6, 0), Vec3(0.6, -1e-6, 0), Vec3(0.45, -0.5, 0)}, false, "coplanar 1e-6 apart");
  expect_tt(kA, {Vec3(0.5, 0.5, 0), Vec3(1, 1, 0), Vec3(1.5, 0.5, 0)}, true, "coplanar vertex on an edge");
  // Degenerate triangle (a segment) piercing A, and one missing it.
  expect_tt(kA, {Vec3(0.2, 0.2, -1), Vec3(0.2, 0.2, 1), Vec3(0.2, 0.2, 0.5)}, true, "degenerate piercing");
  expect_tt(kA, {Vec3(1.2, 0.2, -1), Vec3(1.2, 0.2, 1), Vec3(1.2, 0.2, 0.5)}, false, "degenerate missing");
}

TEST(ContactIntersect, KnownCasesSurviveRigidMotionAtClothScale) {
  // 1 cm triangles placed a metre from the origin, randomly rotated: clear cases (margins of
  // 1e-7 m, far above the 1e-14 m tolerance) keep their answers.
  std::mt19937 rng(401);
  for (int it = 0; it < 50; ++it) {
    const Mat3 R = test::random_rotation(rng);
    const Vec3 o = test::random_vec3(rng);
    auto X = [&](const Vec3& v) { return Vec3(o + R * (0.01 * v)); };
    const Corners A = {X(kA[0]), X(kA[1]), X(kA[2])};
    const Real m = 1e-5;  // 1e-7 m after scaling
    EXPECT_TRUE(tt(A, {X(Vec3(0.2, 0.2, -m)), X(Vec3(0.3, 0.2, 1)), X(Vec3(0.2, 0.3, 1))}));
    EXPECT_FALSE(tt(A, {X(Vec3(0.2, 0.2, m)), X(Vec3(0.3, 0.2, 1)), X(Vec3(0.2, 0.3, 1))}));
    EXPECT_TRUE(tt(A, {X(Vec3(0.2, 0.2, 0)), X(Vec3(1.2, 0.2, 0)), X(Vec3(0.2, 1.2, 0))}));  // coplanar
    EXPECT_FALSE(tt(A, {X(Vec3(0.3, -m, 0)), X(Vec3(0.6, -m, 0)), X(Vec3(0.45, -0.5, 0))}));
    EXPECT_TRUE(tt(A, {X(Vec3(0.3, m, 0)), X(Vec3(0.6, m, 0)), X(Vec3(0.45, -0.5, 0))}));
  }
}

TEST(ContactIntersect, RandomTrianglesMatchEdgeCrossingReference) {
  std::mt19937 rng(403);
  int hits = 0, total = 0;
  for (int it = 0; it < 20000; ++it) {
    Corners A, B;
    for (auto& v : A) v = test::random_vec3(rng);
    const Vec3 shift = 0.8 * test::random_vec3(rng);
    for (auto& v : B) v = 0.7 * test::random_vec3(rng) + shift;
    const bool ref = ref_triangles(A, B);
    EXPECT_EQ(tt(A, B), ref) << "it " << it;
    hits += ref;
    ++total;
  }
  // Both outcomes well represented.
  EXPECT_GT(hits, total / 10);
  EXPECT_LT(hits, total * 9 / 10);
}

// 2D reference for coplanar triangles: proper edge crossing or containment (general position).
Real cross2(const Vec2& a, const Vec2& b, const Vec2& c) {
  return (b - a).x() * (c - a).y() - (b - a).y() * (c - a).x();
}
bool inside2(const Vec2& p, const std::array<Vec2, 3>& T) {
  const Real a = cross2(T[0], T[1], p), b = cross2(T[1], T[2], p), c = cross2(T[2], T[0], p);
  return (a >= 0 && b >= 0 && c >= 0) || (a <= 0 && b <= 0 && c <= 0);
}
bool ref_coplanar(const std::array<Vec2, 3>& A, const std::array<Vec2, 3>& B) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const Vec2 &p0 = A[i], &p1 = A[(i + 1) % 3], &q0 = B[j], &q1 = B[(j + 1) % 3];
      if (cross2(p0, p1, q0) * cross2(p0, p1, q1) < 0 && cross2(q0, q1, p0) * cross2(q0, q1, p1) < 0) return true;
    }
  return inside2(A[0], B) || inside2(B[0], A);
}

TEST(ContactIntersect, RandomCoplanarTrianglesMatch2DReference) {
  std::mt19937 rng(405);
  std::uniform_real_distribution<Real> u(-1, 1);
  int hits = 0;
  const int n = 5000;
  for (int it = 0; it < n; ++it) {
    std::array<Vec2, 3> A2, B2;
    for (auto& v : A2) v = Vec2(u(rng), u(rng));
    const Vec2 shift(u(rng), u(rng));
    for (auto& v : B2) v = 0.6 * Vec2(u(rng), u(rng)) + shift;
    const bool ref = ref_coplanar(A2, B2);
    const Mat3 R = test::random_rotation(rng);
    const Vec3 o = test::random_vec3(rng);
    auto X = [&](const Vec2& v) { return Vec3(o + R * Vec3(v.x(), v.y(), 0)); };
    const Corners A = {X(A2[0]), X(A2[1]), X(A2[2])};
    const Corners B = {X(B2[0]), X(B2[1]), X(B2[2])};
    EXPECT_EQ(tt(A, B), ref) << "it " << it;
    hits += ref;
  }
  EXPECT_GT(hits, n / 10);
  EXPECT_LT(hits, n * 9 / 10);
}

TEST(ContactIntersect, SegmentTriangle) {
  Real t = -1;
  EXPECT_TRUE(segment_triangle_intersect(Vec3(0.2, 0.2, -1), Vec3(0.2, 0.2, 3), kA[0], kA[1], kA[2], &t));
  EXPECT_NEAR(t, 0.25, 1e-15);
  EXPECT_FALSE(segment_triangle_intersect(Vec3(0.2, 0.2, 0.1), Vec3(0.2, 0.2, 3), kA[0], kA[1], kA[2], &t));
  EXPECT_FALSE(segment_triangle_intersect(Vec3(0.8, 0.8, -1), Vec3(0.8, 0.8, 1), kA[0], kA[1], kA[2], &t));
  EXPECT_TRUE(segment_triangle_intersect(Vec3(0.5, 0.5, -1), Vec3(0.5, 0.5, 1), kA[0], kA[1], kA[2], &t));  // on edge
  EXPECT_NEAR(t, 0.5, 1e-15);
  EXPECT_TRUE(segment_triangle_intersect(Vec3(0.2, 0.2, 0), Vec3(0.2, 0.2, 1), kA[0], kA[1], kA[2], &t));  // endpoint on face
  EXPECT_EQ(t, 0.0);
  // Coplanar: entering through the edge x = 0 at parameter 0.25.
  EXPECT_TRUE(segment_triangle_intersect(Vec3(-0.5, 0.3, 0), Vec3(1.5, 0.3, 0), kA[0], kA[1], kA[2], &t));
  EXPECT_NEAR(t, 0.25, 1e-10);  // widened by the tolerance (1e-12 x extent)
  EXPECT_FALSE(segment_triangle_intersect(Vec3(-0.5, 1.3, 0), Vec3(1.5, 1.3, 0), kA[0], kA[1], kA[2], &t));
  // Degenerate triangle: segment-segment.
  EXPECT_TRUE(segment_triangle_intersect(Vec3(0.5, -1, 0), Vec3(0.5, 1, 0), Vec3(0, 0, 0), Vec3(1, 0, 0),
                                         Vec3(2, 0, 0), &t));
  EXPECT_NEAR(t, 0.5, 1e-15);

  std::mt19937 rng(407);
  int hits = 0;
  for (int it = 0; it < 20000; ++it) {
    const Corners T = {test::random_vec3(rng), test::random_vec3(rng), test::random_vec3(rng)};
    const Vec3 s0 = 1.2 * test::random_vec3(rng), s1 = 1.2 * test::random_vec3(rng);
    Real tr;
    const bool ref = ref_segment_triangle(s0, s1, T, &tr);
    Real tp = -1;
    const bool got = segment_triangle_intersect(s0, s1, T[0], T[1], T[2], &tp);
    EXPECT_EQ(got, ref) << it;
    if (got && ref) EXPECT_NEAR(tp, tr, 1e-9);
    hits += ref;
  }
  EXPECT_GT(hits, 1000);
}

}  // namespace
}  // namespace gd::sim
