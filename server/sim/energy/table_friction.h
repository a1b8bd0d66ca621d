#pragma once
/// \file
/// Lagged, smoothed Coulomb friction of a vertex sliding on a plane (IPC friction potential).

#include <cmath>

#include <Eigen/Geometry>  // cross()

#include "sim/types.h"

namespace gd::sim {

/// 3x2 tangent basis of a plane with unit normal n: columns t1, t2 orthonormal, orthogonal to n,
/// with (t1, t2, n) right-handed (t2 = n x t1). Continuous except where the reference axis
/// switches (|n_x| = 0.9); only ever evaluated once per lagged contact, so this is harmless.
GD_HD void plane_tangent_basis(const Vec3& n, Eigen::Matrix<Real, 3, 2>* T) {
  const Vec3 ref = fabs(n.x()) < Real(0.9) ? Vec3(Vec3::UnitX()) : Vec3(Vec3::UnitY());
  const Vec3 t1 = (ref - ref.dot(n) * n).normalized();
  const Vec3 t2 = n.cross(t1);
  T->col(0) = t1;
  T->col(1) = t2;
}

/// Smoothed friction potential of a vertex, J:
///   u = Tᵀ (x - x_t)  (tangential slip over the step, m),  y = |u|,
///   f0(y) = -y³/(3 eps²) + y²/eps + eps/3  for y < eps,  y otherwise,
///   E = mu lambda f0(y)
/// x, x_t: position now and at step start (m); T: tangent basis (plane_tangent_basis); mu:
/// friction coefficient; lambda: lagged normal force (N; plane_barrier_force_magnitude at x_t);
/// eps = eps_v h > 0 (m): slip below which friction is smoothed to static-like viscous behaviour.
/// Gradient (N) mu lambda f1(y) T û with f1 = f0' (= 1 when y >= eps, so the friction force has
/// magnitude mu lambda when sliding; 0 at y = 0). Hessian (N/m)
///   T mu lambda [f1'(y) ûûᵀ + (f1(y)/y)(I - ûûᵀ)] Tᵀ   (limit 2/eps I at y = 0),
/// PSD everywhere (exact = projected). Pointers may be null.
GD_HD Real plane_friction_energy(const Vec3& x, const Vec3& x_t,
                                 const Eigen::Matrix<Real, 3, 2>& T, Real mu, Real lambda,
                                 Real eps, Vec3* grad, Mat3* hess) {
  const Vec2 u = T.transpose() * (x - x_t);
  const Real y = u.norm();
  const Real c = mu * lambda;
  const bool smooth = y < eps;
  Real f0;
  Real f1;        // f0'(y)
  Real df1;       // f1'(y)
  Real f1_over_y; // f1(y)/y, finite limit 2/eps at y = 0
  if (smooth) {
    const Real q = y / eps;
    f0 = -y * q * q / Real(3) + y * q + eps / Real(3);
    f1 = -q * q + Real(2) * q;
    df1 = (Real(2) - Real(2) * q) / eps;
    f1_over_y = (Real(2) - q) / eps;
  } else {
    f0 = y;
    f1 = Real(1);
    df1 = Real(0);
    f1_over_y = y > Real(0) ? Real(1) / y : Real(0);  // y = 0 here only if eps <= 0
  }
  const Vec2 uh = y > Real(0) ? Vec2(u / y) : Vec2(Vec2::Zero());
  if (grad) *grad = T * ((c * f1) * uh);
  if (hess) {
    const Eigen::Matrix<Real, 2, 2> P = uh * uh.transpose();
    const Eigen::Matrix<Real, 2, 2> Hu =
        c * (df1 * P + f1_over_y * (Eigen::Matrix<Real, 2, 2>::Identity() - P));
    // At y = 0, uh = 0 and P = 0, leaving the isotropic limit c (2/eps) I.
    *hess = T * Hu * T.transpose();
  }
  return c * f0;
}

}  // namespace gd::sim
