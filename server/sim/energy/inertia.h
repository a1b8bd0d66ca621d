#pragma once
/// \file
/// Inertia term of the implicit-Euler incremental potential for one lumped vertex mass.

#include "sim/types.h"

namespace gd::sim {

/// Inertia energy of a vertex, J:  E = m / (2 h²) |x - x_hat|²
/// x: position (m), x_hat: predicted position x^t + h v^t (m), mass (kg), h: time step (s).
/// Gradient (N) m/h² (x - x_hat) and Hessian (N/m) m/h² I are written when the pointers are
/// non-null (constant PSD: exact = projected).
GD_HD Real inertia_energy(const Vec3& x, const Vec3& x_hat, Real mass, Real h, Vec3* grad,
                          Mat3* hess) {
  const Real c = mass / (h * h);
  const Vec3 d = x - x_hat;
  if (grad) *grad = c * d;
  if (hess) *hess = c * Mat3::Identity();
  return Real(0.5) * c * d.squaredNorm();
}

}  // namespace gd::sim
