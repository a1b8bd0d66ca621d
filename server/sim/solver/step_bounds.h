#pragma once
/// \file
/// How far along a Newton direction the step may go: CCD against the table, colliders and
/// self-contact pairs, then Armijo backtracking.
/// Member functions of Solver<Exec> (solver_impl.h), written once for every backend.

#include "sim/solver/solver_impl.h"

namespace gd::sim {

/// Largest step fraction along dx that keeps the state free of crossings (CCD).
template <class Exec>
double Solver<Exec>::max_step() { return std::min({table_ccd_bound(), self_ccd_bound(), collider_step_bound()}); }

/// Conservative bound against colliders (distance is 1-Lipschitz): no free vertex moves more
/// than 90% of its distance to a collider's surface in one step.
template <class Exec>
double Solver<Exec>::collider_step_bound() {
  if (n_col_ == 0) return 1.0;
  const detail::View V = view();
  const double* x = Exec::ptr(x_);
  const double* dx = Exec::ptr(dx_);
  const double inv = Exec::max(n_, [=] GD_HD_LAMBDA(int i) {
    if (V.fixed[i]) return 0.0;
    const Real len = detail::load3(dx, i).norm();
    if (len == 0) return 0.0;
    double worst = 0;
    for (int c = 0; c < V.n_col; ++c) {
      const double* q = V.col_pose + 24 * c;
      const Mat3 R1 = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(q + 12);
      const Vec3 t1(q[21], q[22], q[23]);
      const Real d = collider_world_distance(detail::load3(x, i), R1, t1, V.col_shape[c], &V.col_mesh, nullptr, nullptr);
      worst = fmax(worst, d > 0 ? len / (0.9 * d) : 1e12);
    }
    return worst;
  }, Exec::kParallelMinHeavy);
  return inv > 1.0 ? 1.0 / inv : 1.0;
}

/// The table is a half-space, so its CCD bound separates per vertex: a free vertex whose step
/// would close more than 90% of its height above the table has the normal part of its step cut
/// to that, the rest of dx kept (a projected Newton direction, as for bound constraints). Without
/// it the few vertices falling onto the table shortened every vertex's step (alpha 0.1-0.3 over
/// several Newton iterations of a landing step). Applied only when the cut direction still
/// descends (g . dx < 0); else dx stays Newton's and table_ccd_bound shortens it as a whole.
/// Returns the number of vertices cut.
template <class Exec>
int Solver<Exec>::cut_at_table() {
  if (!P_.table) return 0;
  const detail::View V = view();
  const detail::Params P = P_;
  const double* x = Exec::ptr(x_);
  const double* g = Exec::ptr(g_);
  double* dx = Exec::ptr(dx_);
  // Normal motion to remove from vertex i (>= 0; 0 where the step keeps 10% of the height).
  const auto cut = [=] GD_HD_LAMBDA(int i) -> double {
    if (V.fixed[i]) return 0.0;
    const Real d = P.table_n.dot(detail::load3(x, i)) - P.table_offset;
    const Real dn = P.table_n.dot(detail::load3(dx, i));
    return d > 0 && dn < -kTableCcdFraction * d ? -kTableCcdFraction * d - dn : 0.0;
  };
  const double cut_slope = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) {
    const double c = cut(i);
    return c > 0 ? c * P.table_n.dot(detail::load3(g, i)) : 0.0;
  });
  const double cut_count = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) { return cut(i) > 0 ? 1.0 : 0.0; });
  if (cut_count == 0 || dot(g_, dx_) + cut_slope >= 0) return 0;
  Exec::for_each(n_, [=] GD_HD_LAMBDA(int i) {
    const double c = cut(i);
    if (c > 0)
      for (int a = 0; a < 3; ++a) dx[3 * i + a] += c * P.table_n[a];
  });
  return static_cast<int>(cut_count);
}

/// Largest step fraction keeping every free vertex at least 10% of its distance above the
/// table (continuous collision detection against a plane is exact and cheap).
template <class Exec>
double Solver<Exec>::table_ccd_bound() {
  if (!P_.table) return 1.0;
  const detail::View V = view();
  const detail::Params P = P_;
  const double* x = Exec::ptr(x_);
  const double* dx = Exec::ptr(dx_);
  // max over vertices of the inverse admissible fraction
  const double inv = Exec::max(n_, [=] GD_HD_LAMBDA(int i) {
    if (V.fixed[i]) return 0.0;
    const Real d = P.table_n.dot(detail::load3(x, i)) - P.table_offset;
    const Real dn = P.table_n.dot(detail::load3(dx, i));
    if (dn >= 0) return 0.0;
    return -dn / (kTableCcdFraction * d);
  });
  return inv > 1.0 ? 1.0 / inv : 1.0;
}

/// Largest fraction of dx along which no candidate pair closes more than 90% of its gap above
/// the CCD floor. The floor (a micrometre at the default dhat) keeps pairs far above the rounding
/// of the distance and triangle-triangle tests: without it a pair the barrier could not stop
/// (a gripper pulling cloth through cloth) closed to 1e-14 m over a few steps, the exact test then
/// read the touching edges as crossing, and the untangling fail-safe made real crossings of them.
/// A pair within twice the floor may close to about half its distance (ccd_floor_offset).
template <class Exec>
double Solver<Exec>::self_ccd_bound() {
  if (!self_ || cand_.n == 0) return 1.0;
  const detail::View V = view();
  const double* x = Exec::ptr(x_);
  const double* dx = Exec::ptr(dx_);
  const Real ccd_floor = P_.ccd_floor;
  const double inv = Exec::max(V.cand.n, [=] GD_HD_LAMBDA(int c) {
    const int* v = V.cand.v + 4 * c;
    const Vec3 a = detail::load3(x, v[0]), b = detail::load3(x, v[1]), q = detail::load3(x, v[2]),
               d = detail::load3(x, v[3]);
    const Vec3 da = detail::load3(dx, v[0]), db = detail::load3(dx, v[1]), dq = detail::load3(dx, v[2]),
               dd = detail::load3(dx, v[3]);
    const Real alpha =
        V.cand.type[c] == 0
            ? point_triangle_ccd(a, b, q, d, da, db, dq, dd, 0.0, kCcdGapFraction, kCcdMaxIterations, ccd_floor)
            : edge_edge_ccd(a, b, q, d, da, db, dq, dd, 0.0, kCcdGapFraction, kCcdMaxIterations, ccd_floor);
    return alpha >= 1.0 ? 0.0 : (alpha > 1e-12 ? 1.0 / alpha : 1e12);
  }, Exec::kParallelMinHeavy);
  return inv > 1.0 ? 1.0 / inv : 1.0;
}

/// Backtracking (Armijo) from alpha_max, given L(x) = e0; returns the accepted step fraction.
/// Each trial also computes the gradient there (g_trial_): the next Newton iteration's residual
/// check then needs no pass of its own. evals counts the evaluations.
template <class Exec>
double Solver<Exec>::line_search(double alpha_max, double e0, int* evals) {
  last_trial_alpha_ = -1;
  const double slope = dot(g_, dx_);
  double alpha = alpha_max;
  for (int k = 0; k < 20; ++k) {
    copy(x_, x_trial_);
    axpy(alpha, dx_, x_trial_);
    const double e = evaluate(x_trial_, g_trial_, false);
    ++*evals;
    if (std::isfinite(e) && e <= e0 + 1e-4 * alpha * std::min(slope, 0.0)) {
      last_trial_alpha_ = alpha;
      return alpha;
    }
    alpha *= 0.5;
  }
  return 0.0;
}

}  // namespace gd::sim
