#pragma once
// Solver settings under which a step's result does not depend on the linear solver's path (the
// order of additions, the preconditioner): PCG to a relative residual of 1e-11 and Newton to
// 1e-8 m/s, the residual stopping rule off. Tests that compare backends or code paths step by
// step use them.
#include "sim/solver/options.h"

namespace gd::sim::test {

inline SceneOptions tight_solve(SceneOptions o = {}) {
  o.pcg_tol = 1e-11;
  o.pcg_max_iters = 5000;
  o.pcg_newton_fraction = 0;
  o.newton_max_iters = 20;
  o.newton_tol = 1e-8;
  o.newton_rtol = o.newton_atol = 0;
  return o;
}

}  // namespace gd::sim::test
