#pragma once
/// \file
/// Mass-proportional (Rayleigh alpha) damping as a dissipation potential over one implicit step:
/// E = alpha m / (2h) |x - x_t|^2, i.e. a force -alpha m v with v = (x - x_t)/h. It also damps
/// rigid motion, so the default is zero; air drag (drag.h) is the physical alternative.

#include "sim/types.h"

namespace gd::sim {

/// Value of the mass-damping potential of one vertex; gradient and (constant, PSD) Hessian
/// diagonal written when the pointers are non-null. alpha in 1/s, mass in kg, h in s.
GD_HD Real mass_damping_energy(const Vec3& x, const Vec3& x_t, Real mass, Real alpha, Real h,
                               Vec3* grad, Real* hess_diag) {
  const Real c = alpha * mass / h;
  const Vec3 d = x - x_t;
  if (grad) *grad = c * d;
  if (hess_diag) *hess_diag = c;
  return 0.5 * c * d.squaredNorm();
}

}  // namespace gd::sim
