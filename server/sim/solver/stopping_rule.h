#pragma once
/// \file
/// Newton's stopping rule: the correction still to come, as a mass-weighted RMS velocity
/// (docs/physics.md, "When a step is done").
/// Member functions of Solver<Exec> (solver_impl.h), written once for every backend.

#include "sim/solver/solver_impl.h"

namespace gd::sim {

/// Before Newton iteration k >= 1: whether the iterate is converged, judged by the correction its
/// gradient still asks for against the first step's `scale`: estimated with the last
/// preconditioner where it carries smooth modes (MAS: the next Newton step, P⁻¹g, without
/// assembling or solving), else bounded by residual_bound. The gradient comes from the line
/// search when it was computed there. Where the estimate needs a preconditioner of its own
/// (PCG's block-Jacobi carries no smooth modes), none is made after a correction (`last_taken`)
/// more than kEstimateRatio times the threshold: the next correction is not expected under the
/// threshold, and the estimator's setup is the rule's cost.
template <class Exec>
bool Solver<Exec>::converged(StepStats* st, int k, bool gradient_known, double scale, double last_taken) {
  if (estimator_ && last_taken > kEstimateRatio * residual_threshold(scale)) {
    gd::log().trace("newton {}: the last correction was {:.3g} times the threshold, not converged", k,
                    last_taken / residual_threshold(scale));
    st->converged = false;
    return false;
  }
  // A pair pressed too close keeps the step going whatever the estimate says: no estimate then
  // (its setup is the rule's cost), and the last one checked stays in st->residual.
  bool held = false;
  timed(st->stage.stopping, [&] { held = pressed(); });
  if (held) {
    gd::log().trace("newton {}: a pair is pressed closer than {} CCD floors, not converged", k, kPressedGapFloors);
    st->converged = false;
    return false;
  }
  if (!gradient_known) timed(st->stage.assembly, [&] { evaluate(x_, g_, false); });
  timed(st->stage.stopping, [&] {
    Preconditioner<Exec>* estimator = estimator_ ? estimator_.get() : precond_.get();
    if (precond_ready_ && estimator_pending_) {  // the last iteration's matrix is still assembled
      estimator_->build(matrix_view());
      estimator_pending_ = false;
    }
    if (precond_ready_ && estimator->estimates_smooth_modes()) {
      estimator->apply(Exec::ptr(g_), Exec::ptr(z_));
      st->residual = rms_velocity(z_);
    } else {
      st->residual = residual_bound();
    }
    st->converged = st->residual <= residual_threshold(scale);
    // The pinch on its own too: the same estimate (or bound) over the pinched vertices alone.
    if (st->converged && pinch_mass_ > 0) {
      const double pinch = precond_ready_ && estimator->estimates_smooth_modes() ? pinch_rms_velocity(z_, 1.0)
                                                                                 : pinch_residual_bound();
      st->converged = pinch <= residual_threshold(scale);
      if (!st->converged)
        gd::log().trace("newton {}: the pinch's next correction {:.3g} m/s, not converged", k, pinch);
    }
  });
  gd::log().trace("newton {}: next correction {:.3g} m/s (first step {:.3g}){}", k, st->residual, scale,
                  st->converged ? ", converged" : "");
  return st->converged;
}

/// A self-contact pair pressed closer than kPressedGapFloors CCD floors while the barrier can
/// still stiffen: not converged whatever the residual says, so that stiffen_pressed_pairs gets
/// its next Newton iteration (the per-iteration guard against grips squeezing cloth through
/// cloth; validation case self/press).
template <class Exec>
bool Solver<Exec>::pressed() {
  if (!self_ || kappa_scale_ >= kKappaScaleMax) return false;
  return min_active_distance(x_, x_gen_) < kPressedGapFloors * P_.ccd_floor;
}

/// After the first assembly: whether the predictor is already within newton_atol.
template <class Exec>
bool Solver<Exec>::predictor_converged(StepStats* st) {
  st->residual0 = st->residual = residual_bound();
  st->converged = st->residual0 <= opt_.newton_atol && (pinch_mass_ == 0 || pinch_residual_bound() <= opt_.newton_atol);
  return st->converged;
}

/// Whether the pinched cloth's share of a correction `scale` x d is within `threshold` too (true
/// with no pinch): SceneOptions::pinch_stopping_rule.
template <class Exec>
bool Solver<Exec>::pinch_settled(const Vec<double>& d, double scale, double threshold) {
  return pinch_mass_ == 0 || pinch_rms_velocity(d, scale) <= threshold;
}

/// Whether a Newton step taken at fraction `alpha` of its direction (CCD allowing `alpha_max`)
/// measures how far the iterate is from the step's end, so that a small one ends Newton. A step
/// the line search backtracked below kMeasuredStepFraction does not: the energy rose along the
/// direction, so the model that proposed it is poor there, and a correction cut to 1e-4 of a
/// direction that still asks for metres per second moved little without being near the minimum
/// (pinches swept at a fling's pace ended steps on such cuts and slid out: docs/robot.md, "Steps
/// the line search cut short"); the gradient's estimate before the next iteration judges such an
/// iterate instead. A step CCD cut (alpha = alpha_max: a contact on its path, as where cloth is
/// pressed onto cloth every step) or one taking at least that fraction does measure it.
template <class Exec>
bool Solver<Exec>::correction_measures(double alpha, double alpha_max) const {
  return alpha >= kMeasuredStepFraction || alpha >= alpha_max;
}

/// rms_velocity over the pinched vertices alone (pinch_w_), of the correction scale x d, m/s.
template <class Exec>
double Solver<Exec>::pinch_rms_velocity(const Vec<double>& d, double scale) {
  const double* w = Exec::ptr(pinch_w_);
  const double* p = Exec::ptr(d);
  const double num = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) { return w[i] * detail::load3(p, i).squaredNorm(); });
  return std::abs(scale) * std::sqrt(num / pinch_mass_) / P_.h;
}

/// residual_bound's arithmetic over the pinched vertices alone: not a bound there (the correction
/// at the pinch also answers the gradient elsewhere), the pinch's own share of it.
template <class Exec>
double Solver<Exec>::pinch_residual_bound() {
  const double* w = Exec::ptr(pinch_w_);
  const double* g = Exec::ptr(g_);
  const double num = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) {
    return w[i] > 0 ? detail::load3(g, i).squaredNorm() / w[i] : 0.0;
  });
  return P_.h * std::sqrt(num / pinch_mass_);
}

/// An upper bound of the velocity correction the gradient g_ still asks for: the Hessian is at
/// least M/h² (inertia; every other term is PSD), so the Newton correction d = -H⁻¹ g has
/// |d|_M <= h² |g|_M⁻¹, i.e. an RMS velocity of at most h |g|_M⁻¹ / sqrt(M), m/s. A safe test
/// (it never calls an unconverged iterate converged) that is tight where inertia dominates
/// (free flight, sliding, the predictor) and pessimistic for stiff membrane errors, which the
/// step test after each iteration catches instead.
template <class Exec>
double Solver<Exec>::residual_bound() {
  const detail::View V = view();
  const double* g = Exec::ptr(g_);
  const double num = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) {
    return V.fixed[i] ? 0.0 : detail::load3(g, i).squaredNorm() / V.mass[i];
  });
  return P_.h * std::sqrt(num / free_mass());
}

template <class Exec>
void Solver<Exec>::update_free_mass() {
  const detail::View V = view();
  const double m = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) { return V.fixed[i] ? 0.0 : V.mass[i]; });
  free_mass_ = m > 0 ? m : 1.0;
}

/// Mass-weighted RMS of a displacement over the step, |d|_M / (h sqrt(M)) over the free
/// vertices, m/s.
template <class Exec>
double Solver<Exec>::rms_velocity(const Vec<double>& d) {
  rms_velocity_to(d, Exec::ptr(red_) + kRedDxMass);
  return rms_of_sum(Exec::read(red_, kRedDxMass));
}

/// rms_velocity's sum |d|²_M into *out (the backend's memory); rms_of_sum makes it the velocity.
template <class Exec>
void Solver<Exec>::rms_velocity_to(const Vec<double>& d, double* out) {
  const detail::View V = view();
  const double* p = Exec::ptr(d);
  Exec::sum_to(n_, [=] GD_HD_LAMBDA(int i) {
    return V.fixed[i] ? 0.0 : V.mass[i] * detail::load3(p, i).squaredNorm();
  }, out);
}

}  // namespace gd::sim
