#pragma once
/// \file
/// Strain-rate (stiffness-proportional, Rayleigh-like) viscous damping written as quadratic
/// dissipation potentials over one implicit-Euler step, with directions lagged at step start.
/// beta (s) is the damping time: the damping stress is beta times the stiffness acting on the
/// strain rate.

#include "sim/energy/bending.h"
#include "sim/energy/stretch_shear.h"
#include "sim/types.h"

namespace gd::sim {

/// membrane_damping_energy in the (w_u, w_v) space of stretch_shear.h: the energy at the
/// deformation columns (wu, wv), and for non-null pointers its gradient (N) and constant PSD
/// Hessian (N/m, 6x6) with respect to them.
GD_HD Real membrane_damping_energy_w(const Vec3& wu, const Vec3& wv, const Vec3& wu_t, const Vec3& wv_t,
                                     const StretchShearRest& r, Real beta, Real h, VecN<6>* grad_w,
                                     MatN<6>* hess_w) {
  const Vec3 du = wu - wu_t;
  const Vec3 dv = wv - wv_t;
  const Real lu = wu_t.norm();
  const Real lv = wv_t.norm();
  const Vec3 hu = lu > Real(1e-12) ? Vec3(wu_t / lu) : Vec3(Vec3::Zero());
  const Vec3 hv = lv > Real(1e-12) ? Vec3(wv_t / lv) : Vec3(Vec3::Zero());
  const Real su = hu.dot(du);
  const Real sv = hv.dot(dv);
  const Real ss = wv_t.dot(du) + wu_t.dot(dv);
  const Real c = beta * r.area / h;
  const Real energy = Real(0.5) * c * (r.k_warp * su * su + r.k_weft * sv * sv + r.k_shear * ss * ss);
  if (grad_w) {
    grad_w->segment<3>(0) = c * (r.k_warp * su * hu + r.k_shear * ss * wv_t);
    grad_w->segment<3>(3) = c * (r.k_weft * sv * hv + r.k_shear * ss * wu_t);
  }
  if (hess_w) {
    MatN<6>& Hw = *hess_w;
    Hw.setZero();
    Hw.block<3, 3>(0, 0) = (c * r.k_warp) * (hu * hu.transpose());
    Hw.block<3, 3>(3, 3) = (c * r.k_weft) * (hv * hv.transpose());
    VecN<6> rs;
    rs.segment<3>(0) = wv_t;
    rs.segment<3>(3) = wu_t;
    Hw += (c * r.k_shear) * (rs * rs.transpose());
  }
  return energy;
}

/// Membrane damping potential of a triangle, J:
///   Δw = w(x) - w(x^t)  (per column),
///   E = beta/(2h) area [k_warp (ŵ_u^t.Δw_u)² + k_weft (ŵ_v^t.Δw_v)² + k_shear (w_v^t.Δw_u + w_u^t.Δw_v)²]
/// x0, x1, x2: positions (m); wu_t, wv_t: deformation columns at step start (deformation_columns
/// of x^t); r: the triangle's StretchShearRest (stiffness N/m, area m^2); beta (s); h (s).
/// The Hessian is beta/h times the Gauss-Newton membrane Hessian at x^t (with |w| >= 1), constant
/// and PSD (exact = projected). Gradient (N) ordered (x0, x1, x2) xyz. Pointers may be null.
GD_HD Real membrane_damping_energy(const Vec3& x0, const Vec3& x1, const Vec3& x2,
                                   const Vec3& wu_t, const Vec3& wv_t, const StretchShearRest& r,
                                   Real beta, Real h, Vec9* grad, Mat9* hess) {
  Vec3 wu;
  Vec3 wv;
  deformation_columns(x0, x1, x2, r.Dm_inv, &wu, &wv);
  VecN<6> gw;
  MatN<6> Hw;
  const Real energy = membrane_damping_energy_w(wu, wv, wu_t, wv_t, r, beta, h, grad ? &gw : nullptr,
                                                hess ? &Hw : nullptr);
  if (grad == nullptr && hess == nullptr) return energy;
  Vec3 cu;
  Vec3 cv;
  detail::membrane_weights(r.Dm_inv, &cu, &cv);
  if (grad) detail::membrane_map_gradient(cu, cv, gw.segment<3>(0), gw.segment<3>(3), grad);
  if (hess) detail::membrane_map_hessian(cu, cv, Hw, hess);
  return energy;
}

/// The constant c = beta/h area G coef² (J/rad²) of bending_damping_energy: its Hessian is
/// c ∇θ^t ∇θ^tᵀ (the solver adds it in that factored form).
GD_HD Real bending_damping_coef(const HingeRest& r, Real beta, Real h) {
  return beta * r.area * r.stiffness * r.coef * r.coef / h;
}

/// Bending damping potential of a hinge, J:
///   E = beta/(2h) area G coef² (∇θ^t . (x - x^t))²
/// x, x_t: the hinge's 4 positions stacked (x0, x1, x2, x3; m) now and at step start;
/// grad_theta_t: ∇θ at step start (1/m; dihedral_angle_derivatives of x^t); r: HingeRest (uses
/// area, stiffness G, coef; the nonlinear kappa_n term is not included); beta (s); h (s).
/// ∇θ^t.(x - x^t) is the linearised angle change over the step. Hessian (N/m) constant PSD
/// beta/h area G coef² ∇θ^t ∇θ^tᵀ (exact = projected). Pointers may be null.
GD_HD Real bending_damping_energy(const Vec12& x, const Vec12& x_t, const Vec12& grad_theta_t,
                                  const HingeRest& r, Real beta, Real h, Vec12* grad,
                                  Mat12* hess) {
  const Real c = bending_damping_coef(r, beta, h);
  const Real dth = grad_theta_t.dot(x - x_t);
  if (grad) *grad = (c * dth) * grad_theta_t;
  if (hess) *hess = c * (grad_theta_t * grad_theta_t.transpose());
  return Real(0.5) * c * dth * dth;
}

}  // namespace gd::sim
