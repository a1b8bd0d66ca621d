#pragma once
/// \file
/// Nonlinear dihedral-angle hinge bending of two triangles sharing an edge.
///
/// Vertex order: x0, x1 = the shared edge; x2 = opposite vertex of triangle (x0, x1, x2);
/// x3 = opposite vertex of triangle (x1, x0, x3). Both triangles are listed with the same
/// orientation, so their normals n1 = (x1-x0)x(x2-x0) and n2 = (x0-x1)x(x3-x1) agree when flat.
///
/// Signed dihedral angle: with e = x1-x0, a = x2-x0, b = x3-x0,
///   n1 = e x a,  n2 = b x e,
///   X = n1.n2 = (e.b)(a.e) - (e.e)(a.b),   Y = (n1 x n2).ê = -|e| e.(a x b),
///   θ = atan2(Y, X) in (-π, π]
/// i.e. θ is the angle that rotates n1 onto n2 about ê = e/|e| (right-hand rule). θ = 0 when flat.
/// θ > 0 when the hinge is convex seen from the side the normals point to (a "mountain": the
/// wings x2, x3 fall away from the normals, normals diverge); θ < 0 when it is concave (a "valley":
/// the wings rise towards the normals). Example: x0 = 0, x1 = (1,0,0), x2 = (0,1,0):
/// x3 = (0,0,-1) gives θ = +π/2, x3 = (0,0,1) gives θ = -π/2, x3 = (0,-1,0) gives θ = 0.
/// θ is not unwrapped: folding through ±π (the two wings passing through each other) jumps by 2π.

#include <cmath>

#include <Eigen/Geometry>  // cross()

#include "sim/types.h"

namespace gd::sim {

/// Rest data of one hinge. The hinge curvature is κ = coef * (θ - θ0) (1/m).
struct HingeRest {
  Real theta0;     ///< rest dihedral angle, rad (0 for a flat pattern)
  Real coef;       ///< sqrt(3) |e_rest| / (A1 + A2), 1/m: use hinge_rest_coef (see there)
  Real area;       ///< (A1 + A2) / 3, m^2: the area the hinge stands for
  Real stiffness;  ///< bending stiffness G, N·m
  Real kappa_n;    ///< curvature at which the bending moment has doubled, 1/m; <= 0: linear
  /// Internal friction (bending_friction.h): the slider's limit moment per unit length, N
  /// (KES 2HB / 2); 0: none.
  Real friction_moment = 0;
  Real friction_stiffness = 0;  ///< the friction element's spring, N·m (M / its slip curvature)
};

namespace detail {

/// Cross-product matrix: skew(v) w = v x w.
GD_HD Mat3 skew(const Vec3& v) {
  Mat3 m;
  m << Real(0), -v.z(), v.y(), v.z(), Real(0), -v.x(), -v.y(), v.x(), Real(0);
  return m;
}

/// True when the hinge is too degenerate for a meaningful angle: zero-length edge, or a wing whose
/// opposite vertex is (relatively, sin < 1e-10) collinear with the edge.
GD_HD bool hinge_degenerate(const Vec3& e, const Vec3& a, const Vec3& b) {
  const Real ee = e.squaredNorm();
  if (!(ee > Real(1e-300))) return true;
  const Real tol2 = Real(1e-20);
  const Real n1 = e.cross(a).squaredNorm();
  const Real n2 = b.cross(e).squaredNorm();
  if (!(n1 > tol2 * ee * a.squaredNorm())) return true;
  if (!(n2 > tol2 * ee * b.squaredNorm())) return true;
  return false;
}

/// Maps a gradient with respect to (e, a, b) to (x0, x1, x2, x3): e = x1-x0, a = x2-x0, b = x3-x0.
GD_HD void hinge_map_gradient(const Vec9& g9, Vec12* g12) {
  g12->segment<3>(3) = g9.segment<3>(0);
  g12->segment<3>(6) = g9.segment<3>(3);
  g12->segment<3>(9) = g9.segment<3>(6);
  g12->segment<3>(0) = -(g9.segment<3>(0) + g9.segment<3>(3) + g9.segment<3>(6));
}

/// Maps a Hessian with respect to (e, a, b) to (x0, x1, x2, x3): H12 = Jᵀ H9 J with the constant
/// Jacobian J = [[-I, I, 0, 0], [-I, 0, I, 0], [-I, 0, 0, I]].
GD_HD void hinge_map_hessian(const Mat9& H9, Mat12* H12) {
  // M = H9 J (9x12): column block 0 = -(sum of column blocks of H9), block j = H9 column block j-1.
  Eigen::Matrix<Real, 9, 12> M;
  M.block<9, 3>(0, 3) = H9.block<9, 3>(0, 0);
  M.block<9, 3>(0, 6) = H9.block<9, 3>(0, 3);
  M.block<9, 3>(0, 9) = H9.block<9, 3>(0, 6);
  M.block<9, 3>(0, 0) = -(H9.block<9, 3>(0, 0) + H9.block<9, 3>(0, 3) + H9.block<9, 3>(0, 6));
  // H12 = Jᵀ M: row block 0 = -(sum of row blocks of M), row block i = M row block i-1.
  H12->block<3, 12>(3, 0) = M.block<3, 12>(0, 0);
  H12->block<3, 12>(6, 0) = M.block<3, 12>(3, 0);
  H12->block<3, 12>(9, 0) = M.block<3, 12>(6, 0);
  H12->block<3, 12>(0, 0) = -(M.block<3, 12>(0, 0) + M.block<3, 12>(3, 0) + M.block<3, 12>(6, 0));
}

/// θ and (optionally) its exact gradient and Hessian with respect to (x0..x3). Returns false (and
/// θ = 0, zero derivatives) for a degenerate hinge.
GD_HD bool hinge_angle(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3, Real* theta,
                       Vec12* grad, Mat12* hess) {
  const Vec3 e = x1 - x0;
  const Vec3 a = x2 - x0;
  const Vec3 b = x3 - x0;
  if (hinge_degenerate(e, a, b)) {
    *theta = Real(0);
    if (grad) grad->setZero();
    if (hess) hess->setZero();
    return false;
  }
  const Real ee = e.dot(e);
  const Real ab = a.dot(b);
  const Real ae = a.dot(e);
  const Real eb = e.dot(b);
  const Real L = sqrt(ee);
  const Vec3 axb = a.cross(b);
  const Real T = e.dot(axb);  // det[e, a, b]
  const Real X = eb * ae - ee * ab;
  const Real Y = -L * T;
  *theta = atan2(Y, X);
  if (grad == nullptr && hess == nullptr) return true;

  // Gradients with respect to (e, a, b).
  Vec9 gX;
  gX.segment<3>(0) = ae * b + eb * a - (Real(2) * ab) * e;
  gX.segment<3>(3) = eb * e - ee * b;
  gX.segment<3>(6) = ae * e - ee * a;
  Vec9 gT;
  gT.segment<3>(0) = axb;
  gT.segment<3>(3) = b.cross(e);
  gT.segment<3>(6) = e.cross(a);
  Vec9 gL = Vec9::Zero();
  gL.segment<3>(0) = e / L;
  const Vec9 gY = -(L * gT + T * gL);

  const Real r2 = X * X + Y * Y;  // = |n1|^2 |n2|^2 > 0 (not degenerate)
  const Vec9 num = X * gY - Y * gX;
  if (grad) hinge_map_gradient(num / r2, grad);
  if (hess == nullptr) return true;

  const Mat3 I = Mat3::Identity();
  Mat9 HX = Mat9::Zero();
  HX.block<3, 3>(0, 0) = b * a.transpose() + a * b.transpose() - (Real(2) * ab) * I;
  HX.block<3, 3>(0, 3) = b * e.transpose() + eb * I - Real(2) * e * b.transpose();
  HX.block<3, 3>(0, 6) = ae * I + a * e.transpose() - Real(2) * e * a.transpose();
  HX.block<3, 3>(3, 6) = e * e.transpose() - ee * I;
  HX.block<3, 3>(3, 0) = HX.block<3, 3>(0, 3).transpose();
  HX.block<3, 3>(6, 0) = HX.block<3, 3>(0, 6).transpose();
  HX.block<3, 3>(6, 3) = HX.block<3, 3>(3, 6).transpose();

  Mat9 HT = Mat9::Zero();
  HT.block<3, 3>(0, 3) = -skew(b);
  HT.block<3, 3>(0, 6) = skew(a);
  HT.block<3, 3>(3, 6) = -skew(e);
  HT.block<3, 3>(3, 0) = skew(b);
  HT.block<3, 3>(6, 0) = -skew(a);
  HT.block<3, 3>(6, 3) = skew(e);

  Mat9 HL = Mat9::Zero();
  const Vec3 eh = e / L;
  HL.block<3, 3>(0, 0) = (I - eh * eh.transpose()) / L;

  const Mat9 HY = -(T * HL + gL * gT.transpose() + gT * gL.transpose() + L * HT);

  Mat9 H9 = (X * HY - Y * HX + gY * gX.transpose() - gX * gY.transpose()) / r2 -
            (num * (Real(2) * X * gX + Real(2) * Y * gY).transpose()) / (r2 * r2);
  H9 = Real(0.5) * (H9 + H9.transpose()).eval();
  hinge_map_hessian(H9, hess);
  return true;
}

}  // namespace detail

/// Signed dihedral angle θ (rad) of the hinge (x0, x1 | x2, x3); see the file comment for the
/// vertex order and sign convention. Returns 0 for a degenerate hinge.
GD_HD Real dihedral_angle(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3) {
  Real theta;
  detail::hinge_angle(x0, x1, x2, x3, &theta, nullptr, nullptr);
  return theta;
}

/// Signed dihedral angle θ (rad) and, for non-null pointers, its exact gradient (1/m, ordered
/// x0, x1, x2, x3 each xyz) and exact Hessian (1/m^2). Derived by the chain rule from closed-form
/// derivatives of X and Y with respect to (e, a, b) and the atan2 rule
///   ∇θ = (X∇Y - Y∇X)/r²,  Hθ = [X HY - Y HX + ∇Y∇Xᵀ - ∇X∇Yᵀ]/r² - (X∇Y - Y∇X)(2X∇X + 2Y∇Y)ᵀ/r⁴,
/// r² = X² + Y². Degenerate hinges give θ = 0 and zero derivatives.
GD_HD Real dihedral_angle_derivatives(const Vec3& x0, const Vec3& x1, const Vec3& x2,
                                      const Vec3& x3, Vec12* grad, Mat12* hess) {
  Real theta;
  detail::hinge_angle(x0, x1, x2, x3, &theta, grad, hess);
  return theta;
}

/// Rest coefficients of a hinge from rest positions X0..X3 (same vertex order as the energy; m):
/// A1 = |(X1-X0)x(X2-X0)|/2, A2 = |(X0-X1)x(X3-X1)|/2; returns coef = sqrt(3)|X1-X0|/(A1+A2) (1/m)
/// and writes *area = (A1+A2)/3 (m^2) when non-null. Degenerate input (A1+A2 = 0) gives coef = 0
/// and area = 0.
///
/// Calibration: the factor sqrt(3) (not sqrt(6), which gives the hinge weight G|e|²/(A1+A2))
/// makes the linear part of bending_energy reproduce the continuum (G/2) κ² per unit area
/// when a fine equilateral mesh is bent isometrically onto a cylinder (vertices on the cylinder),
/// which is how cloth bends; measured ratio 1.000 at every in-plane orientation (tests/sim/energy/
/// bending_test.cpp). With sqrt(6) the same test gives exactly 2x. The calibration is mesh
/// dependent: right-isosceles (split-quad) meshes give 1x to 3x depending on orientation, and a
/// 15%-jittered equilateral mesh about +4%. The hinge curvature κ is not the local continuum
/// curvature: on the isometric cylinder the curvature concentrates on some hinges (for bending
/// across a row of edges, κ_hinge = sqrt(3)/R on those edges and 0 on the others), so the
/// quartic kappa_n term of bending_energy comes out 1.2x to 3x its continuum value
/// A G κ⁴/(4 kappa_n²) on an equilateral mesh, depending on the bending direction.
GD_HD Real hinge_rest_coef(Real edge_length, Real a1, Real a2, Real* area) {
  const Real sum = a1 + a2;
  if (!(sum > Real(0))) {
    if (area) *area = Real(0);
    return Real(0);
  }
  if (area) *area = sum / Real(3);
  return sqrt(Real(3)) * edge_length / sum;
}

/// hinge_rest_coef from the rest positions of the hinge's four vertices.
GD_HD Real hinge_rest_coef(const Vec3& X0, const Vec3& X1, const Vec3& X2, const Vec3& X3,
                           Real* area) {
  const Real a1 = Real(0.5) * (X1 - X0).cross(X2 - X0).norm();
  const Real a2 = Real(0.5) * (X0 - X1).cross(X3 - X1).norm();
  return hinge_rest_coef((X1 - X0).norm(), a1, a2, area);
}

/// hinge_rest_coef for 2D pattern (rest) coordinates (m), embedded in the z = 0 plane.
GD_HD Real hinge_rest_coef(const Vec2& X0, const Vec2& X1, const Vec2& X2, const Vec2& X3,
                           Real* area) {
  return hinge_rest_coef(Vec3(X0.x(), X0.y(), Real(0)), Vec3(X1.x(), X1.y(), Real(0)),
                         Vec3(X2.x(), X2.y(), Real(0)), Vec3(X3.x(), X3.y(), Real(0)), area);
}

namespace detail {

/// The bending energy's scalar part as a function of θ: returns E and writes dE/dθ and d²E/dθ²
/// (d²E > 0: the Gauss-Newton factor).
GD_HD Real bending_of_theta(const HingeRest& r, Real theta, Real* dE, Real* d2E) {
  const Real inv_kn2 = r.kappa_n > Real(0) ? Real(1) / (r.kappa_n * r.kappa_n) : Real(0);
  const Real K = r.area * r.stiffness;
  const Real kappa = r.coef * (theta - r.theta0);
  const Real k2 = kappa * kappa;
  *dE = K * r.coef * kappa * (Real(1) + k2 * inv_kn2);
  *d2E = K * r.coef * r.coef * (Real(1) + Real(3) * k2 * inv_kn2);
  return K * (Real(0.5) * k2 + Real(0.25) * k2 * k2 * inv_kn2);
}

}  // namespace detail

/// Nonlinear hinge bending energy, J:
///   κ = coef (θ - θ0),   E = area G (κ²/2 + κ⁴/(4 κn²))
/// so the bending moment per unit length is G κ (1 + (κ/κn)²). kappa_n <= 0 drops the quartic
/// term (linear bending). Vertex order x0, x1 (edge), x2, x3 (wings); gradient (N) ordered
/// (x0, x1, x2, x3) xyz. Hessian (N/m), written when non-null and kind != kNone:
///  - kExact: E''(θ)∇θ∇θᵀ + E'(θ)Hθ;
///  - kProjected: Gauss-Newton E''(θ)∇θ∇θᵀ (PSD: E'' = area G coef² (1 + 3κ²/κn²) > 0).
/// Degenerate hinges (zero-length edge, collinear wing) contribute 0 energy and 0 derivatives.
GD_HD Real bending_energy(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3,
                          const HingeRest& r, Vec12* grad, Mat12* hess, HessianKind kind) {
  const bool want_hess = hess != nullptr && kind != HessianKind::kNone;
  const bool want_theta_hess = want_hess && kind == HessianKind::kExact;
  Vec12 gth;
  Mat12 Hth;
  Real theta;
  const bool ok = detail::hinge_angle(x0, x1, x2, x3, &theta,
                                      (grad != nullptr || want_hess) ? &gth : nullptr,
                                      want_theta_hess ? &Hth : nullptr);
  if (!ok) {
    if (grad) grad->setZero();
    if (want_hess) hess->setZero();
    return Real(0);
  }
  Real dE, d2E;
  const Real energy = detail::bending_of_theta(r, theta, &dE, &d2E);
  if (grad) *grad = dE * gth;
  if (want_hess) {
    *hess = d2E * (gth * gth.transpose());
    if (want_theta_hess) *hess += dE * Hth;
  }
  return energy;
}

/// bending_energy with its Gauss-Newton (kProjected) Hessian in factored form, the form the
/// solver assembles from: Hessian = *hess_coef ∇θ ∇θᵀ with ∇θ written to *grad_theta (a
/// rank-one 12x12 matrix added block by block without being formed). grad may be null;
/// grad_theta and hess_coef may not. Degenerate hinges: 0 energy, zero ∇θ and coefficient.
/// theta_out, when non-null, receives θ (0 for a degenerate hinge).
GD_HD Real bending_energy_rank1(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3,
                                const HingeRest& r, Vec12* grad, Vec12* grad_theta, Real* hess_coef,
                                Real* theta_out = nullptr) {
  Real theta;
  const bool ok = detail::hinge_angle(x0, x1, x2, x3, &theta, grad_theta, nullptr);
  if (theta_out) *theta_out = theta;
  if (!ok) {
    if (grad) grad->setZero();
    *hess_coef = Real(0);
    return Real(0);
  }
  Real dE;
  const Real energy = detail::bending_of_theta(r, theta, &dE, hess_coef);
  if (grad) *grad = dE * *grad_theta;
  return energy;
}

}  // namespace gd::sim
