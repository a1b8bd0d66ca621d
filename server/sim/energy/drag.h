#pragma once
/// \file
/// Aerodynamic drag on a triangle, written as a dissipation potential over one implicit-Euler
/// step (velocity = (x - x_prev) / h) with lagged (step-start) normal and coefficients, so it is
/// a convex quadratic in the positions.

#include "sim/types.h"

namespace gd::sim {

/// Lagged normal drag coefficient, kg/(m^2 s):  c_n = 0.5 rho_air C_d |v_n| + c_lin
/// rho_air: air density (kg/m^3, ~1.2), cd: drag coefficient of a plate (dimensionless, ~1-2),
/// vn_abs: |normal velocity of the triangle| at step start (m/s), c_lin: linear drag, kg/(m^2 s)
/// (keeps some drag at low speed). The force per unit area is then -c_n v_n.
GD_HD Real drag_normal_coefficient(Real rho_air, Real cd, Real vn_abs, Real c_lin) {
  return Real(0.5) * rho_air * cd * vn_abs + c_lin;
}

/// Drag dissipation potential of a triangle over a step, J:
///   c(x) = (x0 + x1 + x2)/3,  Δ = c(x) - c_prev,
///   E = area/(2h) [c_n (n.Δ)² + c_t |Δ - (n.Δ) n|²]
/// x0, x1, x2: positions (m), c_prev: centroid at step start (m), n: lagged UNIT normal, area (m^2),
/// cn, ct: normal / tangential coefficients (kg/(m^2 s)), h: step (s). -∂E/∂x_i = -area/3 (c_n v_n
/// + c_t v_t) with v = Δ/h: each vertex takes a third of the drag force. Gradient (N) ordered
/// (x0, x1, x2) xyz; Hessian (N/m) constant and PSD (exact = projected): block (i, j) =
/// area/(9h) [c_n n nᵀ + c_t (I - n nᵀ)]. Pointers may be null.
GD_HD Real drag_energy(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& c_prev,
                       const Vec3& n, Real area, Real cn, Real ct, Real h, Vec9* grad,
                       Mat9* hess) {
  const Vec3 delta = (x0 + x1 + x2) / Real(3) - c_prev;
  const Real dn = n.dot(delta);
  const Vec3 dt = delta - dn * n;
  const Real s = area / h;
  const Real energy = Real(0.5) * s * (cn * dn * dn + ct * dt.squaredNorm());
  if (grad) {
    const Vec3 g = (s / Real(3)) * (cn * dn * n + ct * dt);
    for (int i = 0; i < 3; ++i) grad->segment<3>(3 * i) = g;
  }
  if (hess) {
    const Mat3 P = n * n.transpose();
    const Mat3 B = (s / Real(9)) * (cn * P + ct * (Mat3::Identity() - P));
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) hess->block<3, 3>(3 * i, 3 * j) = B;
  }
  return energy;
}

}  // namespace gd::sim
