#pragma once
/// \file
/// Intersection tests between closed triangles and segments (for detecting and untangling
/// self-intersections). Triangles and segments are closed sets: touching counts as intersecting.
///
/// Epsilon policy. Let L be the extent of the input (largest coordinate range over all the points
/// of the test) and tol = kIntersectTol · L (m), kIntersectTol = 1e-12. A point whose distance to a
/// plane, line or edge is <= tol is treated as lying on it. Consequences:
///   - configurations separated by more than ~tol are classified exactly (up to rounding, which is
///     ~1e-16 L, far below tol);
///   - configurations within ~tol of touching may be answered either way (in practice they are
///     reported as intersecting: the tests lean towards "intersect");
///   - coplanar input (all vertices of one triangle within tol of the other's plane) is decided by
///     a 2D overlap test in the plane (projection dropping the dominant normal axis);
///   - a degenerate triangle (sin of its smallest angle below 1e-8, see kEdgeEdgeParallelTol) is
///     treated as its longest edge.
///
/// Method (own formulation of the interval-overlap idea of Möller): triangle B meets the plane of
/// A in a segment S (or point) computed from the signed distances of B's vertices; B ∩ A = S ∩ A,
/// and S ∩ A is decided in A's plane by clipping S against A's three closed half-planes
/// (Cyrus-Beck). Rejection first when all of B's vertices are strictly on one side of A's plane or
/// all of A's strictly on one side of B's.

#include <cmath>

#include <Eigen/Geometry>

#include "sim/contact/distance.h"
#include "sim/types.h"

namespace gd::sim {

/// Relative tolerance of the intersection tests (see the file comment).
inline constexpr Real kIntersectTol = Real(1e-12);

namespace contact_detail {

/// Index of the largest-magnitude component of n.
GD_HD int dominant_axis(const Vec3& n) {
  const Real ax = fabs(n.x()), ay = fabs(n.y()), az = fabs(n.z());
  if (ax >= ay && ax >= az) return 0;
  return ay >= az ? 1 : 2;
}

/// 2D coordinates of x in the plane dropping coordinate `axis` (the other two in cyclic order).
GD_HD Vec2 drop_axis(const Vec3& x, int axis) {
  return Vec2(x[(axis + 1) % 3], x[(axis + 2) % 3]);
}

/// Twice the signed area of (a, b, c): (b - a) × (c - a).
GD_HD Real orient2(const Vec2& a, const Vec2& b, const Vec2& c) {
  const Vec2 u = b - a, v = c - a;
  return u.x() * v.y() - u.y() * v.x();
}

/// Extent of a set of points: the largest coordinate range, at least the smallest positive normal
/// double so tolerances never vanish.
GD_HD Real extent(const Vec3* pts, int n) {
  Vec3 lo = pts[0], hi = pts[0];
  for (int i = 1; i < n; ++i) {
    lo = lo.cwiseMin(pts[i]);
    hi = hi.cwiseMax(pts[i]);
  }
  const Real L = (hi - lo).maxCoeff();
  return L > Real(1e-300) ? L : Real(1e-300);
}

/// Clips the 2D segment x(t) = x0 + t (x1 - x0), t in [0, 1], against the closed triangle
/// (a, b, c) (either orientation, non-degenerate), each edge's half-plane widened by distance tol.
/// Returns true with the parameter interval [*t_in, *t_out] of the part inside when non-empty.
GD_HD bool clip_segment_triangle_2d(const Vec2& x0, const Vec2& x1, const Vec2& a, const Vec2& b,
                                    const Vec2& c, Real tol, Real* t_in, Real* t_out) {
  const Real sigma = orient2(a, b, c) >= Real(0) ? Real(1) : Real(-1);
  const Vec2* v[3] = {&a, &b, &c};
  const Vec2 d = x1 - x0;
  Real lo = Real(0), hi = Real(1);
  for (int k = 0; k < 3; ++k) {
    const Vec2& p = *v[k];
    const Vec2& q = *v[(k + 1) % 3];
    const Vec2 e = q - p;
    // Signed distance-times-|e| of x(t) from the edge line, positive inside: f0 + t f1 >= -tol |e|.
    const Real f0 = sigma * orient2(p, q, x0);
    const Real f1 = sigma * (e.x() * d.y() - e.y() * d.x());
    const Real slack = tol * e.norm();
    if (f1 == Real(0)) {
      if (f0 < -slack) return false;
      continue;
    }
    const Real t = (-slack - f0) / f1;
    if (f1 > Real(0)) {
      if (t > lo) lo = t;
    } else {
      if (t < hi) hi = t;
    }
    if (lo > hi) return false;
  }
  if (t_in) *t_in = lo;
  if (t_out) *t_out = hi;
  return true;
}

/// Longest edge of a triangle, as its two endpoints.
GD_HD void longest_edge(const Vec3& a, const Vec3& b, const Vec3& c, Vec3* p, Vec3* q) {
  const Real lab = (b - a).squaredNorm(), lbc = (c - b).squaredNorm(), lca = (a - c).squaredNorm();
  if (lab >= lbc && lab >= lca) {
    *p = a;
    *q = b;
  } else if (lbc >= lca) {
    *p = b;
    *q = c;
  } else {
    *p = c;
    *q = a;
  }
}

/// True when the triangle's normal is numerically unreliable (see kEdgeEdgeParallelTol).
GD_HD bool triangle_degenerate(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 e1 = b - a, e2 = c - a;
  return !(e1.cross(e2).squaredNorm() > kEdgeEdgeParallelTol * e1.squaredNorm() * e2.squaredNorm());
}

/// -1, 0, +1 with |v| <= tol mapped to 0.
GD_HD int sign_tol(Real v, Real tol) { return v > tol ? 1 : (v < -tol ? -1 : 0); }

/// Segment-triangle test with an externally given tolerance tol (m); the triangle must be
/// non-degenerate. See segment_triangle_intersect.
GD_HD bool segment_triangle_tol(const Vec3& s0, const Vec3& s1, const Vec3& t0, const Vec3& t1,
                                const Vec3& t2, Real tol, Real* t_param) {
  const Vec3 n = (t1 - t0).cross(t2 - t0);
  const Real nn = n.norm();
  const Real o0 = n.dot(s0 - t0), o1 = n.dot(s1 - t0);
  const int g0 = sign_tol(o0, tol * nn), g1 = sign_tol(o1, tol * nn);
  if (g0 * g1 > 0) return false;
  const int ax = dominant_axis(n);
  const Vec2 a = drop_axis(t0, ax), b = drop_axis(t1, ax), c = drop_axis(t2, ax);
  if (g0 == 0 && g1 == 0) {  // coplanar: first parameter of the overlap
    Real lo, hi;
    if (!clip_segment_triangle_2d(drop_axis(s0, ax), drop_axis(s1, ax), a, b, c, tol, &lo, &hi))
      return false;
    if (t_param) *t_param = lo;
    return true;
  }
  Real t;
  if (g0 == 0)
    t = Real(0);
  else if (g1 == 0)
    t = Real(1);
  else
    t = o0 / (o0 - o1);
  const Vec2 x = drop_axis(s0 + t * (s1 - s0), ax);
  if (!clip_segment_triangle_2d(x, x, a, b, c, tol, nullptr, nullptr)) return false;
  if (t_param) *t_param = t;
  return true;
}

/// Segment-segment closed test with tolerance tol (m): closest distance <= tol.
GD_HD bool segment_segment_tol(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1, Real tol,
                               Real* ta) {
  Real sa, sb;
  const EdgeEdgeRegion r = edge_edge_closest_feature(a0, a1, b0, b1, &sa, &sb);
  if (!(edge_edge_distance2(a0, a1, b0, b1, r, nullptr, nullptr) <= tol * tol)) return false;
  if (ta) *ta = sa;
  return true;
}

}  // namespace contact_detail

/// True when the closed segment (s0, s1) and the closed triangle (t0, t1, t2) intersect (within
/// the tolerance of the file comment). When true and `t_param` is non-null, writes the parameter
/// t in [0, 1] of an intersection point s0 + t (s1 - s0): the crossing point of the plane for a
/// transversal segment, the first point of the overlap for a segment lying in the triangle's plane
/// (the closest-point parameter for a degenerate triangle). Units m.
GD_HD bool segment_triangle_intersect(const Vec3& s0, const Vec3& s1, const Vec3& t0, const Vec3& t1,
                                      const Vec3& t2, Real* t_param) {
  const Vec3 pts[5] = {s0, s1, t0, t1, t2};
  const Real tol = kIntersectTol * contact_detail::extent(pts, 5);
  if (contact_detail::triangle_degenerate(t0, t1, t2)) {
    Vec3 p, q;
    contact_detail::longest_edge(t0, t1, t2, &p, &q);
    return contact_detail::segment_segment_tol(s0, s1, p, q, tol, t_param);
  }
  return contact_detail::segment_triangle_tol(s0, s1, t0, t1, t2, tol, t_param);
}

/// True when the closed triangles A = (a0, a1, a2) and B = (b0, b1, b2) intersect (within the
/// tolerance of the file comment); meant for triangles sharing no vertex (triangles sharing a
/// vertex always "intersect" at it). Coplanar triangles: true when they overlap in the plane
/// (including touching edges). Units m.
GD_HD bool triangles_intersect(const Vec3& a0, const Vec3& a1, const Vec3& a2, const Vec3& b0,
                               const Vec3& b1, const Vec3& b2) {
  using namespace contact_detail;
  const Vec3 pts[6] = {a0, a1, a2, b0, b1, b2};
  const Real tol = kIntersectTol * extent(pts, 6);
  const bool degA = triangle_degenerate(a0, a1, a2);
  const bool degB = triangle_degenerate(b0, b1, b2);
  if (degA || degB) {
    Vec3 p, q;
    if (degA && degB) {
      Vec3 r, s;
      longest_edge(a0, a1, a2, &p, &q);
      longest_edge(b0, b1, b2, &r, &s);
      return segment_segment_tol(p, q, r, s, tol, nullptr);
    }
    if (degA) {
      longest_edge(a0, a1, a2, &p, &q);
      return segment_triangle_tol(p, q, b0, b1, b2, tol, nullptr);
    }
    longest_edge(b0, b1, b2, &p, &q);
    return segment_triangle_tol(p, q, a0, a1, a2, tol, nullptr);
  }
  // Signed distances (times |n|) of each triangle's vertices to the other's plane.
  const Vec3 nA = (a1 - a0).cross(a2 - a0);
  const Vec3 nB = (b1 - b0).cross(b2 - b0);
  const Real tA = tol * nA.norm(), tB = tol * nB.norm();
  const Vec3* B[3] = {&b0, &b1, &b2};
  Real oB[3];
  int gB[3];
  for (int i = 0; i < 3; ++i) {
    oB[i] = nA.dot(*B[i] - a0);
    gB[i] = sign_tol(oB[i], tA);
  }
  if (gB[0] == gB[1] && gB[1] == gB[2] && gB[0] != 0) return false;
  int gA[3];
  const Vec3* A[3] = {&a0, &a1, &a2};
  for (int i = 0; i < 3; ++i) gA[i] = sign_tol(nB.dot(*A[i] - b0), tB);
  if (gA[0] == gA[1] && gA[1] == gA[2] && gA[0] != 0) return false;

  const int ax = dominant_axis(nA);
  const Vec2 a2d[3] = {drop_axis(a0, ax), drop_axis(a1, ax), drop_axis(a2, ax)};
  if (gB[0] == 0 && gB[1] == 0 && gB[2] == 0) {
    // Coplanar: an edge of B meets A, or B lies inside A... or A inside B (a vertex of A in B).
    const Vec2 b2d[3] = {drop_axis(b0, ax), drop_axis(b1, ax), drop_axis(b2, ax)};
    for (int k = 0; k < 3; ++k)
      if (clip_segment_triangle_2d(b2d[k], b2d[(k + 1) % 3], a2d[0], a2d[1], a2d[2], tol, nullptr,
                                   nullptr))
        return true;
    return clip_segment_triangle_2d(a2d[0], a2d[0], b2d[0], b2d[1], b2d[2], tol, nullptr, nullptr);
  }
  // S = B ∩ plane(A): vertices on the plane and crossings of edges with strictly opposite signs.
  Vec3 S[3];
  int ns = 0;
  for (int i = 0; i < 3; ++i) {
    if (gB[i] == 0 && ns < 3) S[ns++] = *B[i];
    const int j = (i + 1) % 3;
    if (gB[i] * gB[j] < 0 && ns < 3) {
      const Real t = oB[i] / (oB[i] - oB[j]);
      S[ns++] = *B[i] + t * (*B[j] - *B[i]);
    }
  }
  if (ns == 0) return false;  // unreachable: signs are mixed here
  // ns <= 2 unless all three vertices are on the plane (handled above); use the first and last.
  return clip_segment_triangle_2d(drop_axis(S[0], ax), drop_axis(S[ns - 1], ax), a2d[0], a2d[1], a2d[2],
                                  tol, nullptr, nullptr);
}

}  // namespace gd::sim
