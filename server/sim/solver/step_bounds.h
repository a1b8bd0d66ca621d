#pragma once
/// \file
/// How far along a Newton direction the step may go: CCD against the table, colliders and
/// self-contact pairs, then a landing's per-vertex cut at the table or Armijo backtracking.
/// Member functions of Solver<Exec> (solver_impl.h), written once for every backend.

#include "sim/solver/solver_impl.h"

namespace gd::sim {

/// Largest step fraction along dx that keeps the state free of crossings (CCD); the table's own
/// bound is kept in table_bound_.
template <class Exec>
double Solver<Exec>::max_step() {
  const CcdBounds b = ccd_bounds(true, true, true);
  table_bound_ = b.table;  // kept for table_cut_step
  return std::min({b.table, b.self, b.collider});
}

/// The bounds asked for (each where it applies: a table, self-contact candidates, colliders),
/// each the inverse of its largest admissible fraction reduced on the backend into its slot of
/// red_, then read back together: one round trip. With `slope`, g·dx is queued too and left in
/// host_red_[kRedSlope].
template <class Exec>
typename Solver<Exec>::CcdBounds Solver<Exec>::ccd_bounds(bool table, bool self, bool collider, bool slope) {
  table = table && P_.table;
  self = self && self_ && cand_.n > 0;
  collider = collider && n_col_ > 0;
  double* R = Exec::ptr(red_);
  if (table) table_ccd_inverse_to(R + kRedTable);
  if (self) self_ccd_inverse_to(R + kRedSelf);
  if (collider) collider_step_inverse_to(R + kRedCollider);
  if (slope) dot_to(g_, dx_, R + kRedSlope, Exec::kParallelMin);
  CcdBounds b;
  if (!table && !self && !collider && !slope) return b;
  const double* r = read_reductions();
  auto bound = [](double inv) { return inv > 1.0 ? 1.0 / inv : 1.0; };
  if (table) b.table = bound(r[kRedTable]);
  if (self) b.self = bound(r[kRedSelf]);
  if (collider) b.collider = bound(r[kRedCollider]);
  return b;
}

/// Conservative bound against colliders: no free vertex, nor surface sample against the colliders
/// it is held out of, closes more than 90% of its distance to a collider's surface in one step
/// (detail::collider_step_inverse: only the motion towards a convex collider is bounded).
template <class Exec>
void Solver<Exec>::collider_step_inverse_to(double* out) {
  const detail::View V = view();
  const double* x = Exec::ptr(x_);
  const double* dx = Exec::ptr(dx_);
  // The vertices, then (by triangle) the surface samples against the colliders they are held out of.
  Exec::max_to(n_ + (V.n_samp > 0 ? V.nt : 0), [=] GD_HD_LAMBDA(int i) {
    if (i < V.n) return V.fixed[i] ? 0.0 : detail::collider_step_inverse(V, detail::load3(x, i), detail::load3(dx, i));
    return detail::triangle_samples_step_inverse(V, i - V.n, x, dx);
  }, out, Exec::kParallelMinHeavy);
}

/// Largest step fraction keeping every free vertex at least 10% of its distance above the
/// table (continuous collision detection against a plane is exact and cheap).
template <class Exec>
void Solver<Exec>::table_ccd_inverse_to(double* out) {
  const detail::View V = view();
  const detail::Params P = P_;
  const double* x = Exec::ptr(x_);
  const double* dx = Exec::ptr(dx_);
  // max over vertices of the inverse admissible fraction
  Exec::max_to(n_, [=] GD_HD_LAMBDA(int i) {
    if (V.fixed[i]) return 0.0;
    const Real d = P.table_n.dot(detail::load3(x, i)) - P.table_offset;
    const Real dn = P.table_n.dot(detail::load3(dx, i));
    if (dn >= 0) return 0.0;
    return -dn / (0.9 * d);
  }, out);
}

/// Largest fraction of dx along which no candidate pair closes more than 90% of its gap above
/// the CCD floor. The floor (a micrometre at the default dhat) keeps pairs far above the rounding
/// of the distance and triangle-triangle tests: without it a pair the barrier could not stop
/// (a gripper pulling cloth through cloth) closed to 1e-14 m over a few steps, the exact test then
/// read the touching edges as crossing, and the untangling fail-safe made real crossings of them.
/// A pair within twice the floor may close to about half its distance (ccd_floor_offset).
template <class Exec>
void Solver<Exec>::self_ccd_inverse_to(double* out) {
  const detail::View V = view();
  const double* x = Exec::ptr(x_);
  const double* dx = Exec::ptr(dx_);
  const Real ccd_floor = P_.ccd_floor;
  Exec::max_to(V.cand.n, [=] GD_HD_LAMBDA(int c) {
    const Real alpha = detail::pair_ccd_fraction(V.cand.v + 4 * c, V.cand.type[c], x, dx, ccd_floor);
    return alpha >= 1.0 ? 0.0 : (alpha > 1e-12 ? 1.0 / alpha : 1e12);
  }, out, Exec::kParallelMinHeavy);
}

/// The step's length along dx: the per-vertex table cut where it applies (table_cut_step), else
/// Armijo backtracking from the CCD bound alpha_max. Counts the cuts in st->table_cuts and the
/// objective's evaluations in st->energy_evals.
template <class Exec>
double Solver<Exec>::step_length(double alpha_max, double e0, StepStats* st) {
  const double cut = table_cut_step(alpha_max, e0, &st->energy_evals);
  if (cut > 0) {
    ++st->table_cuts;
    return cut;
  }
  return line_search(alpha_max, e0, &st->energy_evals);
}

/// A landing: where the table's CCD bound is what limits the step, the whole Newton step shrinks
/// to the fraction its most constrained vertex allows (fold/5000: 12-30% for several iterations
/// while the sheet lands, every other vertex held back as much). This tries instead the direction
/// with each vertex's motion towards the table cut to 90% of its own height (its motion along
/// the table kept; the table's own CCD bound is then 1), at the largest fraction the other bounds
/// allow, and takes it if that fraction is at least twice the table's bound, the cut direction
/// descends and Armijo accepts it at once; then dx_ holds the cut direction and the fraction is
/// returned. Otherwise -1, with dx_ as it was: the plain line search follows (so a cut direction
/// that descends poorly, as where cloth rests on the table, is never backtracked along). Off
/// with SceneOptions::table_cut = false.
template <class Exec>
double Solver<Exec>::table_cut_step(double alpha_max, double e0, int* evals) {
  if (!P_.table || !opt_.table_cut) return -1;
  const double table_bound = table_bound_;  // max_step's, for this dx
  if (!(table_bound < 1.0) || table_bound > alpha_max) return -1;  // not what limits the step
  copy(dx_, dx_full_);
  const detail::View V = view();
  const detail::Params P = P_;
  const double* x = Exec::ptr(x_);
  double* dx = Exec::ptr(dx_);
  Exec::for_each(n_, [=] GD_HD_LAMBDA(int i) {
    if (V.fixed[i]) return;
    const Real d = P.table_n.dot(detail::load3(x, i)) - P.table_offset;
    const Vec3 di = detail::load3(dx, i);
    const Real dn = P.table_n.dot(di);
    if (dn < 0 && -dn > 0.9 * d) detail::store3(dx, i, Vec3(di - (dn + 0.9 * d) * P.table_n));
  });
  const CcdBounds b = ccd_bounds(false, true, true, true);  // with g·dx
  const double alpha = std::min({1.0, b.self, b.collider, pad_step_bound()});
  const double slope = host_red_[kRedSlope] + pad_slope();
  if (alpha >= 2 * table_bound && slope < 0) {
    copy(x_, x_trial_);
    axpy(alpha, dx_, x_trial_);
    if (!pad_hands_.empty()) set_pads_at(alpha);
    const double e = evaluate(x_trial_, g_trial_, false) + pad_spring_energy(alpha);
    ++*evals;
    if (std::isfinite(e) && e <= e0 + 1e-4 * alpha * slope) {
      last_trial_alpha_ = alpha;
      gd::log().trace("table cut: alpha {:.3g} instead of {:.3g}", alpha, table_bound);
      return alpha;
    }
  }
  copy(dx_full_, dx_);
  return -1;
}

/// Backtracking (Armijo) from alpha_max, given L(x) = e0; returns the accepted step fraction.
/// Each trial also computes the gradient there (g_trial_): the next Newton iteration's residual
/// check then needs no pass of its own. evals counts the evaluations.
template <class Exec>
double Solver<Exec>::line_search(double alpha_max, double e0, int* evals) {
  last_trial_alpha_ = -1;
  dot_to(g_, dx_, Exec::ptr(red_) + kRedSlope, Exec::kParallelMin);  // g·dx, read back with the first trial's energy
  double slope = 0;
  double alpha = alpha_max;
  for (int k = 0; k < 20; ++k) {
    copy(x_, x_trial_);
    axpy(alpha, dx_, x_trial_);
    if (!pad_hands_.empty()) set_pads_at(alpha);  // the hands in the solve where the trial puts them
    const double e = evaluate(x_trial_, g_trial_, false) + pad_spring_energy(alpha);
    if (k == 0) slope = host_red_[kRedSlope] + pad_slope();
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
