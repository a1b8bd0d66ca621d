#pragma once
/// \file
/// Internal friction in bending: the hysteresis of a woven fabric's moment-curvature loop
/// (Kawabata's KES-FB2 pure-bending test reports it as 2HB, the loop's width in moment per unit
/// length). Between yarns that slide on each other a bent fabric keeps part of its bend when the
/// load is taken off, and a bend is resisted by more than the elastic moment while it grows.
///
/// Model (per hinge, in parallel with the elastic hinge of bending.h): a stiff spring in series
/// with a Coulomb slider (the Dahl / Lahey-Heppler element in its rate-independent limit). The
/// slider's angle θf is the state; the spring carries the moment per unit length
///   m = kf κf,  κf = coef (θ - θf),  |m| <= M = 2HB / 2,
/// and the slider slips (θf follows θ) wherever |m| would exceed M. A time step of implicit Euler
/// minimises, for θf at the step's start, the incremental potential
///   Ψ(θ) = area ψ(κf),  ψ(δ) = kf δ²/2 for |δ| <= δy = M/kf, else M|δ| - M δy / 2
/// (the minimum over the slider's new angle of the spring's energy plus the slider's dissipated
/// work M |Δκ|: a Huber function, convex and C¹), so the step is backward Euler for the slider
/// too; after the step bending_friction_slip moves θf to where the spring's moment is ψ'(κf).
/// Over a closed bending cycle the element dissipates 2M per unit of curvature travelled twice:
/// the loop's width at every curvature beyond 2δy from its reversals is 2M = 2HB.
///
/// Vertex order and θ as in bending.h. HingeRest::friction_moment (M, N: moment per unit length)
/// and HingeRest::friction_stiffness (kf, N·m) set the element; M = 0 turns it off (energy 0).

#include "sim/energy/bending.h"

namespace gd::sim {

namespace detail {

/// ψ(κf) times the hinge's area as a function of θ: returns it and writes dΨ/dθ and d²Ψ/dθ²
/// (>= 0: 0 where the slider slips).
GD_HD Real bending_friction_of_theta(const HingeRest& r, Real theta, Real theta_f, Real* dE, Real* d2E) {
  if (!(r.friction_moment > Real(0)) || !(r.friction_stiffness > Real(0))) {
    *dE = Real(0);
    *d2E = Real(0);
    return Real(0);
  }
  const Real M = r.friction_moment, k = r.friction_stiffness;
  const Real delta = r.coef * (theta - theta_f);
  const Real dy = M / k;
  if (fabs(delta) <= dy) {
    *dE = r.area * k * delta * r.coef;
    *d2E = r.area * k * r.coef * r.coef;
    return r.area * Real(0.5) * k * delta * delta;
  }
  const Real s = delta > Real(0) ? Real(1) : Real(-1);
  *dE = r.area * M * s * r.coef;
  *d2E = Real(0);
  return r.area * (M * fabs(delta) - Real(0.5) * M * dy);
}

}  // namespace detail

/// The friction element's incremental potential Ψ (J) for the slider at θf (rad), with gradient
/// (N, x0..x3 xyz) and Hessian (N/m) when non-null: kExact ψ''∇θ∇θᵀ + ψ'Hθ, kProjected the
/// Gauss-Newton ψ''∇θ∇θᵀ (PSD). Degenerate hinges and M = 0 give 0 and zero derivatives.
GD_HD Real bending_friction_energy(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Vec3& x3,
                                   const HingeRest& r, Real theta_f, Vec12* grad, Mat12* hess, HessianKind kind) {
  const bool want_hess = hess != nullptr && kind != HessianKind::kNone;
  const bool want_theta_hess = want_hess && kind == HessianKind::kExact;
  Vec12 gth;
  Mat12 Hth;
  Real theta;
  const bool off = !(r.friction_moment > Real(0));
  if (off || !detail::hinge_angle(x0, x1, x2, x3, &theta, (grad != nullptr || want_hess) ? &gth : nullptr,
                                  want_theta_hess ? &Hth : nullptr)) {
    if (grad) grad->setZero();
    if (want_hess) hess->setZero();
    return Real(0);
  }
  Real dE, d2E;
  const Real energy = detail::bending_friction_of_theta(r, theta, theta_f, &dE, &d2E);
  if (grad) *grad = dE * gth;
  if (want_hess) {
    *hess = d2E * (gth * gth.transpose());
    if (want_theta_hess) *hess += dE * Hth;
  }
  return energy;
}

/// The slider's angle after a step that ended at θ (rad), from θf at its start: unchanged while
/// the spring's moment is within M, else moved so that it is ±M (θ - θf = ±δy / coef).
GD_HD Real bending_friction_slip(const HingeRest& r, Real theta, Real theta_f) {
  if (!(r.friction_moment > Real(0)) || !(r.friction_stiffness > Real(0)) || !(r.coef > Real(0))) return theta_f;
  const Real dy = r.friction_moment / r.friction_stiffness;
  const Real delta = r.coef * (theta - theta_f);
  if (fabs(delta) <= dy) return theta_f;
  return theta - (delta > Real(0) ? dy : -dy) / r.coef;
}

/// The energy the friction element's spring stores with the slider at θf (J): area kf κf²/2 with
/// κf within the slider's reach (after bending_friction_slip); for energy reports.
GD_HD Real bending_friction_stored(const HingeRest& r, Real theta, Real theta_f) {
  if (!(r.friction_moment > Real(0)) || !(r.friction_stiffness > Real(0))) return Real(0);
  const Real dy = r.friction_moment / r.friction_stiffness;
  Real delta = r.coef * (theta - theta_f);
  delta = delta > dy ? dy : (delta < -dy ? -dy : delta);
  return r.area * Real(0.5) * r.friction_stiffness * delta * delta;
}

}  // namespace gd::sim
