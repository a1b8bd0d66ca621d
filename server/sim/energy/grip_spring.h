#pragma once
/// \file
/// Grip spring of one held (grasped) vertex: pulls it towards its gripper target with stiffness
/// k until the pull reaches the grip's force limit, then with that constant force (the grip
/// stalls instead of pulling harder). A gripper whose target runs into the table or through
/// other cloth then presses with a bounded force that the contact barriers can hold.

#include <cmath>

#include "sim/types.h"

namespace gd::sim {

/// Grip spring energy, J, of a vertex at x held towards `target` (both m) with stiffness k (N/m)
/// and force limit f_max (N, > 0; INFINITY for a plain spring). With r = |x - target| and
/// r0 = f_max / k:
///   E = k r^2 / 2                 for r <= r0,
///   E = f_max (r - r0 / 2)        beyond (C1 at r0: both pull with f_max there).
/// Gradient (N) k (x - target), or f_max n beyond (n the unit vector from target to x).
/// Hessian (N/m): k I, or beyond the exact f_max / r (I - n n^T), which is PSD already (no
/// stiffness along n: the vertex's own inertia term keeps the Newton system definite).
GD_HD Real grip_spring_energy(const Vec3& x, const Vec3& target, Real k, Real f_max, Vec3* grad, Mat3* hess) {
  const Vec3 d = x - target;
  const Real r2 = d.squaredNorm();
  const Real r0 = f_max / k;
  if (r2 <= r0 * r0) {
    if (grad) *grad = k * d;
    if (hess) *hess = k * Mat3::Identity();
    return Real(0.5) * k * r2;
  }
  const Real r = sqrt(r2);
  const Vec3 n = d / r;
  if (grad) *grad = f_max * n;
  if (hess) *hess = (f_max / r) * (Mat3::Identity() - n * n.transpose());
  return f_max * (r - Real(0.5) * r0);
}

/// Magnitude of the grip spring's pull, N: min(k r, f_max).
GD_HD Real grip_spring_force(const Vec3& x, const Vec3& target, Real k, Real f_max) {
  return fmin(k * (x - target).norm(), f_max);
}

}  // namespace gd::sim
