#pragma once
/// \file
/// The IPC log barrier on a gap, shared by every contact potential (table, colliders, cloth
/// self-contact): b(g) = -kappa (g - dhat)^2 ln(g / dhat) for 0 < g < dhat, 0 for g >= dhat,
/// +inf for g <= 0. C^2 at dhat; on (0, dhat) b > 0, b' < 0 and b'' > 0.

#include <cmath>

#include "sim/types.h"

namespace gd::sim {

/// b(g) in J; writes b'(g) (N) and b''(g) (N/m) when non-null (0 for g >= dhat and g <= 0).
GD_HD Real log_barrier(Real g, Real dhat, Real kappa, Real* db, Real* d2b) {
  if (g >= dhat || !(g > Real(0))) {
    if (db) *db = Real(0);
    if (d2b) *d2b = Real(0);
    return g >= dhat ? Real(0) : Real(INFINITY);
  }
  const Real s = g - dhat;
  const Real lg = ::log(g / dhat);
  if (db) *db = -kappa * (Real(2) * s * lg + s * s / g);
  if (d2b) *d2b = -kappa * (Real(2) * lg + Real(4) * s / g - s * s / (g * g));
  return -kappa * s * s * lg;
}

}  // namespace gd::sim
