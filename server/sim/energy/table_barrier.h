#pragma once
/// \file
/// IPC log barrier keeping a vertex above a plane (the table): {p : n.p = offset}, n unit.

#include <cmath>

#include "sim/energy/log_barrier.h"
#include "sim/types.h"

namespace gd::sim {

/// The barrier of the distance d to the plane (log_barrier.h).
GD_HD Real plane_barrier_function(Real d, Real dhat, Real kappa, Real* db, Real* d2b) {
  return log_barrier(d, dhat, kappa, db, d2b);
}

/// Barrier energy of a vertex against the plane n.p = offset (n unit, pointing to the free side),
/// J:  d = n.x - offset,  E = b(d) (see plane_barrier_function; dhat in m, kappa in J/m² = N/m
/// since b ~ kappa d²). Returns +INFINITY for d <= 0 (the line search must reject such
/// a step; gradient and Hessian are then written as 0). Gradient (N) b'(d) n; Hessian (N/m)
/// b''(d) n nᵀ, PSD on the whole domain (exact = projected). Pointers may be null.
GD_HD Real plane_barrier_energy(const Vec3& x, const Vec3& n, Real offset, Real dhat, Real kappa,
                                Vec3* grad, Mat3* hess) {
  const Real d = n.dot(x) - offset;
  Real db;
  Real d2b;
  const Real energy = plane_barrier_function(d, dhat, kappa, &db, &d2b);
  if (grad) *grad = db * n;
  if (hess) *hess = d2b * (n * n.transpose());
  return energy;
}

/// Contact force magnitude of the barrier at distance d (N): -b'(d) >= 0; 0 for d >= dhat and
/// +INFINITY for d <= 0 (callers lagging the friction normal force must only use d > 0).
GD_HD Real plane_barrier_force_magnitude(Real d, Real dhat, Real kappa) {
  if (!(d > Real(0))) return Real(INFINITY);
  Real db;
  plane_barrier_function(d, dhat, kappa, &db, nullptr);
  return -db;
}

}  // namespace gd::sim
