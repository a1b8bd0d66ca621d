#pragma once
/// \file
/// Squared distances between contact primitives (point-point, point-segment, point-triangle,
/// segment-segment) with exact gradients and Hessians, for the self-contact barrier.
///
/// Method: classify the closest pair of features (vertex / edge interior / face interior), then
/// evaluate and differentiate that feature pair's smooth formula. The squared distance is C¹
/// across region boundaries (value and gradient agree there) but its Hessian jumps, so
/// finite-difference checks must stay away from boundaries.
///
/// Every feature formula is one of three kernels of "difference vectors" (m, m²):
///   point-point:  f(r)          = |r|²
///   point-line:   f(r, e)       = |r × e|² / |e|²                 = |r|² - (r·e)²/(e·e)
///   point-plane / line-line:
///                 f(r, e1, e2)  = (r · (e1 × e2))² / |e1 × e2|²
/// where r, e, e1, e2 are differences of vertex positions. Gradients and Hessians are derived in
/// the difference variables and mapped to vertex coordinates through the constant Jacobian
/// (entries 0, ±1). Units: inputs m, squared distance m², gradient m, Hessian dimensionless.
/// Gradient layout: vertex-major, xyz per vertex, in the argument order of the function.

#include <cmath>

#include <Eigen/Geometry>  // cross()

#include "sim/types.h"

namespace gd::sim {

/// Closest feature of a segment (e0, e1) to a point.
enum class PointSegmentRegion : int {
  kVertex0 = 0,  ///< the closest point is e0 (also used for a zero-length segment)
  kVertex1 = 1,  ///< the closest point is e1
  kInterior = 2, ///< the closest point is strictly inside the segment (point-line distance)
};

/// Closest feature of a triangle (t0, t1, t2) to a point.
enum class PointTriangleRegion : int {
  kVertex0 = 0,  ///< t0 (point-point)
  kVertex1 = 1,  ///< t1
  kVertex2 = 2,  ///< t2
  kEdge01 = 3,   ///< interior of edge t0-t1 (point-line)
  kEdge12 = 4,   ///< interior of edge t1-t2
  kEdge20 = 5,   ///< interior of edge t2-t0
  kFace = 6,     ///< interior of the face (point-plane)
};

/// Closest pair of features of two segments a = (a0, a1), b = (b0, b1).
enum class EdgeEdgeRegion : int {
  kA0B0 = 0,       ///< endpoints a0 and b0 (point-point)
  kA0B1 = 1,       ///< a0 and b1
  kA1B0 = 2,       ///< a1 and b0
  kA1B1 = 3,       ///< a1 and b1
  kA0EdgeB = 4,    ///< a0 and the interior of segment b (point-line)
  kA1EdgeB = 5,    ///< a1 and the interior of b
  kB0EdgeA = 6,    ///< b0 and the interior of segment a
  kB1EdgeA = 7,    ///< b1 and the interior of a
  kInterior = 8,   ///< interiors of both segments (line-line distance)
};

/// Edges whose direction vectors satisfy |ea × eb|² <= kEdgeEdgeParallelTol |ea|² |eb|²
/// (sin² of the angle between them, i.e. angle below 1e-8 rad) are treated as parallel: the
/// line-line formula is not used and the distance comes from the four endpoint-segment pairs
/// (exact for parallel segments; for nearly parallel ones the error is at most
/// length · 1e-8). The same tolerance declares a triangle degenerate (no face region).
inline constexpr Real kEdgeEdgeParallelTol = Real(1e-16);

namespace contact_detail {

/// Cross-product matrix: skew(v) w = v × w.
GD_HD Mat3 skew(const Vec3& v) {
  Mat3 m;
  m << Real(0), -v.z(), v.y(), v.z(), Real(0), -v.x(), -v.y(), v.x(), Real(0);
  return m;
}

/// Maps derivatives with respect to NY difference vectors y_i = Σ_j C[i][j] x_j (C entries are
/// 0, ±1) to derivatives with respect to the NX vertices x_j: g_x = Cᵀ g_y, H_x = Cᵀ H_y C (3x3
/// blocks). Either output may be null; Hx is written only when Hy is non-null.
template <int NY, int NX>
GD_HD void map_derivatives(const int (&C)[NY][NX], const VecN<3 * NY>& gy, const MatN<3 * NY>* Hy,
                           VecN<3 * NX>* gx, MatN<3 * NX>* Hx) {
  if (gx) {
    gx->setZero();
    for (int i = 0; i < NY; ++i)
      for (int j = 0; j < NX; ++j)
        if (C[i][j] != 0) gx->template segment<3>(3 * j) += Real(C[i][j]) * gy.template segment<3>(3 * i);
  }
  if (Hx && Hy) {
    Hx->setZero();
    for (int i = 0; i < NY; ++i)
      for (int j = 0; j < NX; ++j) {
        if (C[i][j] == 0) continue;
        for (int k = 0; k < NY; ++k)
          for (int l = 0; l < NX; ++l) {
            if (C[k][l] == 0) continue;
            Hx->template block<3, 3>(3 * j, 3 * l) +=
                Real(C[i][j] * C[k][l]) * Hy->template block<3, 3>(3 * i, 3 * k);
          }
      }
  }
}

/// Point-point kernel f(r) = |r|²: gradient 2r, Hessian 2I.
GD_HD Real kernel_pp(const Vec3& r, VecN<3>* g, MatN<3>* H) {
  if (g) *g = Real(2) * r;
  if (H) *H = Real(2) * Mat3::Identity();
  return r.squaredNorm();
}

/// Point-line kernel f(r, e) = |r × e|²/|e|² (distance² from r to the line through 0 along e).
/// Derivatives from the equivalent form |r|² - a²/c with a = r·e, c = e·e:
///   ∂f/∂r = 2r - 2a e/c,   ∂f/∂e = -2a r/c + 2a² e/c²,
///   ∂²f/∂r² = 2I - 2 e eᵀ/c,   ∂²f/∂r∂e = -2(e rᵀ + a I)/c + 4a e eᵀ/c²,
///   ∂²f/∂e² = -2 r rᵀ/c + 4a (r eᵀ + e rᵀ)/c² + 2a² I/c² - 8a² e eᵀ/c³.
/// A zero-length e (c = 0) falls back to the point-point kernel on r (derivatives in e zero).
GD_HD Real kernel_pl(const Vec3& r, const Vec3& e, VecN<6>* g, MatN<6>* H) {
  const Real c = e.squaredNorm();
  if (!(c > Real(0))) {
    if (g) {
      g->setZero();
      g->segment<3>(0) = Real(2) * r;
    }
    if (H) {
      H->setZero();
      H->block<3, 3>(0, 0) = Real(2) * Mat3::Identity();
    }
    return r.squaredNorm();
  }
  const Real a = r.dot(e);
  const Real ic = Real(1) / c;
  if (g) {
    g->segment<3>(0) = Real(2) * r - (Real(2) * a * ic) * e;
    g->segment<3>(3) = (Real(-2) * a * ic) * r + (Real(2) * a * a * ic * ic) * e;
  }
  if (H) {
    const Mat3 I = Mat3::Identity();
    const Mat3 eeT = e * e.transpose();
    H->block<3, 3>(0, 0) = Real(2) * I - (Real(2) * ic) * eeT;
    const Mat3 Hre = (Real(-2) * ic) * (e * r.transpose() + a * I) + (Real(4) * a * ic * ic) * eeT;
    H->block<3, 3>(0, 3) = Hre;
    H->block<3, 3>(3, 0) = Hre.transpose();
    H->block<3, 3>(3, 3) = (Real(-2) * ic) * (r * r.transpose()) +
                           (Real(4) * a * ic * ic) * (r * e.transpose() + e * r.transpose()) +
                           (Real(2) * a * a * ic * ic) * I - (Real(8) * a * a * ic * ic * ic) * eeT;
  }
  return r.cross(e).squaredNorm() * ic;
}

/// q = |e1 × e2|² and its derivatives with respect to (e1, e2). With n = e1 × e2,
/// ∂n/∂e1 = -skew(e2), ∂n/∂e2 = skew(e1) =: Jn (3x6):  ∇q = 2 Jnᵀ n,
/// ∇²q = 2 Jnᵀ Jn + 2 [[0, -skew(n)], [skew(n), 0]].
GD_HD Real kernel_cross2(const Vec3& e1, const Vec3& e2, VecN<6>* g, MatN<6>* H) {
  const Vec3 n = e1.cross(e2);
  if (g || H) {
    Eigen::Matrix<Real, 3, 6> Jn;
    Jn.block<3, 3>(0, 0) = -skew(e2);
    Jn.block<3, 3>(0, 3) = skew(e1);
    if (g) *g = Real(2) * Jn.transpose() * n;
    if (H) {
      *H = Real(2) * Jn.transpose() * Jn;
      const Mat3 sn = skew(n);
      H->block<3, 3>(0, 3) -= Real(2) * sn;
      H->block<3, 3>(3, 0) += Real(2) * sn;
    }
  }
  return n.squaredNorm();
}

/// Point-plane / line-line kernel f(r, e1, e2) = s²/q, s = r·(e1 × e2) = det[r, e1, e2],
/// q = |e1 × e2|². ∇s = (e1×e2, e2×r, r×e1); ∇²s has off-diagonal blocks
/// (r,e1) = -skew(e2), (r,e2) = skew(e1), (e1,e2) = -skew(r) (and transposes). Then
///   ∇f = 2s∇s/q - s²∇q/q²,
///   ∇²f = 2∇s∇sᵀ/q + 2s∇²s/q - 2s(∇s∇qᵀ + ∇q∇sᵀ)/q² - s²∇²q/q² + 2s²∇q∇qᵀ/q³.
/// q = 0 (parallel e1, e2) is a precondition violation; it returns |r|² with zero derivatives
/// instead of NaN.
GD_HD Real kernel_plane(const Vec3& r, const Vec3& e1, const Vec3& e2, VecN<9>* g, MatN<9>* H) {
  const Vec3 n = e1.cross(e2);
  const Real q = n.squaredNorm();
  if (!(q > Real(0))) {
    if (g) g->setZero();
    if (H) H->setZero();
    return r.squaredNorm();
  }
  const Real s = r.dot(n);
  const Real iq = Real(1) / q;
  if (g || H) {
    VecN<9> gs;
    gs.segment<3>(0) = n;
    gs.segment<3>(3) = e2.cross(r);
    gs.segment<3>(6) = r.cross(e1);
    VecN<6> gq6;
    MatN<6> Hq6;
    kernel_cross2(e1, e2, &gq6, H ? &Hq6 : nullptr);
    VecN<9> gq = VecN<9>::Zero();
    gq.segment<6>(3) = gq6;
    if (g) *g = (Real(2) * s * iq) * gs - (s * s * iq * iq) * gq;
    if (H) {
      MatN<9> Hs = MatN<9>::Zero();
      Hs.block<3, 3>(0, 3) = -skew(e2);
      Hs.block<3, 3>(0, 6) = skew(e1);
      Hs.block<3, 3>(3, 6) = -skew(r);
      Hs.block<3, 3>(3, 0) = Hs.block<3, 3>(0, 3).transpose();
      Hs.block<3, 3>(6, 0) = Hs.block<3, 3>(0, 6).transpose();
      Hs.block<3, 3>(6, 3) = Hs.block<3, 3>(3, 6).transpose();
      MatN<9> Hq = MatN<9>::Zero();
      Hq.block<6, 6>(3, 3) = Hq6;
      const MatN<9> sq = gs * gq.transpose();
      *H = (Real(2) * iq) * (gs * gs.transpose()) + (Real(2) * s * iq) * Hs -
           (Real(2) * s * iq * iq) * (sq + sq.transpose()) - (s * s * iq * iq) * Hq +
           (Real(2) * s * s * iq * iq * iq) * (gq * gq.transpose());
    }
  }
  return s * s * iq;
}

/// Point-point distance² between vertices i and j of an NX-vertex element (r = x_i - x_j).
template <int NX>
GD_HD Real element_pp(const Vec3* x, int i, int j, VecN<3 * NX>* g, MatN<3 * NX>* H) {
  int C[1][NX] = {};
  C[0][i] = 1;
  C[0][j] = -1;
  VecN<3> g3;
  MatN<3> H3;
  const Real f = kernel_pp(x[i] - x[j], &g3, &H3);
  if (g || H) map_derivatives<1, NX>(C, g3, &H3, g, H);
  return f;
}

/// Distance² from vertex p to the line through vertices e0, e1 (r = x_p - x_e0, e = x_e1 - x_e0).
template <int NX>
GD_HD Real element_pl(const Vec3* x, int p, int e0, int e1, VecN<3 * NX>* g, MatN<3 * NX>* H) {
  int C[2][NX] = {};
  C[0][p] = 1;
  C[0][e0] = -1;
  C[1][e1] = 1;
  C[1][e0] += -1;
  VecN<6> g6;
  MatN<6> H6;
  const Real f = kernel_pl(x[p] - x[e0], x[e1] - x[e0], (g || H) ? &g6 : nullptr, H ? &H6 : nullptr);
  if (g || H) map_derivatives<2, NX>(C, g6, H ? &H6 : nullptr, g, H);
  return f;
}

/// Plane kernel on vertices: r = x_r0 - x_r1, e1 = x_a1 - x_a0, e2 = x_b1 - x_b0.
template <int NX>
GD_HD Real element_plane(const Vec3* x, int r0, int r1, int a0, int a1, int b0, int b1,
                         VecN<3 * NX>* g, MatN<3 * NX>* H) {
  int C[3][NX] = {};
  C[0][r0] += 1;
  C[0][r1] -= 1;
  C[1][a1] += 1;
  C[1][a0] -= 1;
  C[2][b1] += 1;
  C[2][b0] -= 1;
  VecN<9> g9;
  MatN<9> H9;
  const Real f = kernel_plane(x[r0] - x[r1], x[a1] - x[a0], x[b1] - x[b0], (g || H) ? &g9 : nullptr,
                              H ? &H9 : nullptr);
  if (g || H) map_derivatives<3, NX>(C, g9, H ? &H9 : nullptr, g, H);
  return f;
}

}  // namespace contact_detail

// ------------------------------------------------------------------------------------------------
// Point-point
// ------------------------------------------------------------------------------------------------

/// |p - q|² (m²). Gradient (p, q) = (2(p-q), -2(p-q)) (m); Hessian 2[[I, -I], [-I, I]].
/// Pointers may be null.
GD_HD Real point_point_distance2(const Vec3& p, const Vec3& q, VecN<6>* grad, MatN<6>* hess) {
  const Vec3 x[2] = {p, q};
  return contact_detail::element_pp<2>(x, 0, 1, grad, hess);
}

// ------------------------------------------------------------------------------------------------
// Point-segment
// ------------------------------------------------------------------------------------------------

/// Closest feature of the segment (e0, e1) to p: with t = (p-e0)·(e1-e0)/|e1-e0|²,
/// t <= 0 -> kVertex0, t >= 1 -> kVertex1, else kInterior. Writes the clamped parameter t in
/// [0, 1] of the closest point e0 + t (e1 - e0) when `t` is non-null. A zero-length segment gives
/// kVertex0, t = 0.
GD_HD PointSegmentRegion point_segment_closest_feature(const Vec3& p, const Vec3& e0, const Vec3& e1,
                                                       Real* t = nullptr) {
  const Vec3 e = e1 - e0;
  const Real c = e.squaredNorm();
  const Real a = (p - e0).dot(e);
  if (!(c > Real(0)) || a <= Real(0)) {
    if (t) *t = Real(0);
    return PointSegmentRegion::kVertex0;
  }
  if (a >= c) {
    if (t) *t = Real(1);
    return PointSegmentRegion::kVertex1;
  }
  if (t) *t = a / c;
  return PointSegmentRegion::kInterior;
}

/// Squared distance (m²) from p to the segment (e0, e1) evaluated with the formula of the given
/// region (point-point to e0 or e1, or point-line), with exact gradient (m) and Hessian with
/// respect to (p, e0, e1). Use it to keep a region fixed; point_segment_distance2 below
/// classifies first. Pointers may be null.
GD_HD Real point_segment_distance2(const Vec3& p, const Vec3& e0, const Vec3& e1,
                                   PointSegmentRegion region, VecN<9>* grad, MatN<9>* hess) {
  const Vec3 x[3] = {p, e0, e1};
  switch (region) {
    case PointSegmentRegion::kVertex0:
      return contact_detail::element_pp<3>(x, 0, 1, grad, hess);
    case PointSegmentRegion::kVertex1:
      return contact_detail::element_pp<3>(x, 0, 2, grad, hess);
    default:
      return contact_detail::element_pl<3>(x, 0, 1, 2, grad, hess);
  }
}

/// Squared distance (m²) from the point p to the segment (e0, e1), min over the segment, with the
/// exact gradient and Hessian of the closest feature's formula (see point_segment_closest_feature):
///   vertex:   |p - e_k|²,   interior: |(p-e0) × (e1-e0)|² / |e1-e0|².
/// Vertex order of the derivatives: p, e0, e1. Pointers may be null.
GD_HD Real point_segment_distance2(const Vec3& p, const Vec3& e0, const Vec3& e1, VecN<9>* grad,
                                   MatN<9>* hess) {
  return point_segment_distance2(p, e0, e1, point_segment_closest_feature(p, e0, e1), grad, hess);
}

// ------------------------------------------------------------------------------------------------
// Point-triangle
// ------------------------------------------------------------------------------------------------

/// Closest feature of the triangle (t0, t1, t2) to p, and (when `bary` is non-null) the
/// barycentric weights (w0, w1, w2) of the closest point c = w0 t0 + w1 t1 + w2 t2 (all in
/// [0, 1], summing to 1).
/// Classification: p is projected onto the triangle's plane; if the projection lies in the closed
/// triangle (and the triangle is not degenerate, |e1 × e2|² > kEdgeEdgeParallelTol |e1|²|e2|²),
/// the region is kFace. Otherwise the closest point lies on the boundary and the region is that of
/// the nearest of the three point-segment problems (edge interior or vertex). Ties (equal
/// distances) may be resolved either way; the distance values agree there.
GD_HD PointTriangleRegion point_triangle_closest_feature(const Vec3& p, const Vec3& t0, const Vec3& t1,
                                                         const Vec3& t2, Vec3* bary = nullptr) {
  const Vec3 e1 = t1 - t0;
  const Vec3 e2 = t2 - t0;
  const Vec3 r = p - t0;
  const Real a11 = e1.squaredNorm();
  const Real a22 = e2.squaredNorm();
  const Real a12 = e1.dot(e2);
  const Real q = e1.cross(e2).squaredNorm();  // = a11 a22 - a12² (Lagrange identity)
  if (q > kEdgeEdgeParallelTol * a11 * a22) {
    const Real r1 = e1.dot(r);
    const Real r2 = e2.dot(r);
    const Real n1 = a22 * r1 - a12 * r2;  // q * (barycentric weight of t1)
    const Real n2 = a11 * r2 - a12 * r1;  // q * (barycentric weight of t2)
    if (n1 >= Real(0) && n2 >= Real(0) && n1 + n2 <= q) {
      if (bary) {
        const Real w1 = n1 / q, w2 = n2 / q;
        *bary = Vec3(Real(1) - w1 - w2, w1, w2);
      }
      return PointTriangleRegion::kFace;
    }
  }
  // Boundary: nearest of the three edges (each classified as vertex or interior).
  const Vec3* v[3] = {&t0, &t1, &t2};
  Real best = Real(INFINITY);
  PointTriangleRegion region = PointTriangleRegion::kVertex0;
  Vec3 w = Vec3(Real(1), Real(0), Real(0));
  for (int k = 0; k < 3; ++k) {
    const int i = k, j = (k + 1) % 3;
    Real t;
    const PointSegmentRegion rs = point_segment_closest_feature(p, *v[i], *v[j], &t);
    const Vec3 c = *v[i] + t * (*v[j] - *v[i]);
    const Real d2 = (p - c).squaredNorm();
    if (d2 < best) {
      best = d2;
      w.setZero();
      if (rs == PointSegmentRegion::kVertex0) {
        region = static_cast<PointTriangleRegion>(i);
        w[i] = Real(1);
      } else if (rs == PointSegmentRegion::kVertex1) {
        region = static_cast<PointTriangleRegion>(j);
        w[j] = Real(1);
      } else {
        region = static_cast<PointTriangleRegion>(3 + k);  // kEdge01, kEdge12, kEdge20
        w[i] = Real(1) - t;
        w[j] = t;
      }
    }
  }
  if (bary) *bary = w;
  return region;
}

/// Squared distance (m²) from p to the triangle evaluated with the formula of the given region,
/// with exact gradient (m) and Hessian with respect to (p, t0, t1, t2):
///   vertex k:     |p - t_k|²
///   edge (i, j):  |(p - t_i) × (t_j - t_i)|² / |t_j - t_i|²
///   face:         ((p - t0)·n)² / |n|²,  n = (t1 - t0) × (t2 - t0)
/// Use it to keep a region fixed (e.g. during a line search); pointers may be null.
GD_HD Real point_triangle_distance2(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2,
                                    PointTriangleRegion region, VecN<12>* grad, MatN<12>* hess) {
  const Vec3 x[4] = {p, t0, t1, t2};
  using contact_detail::element_pl;
  using contact_detail::element_plane;
  using contact_detail::element_pp;
  switch (region) {
    case PointTriangleRegion::kVertex0:
      return element_pp<4>(x, 0, 1, grad, hess);
    case PointTriangleRegion::kVertex1:
      return element_pp<4>(x, 0, 2, grad, hess);
    case PointTriangleRegion::kVertex2:
      return element_pp<4>(x, 0, 3, grad, hess);
    case PointTriangleRegion::kEdge01:
      return element_pl<4>(x, 0, 1, 2, grad, hess);
    case PointTriangleRegion::kEdge12:
      return element_pl<4>(x, 0, 2, 3, grad, hess);
    case PointTriangleRegion::kEdge20:
      return element_pl<4>(x, 0, 3, 1, grad, hess);
    default:
      return element_plane<4>(x, 0, 1, 1, 2, 1, 3, grad, hess);
  }
}

/// Squared distance (m²) from the point p to the closed triangle (t0, t1, t2) (min over the
/// triangle), with the exact gradient (m) and Hessian of the closest feature's formula
/// (point_triangle_closest_feature picks the feature; see the region overload for the formulas).
/// Derivative order: p, t0, t1, t2 (xyz each). Pointers may be null.
GD_HD Real point_triangle_distance2(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2,
                                    VecN<12>* grad, MatN<12>* hess) {
  return point_triangle_distance2(p, t0, t1, t2, point_triangle_closest_feature(p, t0, t1, t2), grad,
                                  hess);
}

// ------------------------------------------------------------------------------------------------
// Edge-edge (segment-segment)
// ------------------------------------------------------------------------------------------------

/// Closest pair of features of the segments a = (a0, a1) and b = (b0, b1), and (when non-null) the
/// parameters sa, sb in [0, 1] of the closest points ca = a0 + sa (a1 - a0), cb = b0 + sb (b1 - b0).
/// Classification: if the edges are not parallel (see kEdgeEdgeParallelTol) and the unconstrained
/// closest points of the two lines lie in both closed segments, the region is kInterior (the
/// minimiser of the convex problem is interior). Otherwise the minimum lies on the boundary of the
/// parameter square, i.e. an endpoint against the other segment: the nearest of the four
/// point-segment problems decides (point-point or point-line). Parallel (and zero-length) edges
/// are thereby handled exactly.
GD_HD EdgeEdgeRegion edge_edge_closest_feature(const Vec3& a0, const Vec3& a1, const Vec3& b0,
                                               const Vec3& b1, Real* sa = nullptr, Real* sb = nullptr) {
  const Vec3 u = a1 - a0;
  const Vec3 v = b1 - b0;
  const Vec3 w = a0 - b0;
  const Real a = u.squaredNorm();
  const Real b = u.dot(v);
  const Real c = v.squaredNorm();
  const Real d = u.dot(w);
  const Real e = v.dot(w);
  const Real D = u.cross(v).squaredNorm();  // = a c - b², accurate for near-parallel edges
  if (D > kEdgeEdgeParallelTol * a * c) {
    const Real sN = b * e - c * d;  // D * sa of the lines
    const Real tN = a * e - b * d;  // D * sb of the lines
    if (sN >= Real(0) && sN <= D && tN >= Real(0) && tN <= D) {
      if (sa) *sa = sN / D;
      if (sb) *sb = tN / D;
      return EdgeEdgeRegion::kInterior;
    }
  }
  // Boundary: four endpoint-segment problems.
  Real best = Real(INFINITY);
  EdgeEdgeRegion region = EdgeEdgeRegion::kA0B0;
  Real bs = Real(0), bt = Real(0);
  const Vec3* A[2] = {&a0, &a1};
  const Vec3* B[2] = {&b0, &b1};
  for (int k = 0; k < 2; ++k) {  // endpoint a_k against segment b
    Real t;
    const PointSegmentRegion rs = point_segment_closest_feature(*A[k], b0, b1, &t);
    const Real d2 = (*A[k] - (b0 + t * v)).squaredNorm();
    if (d2 < best) {
      best = d2;
      bs = Real(k);
      bt = t;
      if (rs == PointSegmentRegion::kInterior)
        region = k == 0 ? EdgeEdgeRegion::kA0EdgeB : EdgeEdgeRegion::kA1EdgeB;
      else
        region = static_cast<EdgeEdgeRegion>(2 * k + (rs == PointSegmentRegion::kVertex1 ? 1 : 0));
    }
  }
  for (int k = 0; k < 2; ++k) {  // endpoint b_k against segment a
    Real t;
    const PointSegmentRegion rs = point_segment_closest_feature(*B[k], a0, a1, &t);
    const Real d2 = (*B[k] - (a0 + t * u)).squaredNorm();
    if (d2 < best) {
      best = d2;
      bs = t;
      bt = Real(k);
      if (rs == PointSegmentRegion::kInterior)
        region = k == 0 ? EdgeEdgeRegion::kB0EdgeA : EdgeEdgeRegion::kB1EdgeA;
      else
        region = static_cast<EdgeEdgeRegion>(2 * (rs == PointSegmentRegion::kVertex1 ? 1 : 0) + k);
    }
  }
  if (sa) *sa = bs;
  if (sb) *sb = bt;
  return region;
}

/// Squared distance (m²) between the segments evaluated with the formula of the given region,
/// with exact gradient (m) and Hessian with respect to (a0, a1, b0, b1):
///   a_i b_j:      |a_i - b_j|²
///   a_i edge b:   |(a_i - b0) × (b1 - b0)|² / |b1 - b0|²   (and symmetrically b_j edge a)
///   interior:     ((b0 - a0)·n)² / |n|²,  n = (a1 - a0) × (b1 - b0)   (line-line)
/// The interior formula requires non-parallel edges (returns |b0 - a0|² with zero derivatives for
/// exactly parallel ones). Pointers may be null.
GD_HD Real edge_edge_distance2(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1,
                               EdgeEdgeRegion region, VecN<12>* grad, MatN<12>* hess) {
  const Vec3 x[4] = {a0, a1, b0, b1};
  using contact_detail::element_pl;
  using contact_detail::element_plane;
  using contact_detail::element_pp;
  switch (region) {
    case EdgeEdgeRegion::kA0B0:
      return element_pp<4>(x, 0, 2, grad, hess);
    case EdgeEdgeRegion::kA0B1:
      return element_pp<4>(x, 0, 3, grad, hess);
    case EdgeEdgeRegion::kA1B0:
      return element_pp<4>(x, 1, 2, grad, hess);
    case EdgeEdgeRegion::kA1B1:
      return element_pp<4>(x, 1, 3, grad, hess);
    case EdgeEdgeRegion::kA0EdgeB:
      return element_pl<4>(x, 0, 2, 3, grad, hess);
    case EdgeEdgeRegion::kA1EdgeB:
      return element_pl<4>(x, 1, 2, 3, grad, hess);
    case EdgeEdgeRegion::kB0EdgeA:
      return element_pl<4>(x, 2, 0, 1, grad, hess);
    case EdgeEdgeRegion::kB1EdgeA:
      return element_pl<4>(x, 3, 0, 1, grad, hess);
    default:
      return element_plane<4>(x, 2, 0, 0, 1, 2, 3, grad, hess);
  }
}

/// Squared distance (m²) between the closed segments a = (a0, a1) and b = (b0, b1) (min over both),
/// with the exact gradient (m) and Hessian of the closest feature pair's formula
/// (edge_edge_closest_feature picks it; parallel and zero-length edges fall back to endpoint
/// formulas, which are exact there). Derivative order: a0, a1, b0, b1. Pointers may be null.
GD_HD Real edge_edge_distance2(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1,
                               VecN<12>* grad, MatN<12>* hess) {
  return edge_edge_distance2(a0, a1, b0, b1, edge_edge_closest_feature(a0, a1, b0, b1), grad, hess);
}

// ------------------------------------------------------------------------------------------------
// A cheap lower bound
// ------------------------------------------------------------------------------------------------

/// A lower bound of a pair's squared distance (m²) for one cross and one dot product: the
/// point's distance to the triangle's plane (type 0: point a, triangle b, c, d) or the distance
/// between the two edges' lines (type 1: edges (a, b) and (c, d)), which the closest points of
/// the closed triangle or segments can only exceed. Most candidate pairs of layered cloth lie
/// beyond the barrier's reach, and this tells so without the closest-feature search
/// (fold/5000: 40% of the line search's candidates). Zero (no bound) where the plane or the
/// lines are ill-conditioned, a sliver triangle or edges within ~0.06 degrees of parallel, so
/// that rounding cannot lift the bound above the distance by more than ~1e-12 of it.
GD_HD_ALWAYS_INLINE Real pair_distance2_lower_bound(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d, int type) {
  const Vec3 e1 = type == 0 ? Vec3(c - b) : Vec3(b - a);
  const Vec3 e2 = type == 0 ? Vec3(d - b) : Vec3(d - c);
  const Vec3 r = type == 0 ? Vec3(a - b) : Vec3(a - c);
  const Vec3 n = e1.cross(e2);
  const Real q = n.squaredNorm();
  if (!(q > Real(1e-6) * e1.squaredNorm() * e2.squaredNorm())) return Real(0);
  const Real s = r.dot(n);
  return s * s / q;
}

/// Whether the pair is certainly farther than `reach` (m) apart by pair_distance2_lower_bound,
/// with a relative margin of 1e-6 that rounding of the bound or of the exact distance cannot
/// cross: where it says so, the exact distance also exceeds `reach`.
GD_HD_ALWAYS_INLINE bool pair_certainly_beyond(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d, int type, Real reach) {
  return pair_distance2_lower_bound(a, b, c, d, type) > reach * reach * Real(1.000001);
}

}  // namespace gd::sim
