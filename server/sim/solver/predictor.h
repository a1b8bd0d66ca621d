#pragma once
/// \file
/// Start of a step (lagged data, Dirichlet targets, the inertial predictor and its contacts),
/// acceptance of a Newton iterate, and the velocity update at the end.
/// Member functions of Solver<Exec> (solver_impl.h), written once for every backend.

#include "sim/solver/solver_impl.h"

namespace gd::sim {

/// Bending at the edge of a clamped region. A wing whose three vertices are all held (Dirichlet or
/// gripped) cannot bend, so a hinge between it and a free wing stands for the free wing's area
/// alone: coef = sqrt(3)|e|/A_free and area = A_free/3 instead of the two wings' sum, twice an
/// interior hinge's stiffness between equal wings. With the sum, the clamped half of the hinge's
/// area took part in the root curvature, a first-order error at every clamped edge (the
/// cantilever's bending length 2-3% short, halving with the mesh; docs/physics.md, "Bending at
/// clamped edges"). Runs when the held vertices change; the backend's copy is re-uploaded only
/// when the set of such hinges changes.
template <class Exec>
void Solver<Exec>::clamp_hinges(const std::vector<int>& fixed, const std::vector<int>& gripped) {
  const SceneData& d = *data_;
  const int nh = d.hinge_count();
  bool changed = false;
  for (int h = 0; h < nh; ++h) {
    const int* hv = d.hinges.data() + 4 * h;
    auto held = [&](int v) { return fixed[v] != 0 || gripped[v] != 0; };
    const bool edge = held(hv[0]) && held(hv[1]);
    const bool wa = edge && held(hv[2]), wb = edge && held(hv[3]);
    const char c = wa == wb ? 0 : (wa ? 1 : 2);
    if (c == hinge_clamped_[h]) continue;
    hinge_clamped_[h] = c;
    changed = true;
    HingeRest r = d.hinge_rest[h];
    const Real a1 = d.hinge_wing_area[2 * h], a2 = d.hinge_wing_area[2 * h + 1];
    const Real free_area = c == 1 ? a2 : a1;
    if (c != 0 && free_area > 0) {
      r.coef *= (a1 + a2) / free_area;
      r.area = free_area / 3;
    }
    hinge_rest_host_[h] = r;
  }
  if (changed) Exec::upload(hinge_rest_, hinge_rest_host_);
}

/// Saves the step-start state, applies Dirichlet targets and an inertial predictor that stays
/// above the table.
template <class Exec>
void Solver<Exec>::begin_step(const KinematicTargets& kin, bool quasi_static) {
  P_.h = opt_.dt;
  P_.quasi_static = quasi_static;
  P_.friction_eps = opt_.friction_eps_v * opt_.dt;
  precond_ready_ = false;  // set up again at this step's first Newton iteration
  estimator_pending_ = false;
  if (quasi_static) Exec::fill(v_, 0.0);
  copy(x_, x_t_);
  copy(v_, v_t_);
  if (P_.beta_bend > 0) {  // the damping's lagged angle gradient
    const detail::View V0 = view();
    double* grad_t = Exec::ptr(hinge_grad_t_);
    Exec::for_each(V0.nh, [=] GD_HD_LAMBDA(int h) { detail::hinge_step_start(V0, h, grad_t); }, Exec::kParallelMinHeavy);
  }
  // Kinematic vertices: hard Dirichlet without self-contact; with self-contact they stay in the
  // solve, pulled to their targets by a stiff spring, so CCD also guards their motion and a
  // gripper pushes cloth aside instead of jumping through it.
  const bool soft = self_ != nullptr;
  std::fill(kin_fixed_host_.begin(), kin_fixed_host_.end(), 0);
  std::vector<int> kin_flag(n_, 0);
  for (int k : kin.vertices) (soft ? kin_flag : kin_fixed_host_)[k] = 1;
  Exec::upload(fixed_, kin_fixed_host_);
  Exec::upload(kin_flag_, kin_flag);
  if (kin.vertices != clamp_held_) {  // hinges on the edge of a held region, when the held set changes
    clamp_held_ = kin.vertices;
    clamp_hinges(kin_fixed_host_, kin_flag);
  }
  update_free_mass();
  std::vector<double> targets(3 * static_cast<size_t>(n_), 0.0);
  for (size_t k = 0; k < kin.vertices.size(); ++k)
    for (int c = 0; c < 3; ++c) targets[3 * kin.vertices[k] + c] = kin.targets[3 * k + c];
  Exec::upload(kin_target_, targets);
  const detail::View V = view();
  const detail::Params P = P_;
  double* x = Exec::ptr(x_);
  Exec::for_each(n_, [=] GD_HD_LAMBDA(int i) {
    if (V.fixed[i] || V.kin[i]) {  // kinematic: straight to the target
      detail::store3(x, i, detail::load3(V.kin_target, i));
      return;
    }
    const Vec3 xt = detail::load3(V.x_t, i);
    Vec3 step = detail::inertia_target(V, P, i) - xt;
    if (P.table) {  // keep the predictor clear of the table
      const Real d = P.table_n.dot(xt) - P.table_offset, dn = P.table_n.dot(step);
      if (dn < 0 && d + dn < 0.5 * d) step *= 0.5 * d / (-dn);
    }
    detail::store3(x, i, xt + step);
  });
  if (n_col_ > 0) project_out_of_colliders();  // a collider may have moved into the cloth
  if (self_) {
    // One broad phase on the predictor's motion x_t -> x: its candidates hold every pair within
    // dhat at x_t too (a swept box contains the box at x_t), so the contacts at the start of
    // the step, which lag the friction, are selected from them; then the whole motion is
    // scaled back by CCD where needed.
    Exec::download(host_xt_, x_t_);
    Exec::download(host_x_, x_);
    self_->find_within_budget(host_xt_, &host_x_);  // a motion that would flood it is halved: dx below
    self_->select_active(host_xt_, kin_fixed_host_);
    self_->build_friction(host_xt_);
    upload_friction();
    upload_candidates();
    for (size_t k = 0; k < host_x_.size(); ++k) host_dx_[k] = host_x_[k] - host_xt_[k];
    Exec::upload(dx_, host_dx_);
    copy(x_t_, x_);
    const double alpha = std::min(self_ccd_bound(), table_ccd_bound());
    axpy(alpha < 1.0 ? 0.9 * alpha : 1.0, dx_, x_);
    if (alpha < 1.0 && n_col_ > 0) project_out_of_colliders();  // the scaled motion may stop short inside one
  }
}

/// x += alpha dx, taking the line search's accepted trial point (bit for bit the state it
/// evaluated) and its gradient, and the candidate pairs' distances it measured there (the next
/// select_active and min_active_distance read them instead of measuring again). Returns whether
/// g_ now holds the gradient at the new x.
template <class Exec>
bool Solver<Exec>::accept_step(double alpha) {
  if (alpha == 0.0) return false;
  if (alpha == last_trial_alpha_) {
    std::swap(x_, x_trial_);
    std::swap(g_, g_trial_);
    if (self_ && cand_.n > 0) {
      Exec::download(host_x_, x_);
      if constexpr (Exec::kHostMemory) {
        self_->set_candidate_distances(host_x_, Exec::ptr(cand_d2_));
      } else {
        Exec::download(host_d2_, cand_d2_);
        self_->set_candidate_distances(host_x_, host_d2_.data());
      }
    }
    return true;
  }
  axpy(alpha, dx_, x_);
  return false;
}

template <class Exec>
void Solver<Exec>::end_step() {
  const double inv_h = 1.0 / P_.h;
  const double* x = Exec::ptr(x_);
  const double* xt = Exec::ptr(x_t_);
  double* v = Exec::ptr(v_);
  Exec::for_each(3 * n_, [=] GD_HD_LAMBDA(int k) { v[k] = (x[k] - xt[k]) * inv_h; });
}

/// A collider may move into the cloth during the step: Newton starts from a guess with every
/// free vertex outside each collider's end pose by dhat/2, or by its clearance at the step's start
/// where that was less (at least 1e-3 dhat): cloth a pad already presses moves with the pad instead
/// of being lifted off it, which in a pinch would move the layer under the pad that far towards
/// the layer beneath and through it (docs/robot.md, "Pinched layers"). Where two colliders squeeze
/// cloth (gripper pads) moving a vertex out of one can move it into the other: then the
/// projections repeat with half the gap, up to three times.
template <class Exec>
void Solver<Exec>::project_out_of_colliders() {
  Exec::download(host_x_, x_);
  Exec::download(host_xt_, x_t_);
  double gap = 0.5 * P_.dhat;
  for (int round = 0; round < 4; ++round, gap *= 0.5) {
    for (const Collider& c : *colliders_)
      c.project_out(&host_x_, kin_fixed_host_, col_t1_, gap, host_xt_, col_t0_, kClearanceFloor * P_.dhat);
    if (colliders_->size() < 2 || !inside_a_collider(host_x_)) break;
  }
  Exec::upload(x_, host_x_);
}

}  // namespace gd::sim
