#pragma once
/// \file
/// Gravitational potential energy of one lumped vertex mass.

#include "sim/types.h"

namespace gd::sim {

/// Gravity potential of a vertex, J:  E = -m g.x
/// x: position (m), mass: lumped vertex mass (kg), g: gravitational acceleration (m/s^2, e.g.
/// (0, 0, -kGravity) for z-up). Gradient (N) -m g written when `grad` is non-null; the Hessian is
/// identically zero (none is produced).
GD_HD Real gravity_energy(const Vec3& x, Real mass, const Vec3& g, Vec3* grad) {
  if (grad) *grad = -mass * g;
  return -mass * g.dot(x);
}

}  // namespace gd::sim
