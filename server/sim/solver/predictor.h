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
  xt_gen_ = x_gen_;  // x_t_ holds what x_ held
  moved_x();         // x_ gets the predictor below
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
    const Vec3 step = detail::clear_of_table(P, xt, detail::inertia_target(V, P, i) - xt);  // clear of the table
    detail::store3(x, i, xt + step);
  });
  pinch_mass_ = 0;                                   // no pinch until carry_pinched_cloth finds one
  if (n_col_ > 0) carry_pinched_cloth();            // cloth pinched by a hand's pads goes with the hand
  // A collider may have moved into the cloth: out of it (a pad in the solve is stopped where the
  // guess is clear of it instead, below: pushed out unguarded, cloth squeezed between pads went
  // into the other pad).
  if (n_col_ > 0) project_out_of_colliders(false, opt_.pad_stiffness > 0);
  bool scaled_back = false;  // the guess's motion scaled back by CCD
  if (self_) {
    // One broad phase on the predictor's motion x_t -> x: its candidates hold every pair within
    // dhat at x_t too (a swept box contains the box at x_t), so the contacts at the start of
    // the step, which lag the friction, are selected from them; then the whole motion is
    // scaled back by CCD where needed.
    copy(x_, x1_);
    find_candidates(x_t_, x1_, false);  // candidates.h; a motion that would flood it is halved: dx below
    select_along(x_t_, xt_gen_);        // its candidates, and the contacts at x_t ...
    build_friction(x_t_, xt_gen_);      // ... lag the friction (active_set.h)
    const double* xt = Exec::ptr(x_t_);
    const double* x1 = Exec::ptr(x1_);
    double* dx = Exec::ptr(dx_);
    Exec::for_each(3 * n_, [=] GD_HD_LAMBDA(int k) { dx[k] = x1[k] - xt[k]; }, Exec::kParallelMinVector);
    copy(x_t_, x_);
    const CcdBounds b = ccd_bounds(true, true, false);
    const double alpha = std::min(b.self, b.table);
    if (!(alpha < 1.0 && pinch_mass_ > 0 && opt_.pinch_first_guess && guess_pinch_first()))
      axpy(alpha < 1.0 ? 0.9 * alpha : 1.0, dx_, x_);
    scaled_back = alpha < 1.0;
  }
  // The scaled motion may stop short inside a collider, and a vertex squeezed between two may be
  // left inside one by the projection itself. Pads in the solve stop here with self-contact off
  // too: the projection above left them out, and the guess went on inside them (not finite).
  if (n_col_ > 0 &&
      (scaled_back || opt_.pad_stiffness > 0 || (Exec::download(host_x_, x_), inside_a_collider(host_x_, true)))) {
    stop_yielding_colliders();        // a yielding one (a gripper pad) stops where the cloth is
    project_out_of_colliders(true, false);  // out of the others, unguarded by CCD
  }
  if (samp_live_) switch_samples();  // a surface sample left inside a pad sits this step out
}

/// This step's Newton cap: SceneOptions::grip_newton_max_iters where higher, while a yielding
/// collider with friction (a finger pad) is in the scene; newton_max_iters otherwise.
template <class Exec>
int Solver<Exec>::newton_max_iters() const {
  const int cap = opt_.newton_max_iters;
  if (!colliders_ || opt_.grip_newton_max_iters <= cap) return cap;
  for (const Collider& c : *colliders_)
    if (c.yielding() && c.friction() > 0) return opt_.grip_newton_max_iters;
  return cap;
}

/// x += alpha dx, taking the line search's accepted trial point (bit for bit the state it
/// evaluated) and its gradient, and the candidate pairs' distances it measured there (the next
/// select_active and min_active_distance read them instead of measuring again). Returns whether
/// g_ now holds the gradient at the new x.
template <class Exec>
bool Solver<Exec>::accept_step(double alpha) {
  move_pads(alpha);  // the hands in the solve (pads_in_solve.h) to where the step takes them
  if (alpha == 0.0) return false;
  if (alpha == last_trial_alpha_) {
    std::swap(x_, x_trial_);
    std::swap(g_, g_trial_);
    moved_x();
    if (self_ && cand_.n > 0) store_candidate_distances(x_gen_);  // active_set.h
    return true;
  }
  axpy(alpha, dx_, x_);
  moved_x();
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

/// Bending friction's sliders after the step (bending_friction.h): where the step carried a
/// hinge's friction spring past its limit moment, the slider slips so that it carries the limit.
template <class Exec>
void Solver<Exec>::slip_bending_friction() {
  const double* x = Exec::ptr(x_);
  const int* hinges = Exec::ptr(hinges_);
  const HingeRest* rest = Exec::ptr(hinge_rest_);
  double* theta_f = Exec::ptr(hinge_theta_f_);
  Exec::for_each(data_->hinge_count(), [=] GD_HD_LAMBDA(int h) {
    const int* hv = hinges + 4 * h;
    const Real theta = dihedral_angle(detail::load3(x, hv[0]), detail::load3(x, hv[1]), detail::load3(x, hv[2]),
                                      detail::load3(x, hv[3]));
    theta_f[h] = bending_friction_slip(rest[h], theta, theta_f[h]);
  });
}

/// A collider may move into the cloth during the step: Newton starts from a guess with every
/// free vertex outside each collider's end pose by dhat/2, or by its clearance at the step's start
/// where that was less (at least 1e-3 dhat): cloth a pad already presses moves with the pad instead
/// of being lifted off it, which in a pinch would move the layer under the pad that far towards
/// the layer beneath and through it (docs/robot.md, "Pinched layers"). Where two colliders squeeze
/// cloth (gripper pads) moving a vertex out of one can move it into the other: then the
/// projections repeat with half the gap, up to three times. skip_clear: the first round leaves out
/// the yielding colliders the guess is clear of (stop_yielding_colliders: stopped short or not,
/// the guess keeps half its clearance from them, and a vertex moved back out to its clearance at
/// the step's start would move unguarded by CCD); the later rounds take every collider (moving a
/// vertex out of another may have moved it into one). skip_yielding: every yielding collider left
/// out (pads in the solve, SceneOptions::pad_stiffness: stop_yielding_colliders then stops each where
/// the guess is clear of it). Each collider at its end pose as the solver has it (col_end_: where
/// a yielding one stopped).
template <class Exec>
void Solver<Exec>::project_out_of_colliders(bool skip_clear, bool skip_yielding) {
  Exec::download(host_x_, x_);
  Exec::download(host_xt_, x_t_);
  double gap = 0.5 * P_.dhat;
  for (int round = 0; round < 4; ++round, gap *= 0.5) {
    for (int k = 0; k < n_col_; ++k)
      if (!(skip_clear && round == 0 && col_clear_[k]) && !(skip_yielding && (*colliders_)[k].yielding()))
        (*colliders_)[k].project_out(&host_x_, kin_fixed_host_, col_end_[k], gap, host_xt_,
                                     (*colliders_)[k].checked_pose(col_t0_), kClearanceFloor * P_.dhat);
    if (colliders_->size() < 2 || !inside_a_collider(host_x_)) break;
  }
  Exec::upload(x_, host_x_);
}

/// The clearance each free vertex must keep from each yielding collider k over this step: half of
/// what it had at the step's start (at most dhat/4, at least the floor). A pad pressing cloth that
/// cannot get away closes the gap by at most half per step: the barrier's force rises step by step,
/// and Newton never starts from cloth pressed onto a pad far closer than the last step left it.
/// With pads in the solve (SceneOptions::pad_stiffness > 0) a vertex already closer than the floor
/// keeps what it has instead: under the floor the step's start itself failed the test, the pad
/// went its whole motion and the projection pushed the cloth out of it unguarded, and a stack
/// squeezed between two pads went into the other pad (PadsInTheSolve, the spring pressing harder
/// than the barrier holds at the floor); kept, the pad stops at its start and the solve decides.
/// The surface samples near a sampled collider (find_near_samples, from host_xt_ and host_x_) get
/// theirs after the vertices' (index n + sample), the same way, except that a sample the projection
/// cannot help (within the floor at the step's start with the pads out of the solve, or inside)
/// keeps none (-infinity; switch_samples leaves it out of the step if the guess leaves it inside):
/// a weak sample pressed within the floor and then ignored let a pad in the solve through the
/// cloth the next step. Empty rows for the other colliders. Reads host_xt_ and host_x_.
template <class Exec>
std::vector<std::vector<double>> Solver<Exec>::yielding_clearances() {
  const double floor = kClearanceFloor * P_.dhat;
  std::vector<std::vector<double>> keep(n_col_);
  find_near_samples(host_xt_, host_x_);
  for (int k = 0; k < n_col_; ++k) {
    if (!(*colliders_)[k].yielding()) continue;
    keep[k].assign(n_ + (samp_live_ ? samples_.size() : 0), 0.0);
    const Eigen::Isometry3d start = (*colliders_)[k].checked_pose(col_t0_);
    for (int i = 0; i < n_; ++i) {
      const Vec3 p(host_xt_[3 * i], host_xt_[3 * i + 1], host_xt_[3 * i + 2]);
      const double d0 = (*colliders_)[k].query(p, start).distance;
      keep[k][i] = std::max(floor, 0.5 * std::min(0.5 * P_.dhat, d0));
      if (opt_.pad_stiffness > 0 && d0 > 0) keep[k][i] = std::min(keep[k][i], d0);
    }
    for (const int s : samp_near_[k]) {
      const double d0 = (*colliders_)[k].query(sample_at(host_xt_, s), start).distance;
      double& kept = keep[k][n_ + s];
      kept = std::max(floor, 0.5 * std::min(0.5 * P_.dhat, d0));
      if (opt_.pad_stiffness > 0 && d0 > 0) kept = std::min(kept, d0);  // as a vertex's
      else if (d0 <= floor) kept = -INFINITY;
    }
  }
  return keep;
}

/// Whether the guess moved a fraction b of the way from x_t (host_xt_ to host_x_) keeps every free
/// vertex its clearance (yielding_clearances) from collider k at `pose`.
template <class Exec>
bool Solver<Exec>::keeps_clear(int k, const Eigen::Isometry3d& pose, double b,
                               const std::vector<std::vector<double>>& keep) const {
  for (int i = 0; i < n_; ++i)
    if (!kin_fixed_host_[i] && (*colliders_)[k].query(guess_at(i, b), pose).distance < keep[k][i]) return false;
  if (!samp_live_ || !col_sampled_host_[k]) return true;
  for (const int s : samp_near_[k]) {  // and the surface samples near it
    if (!(keep[k][n_ + s] > -INFINITY)) continue;
    if ((*colliders_)[k].query(sample_guess_at(s, b), pose).distance < keep[k][n_ + s]) return false;
  }
  return true;
}

/// Vertex i of the guess moved a fraction b of the way from x_t (host_xt_ to host_x_).
template <class Exec>
Vec3 Solver<Exec>::guess_at(int i, double b) const {
  Vec3 p;
  for (int r = 0; r < 3; ++r) p[r] = host_xt_[3 * i + r] + b * (host_x_[3 * i + r] - host_xt_[3 * i + r]);
  return p;
}

/// Surface sample s on the guess moved a fraction b of the way (its triangle's corners by guess_at,
/// combined by its weights).
template <class Exec>
Vec3 Solver<Exec>::sample_guess_at(int s, double b) const {
  const int* v = data_->tris.data() + 3 * samples_.tri[s];
  const double* w = samples_.w.data() + 3 * s;
  return w[0] * guess_at(v[0], b) + w[1] * guess_at(v[1], b) + w[2] * guess_at(v[2], b);
}

/// Whether carry_pinched_cloth found vertex i pinched this step (only where it weighs the pinch).
template <class Exec>
bool Solver<Exec>::pinched(int i) const {
  return pinch_mass_ > 0 && i < static_cast<int>(pinch_w_host_.size()) && pinch_w_host_[i] > 0;
}

/// The predictor's guess in two legs where cloth is pinched and CCD cut the whole motion back
/// (SceneOptions::pinch_first_guess): first the pinched vertices alone go their carried way
/// (carry_pinched_cloth), then the rest of the cloth its own, each leg scaled back by CCD on its
/// own. Cut back as one motion, the pinch was held back by contacts anywhere in the garment while
/// the pads went on, and the pads stopped short on it step after step (docs/robot.md, "A guess that
/// carries the pinch first"). Every point of each leg lies within the vertices' swept boxes from
/// x_t to the carried guess, so the candidates found for that motion hold every pair that can come
/// within dhat on the way. Kept only where the result keeps its clearance from every yielding
/// collider at the end pose: stop_yielding_colliders goes back along a straight path, which only
/// a one-leg guess is checked along. Returns whether x_ holds the two-leg guess (else x_ and dx_
/// are as on entry: x_ = x_t, dx_ the whole motion).
template <class Exec>
bool Solver<Exec>::guess_pinch_first() {
  std::vector<double> dx_all;
  Exec::download(dx_all, dx_);
  Exec::download(host_xt_, x_t_);
  // One leg: the motion of the pinched vertices (or of the others) alone, cut back by CCD from x_.
  std::vector<double> leg(dx_all.size());
  auto go = [&](bool pinch) {
    for (int i = 0; i < n_; ++i)
      for (int r = 0; r < 3; ++r) leg[3 * i + r] = pinched(i) == pinch ? dx_all[3 * i + r] : 0.0;
    Exec::upload(dx_, leg);
    const CcdBounds b = ccd_bounds(true, true, false);
    const double a = std::min(b.self, b.table);
    if (a < 1.0 && gd::log().should_log(spdlog::level::debug)) log_what_cuts(pinch ? "the pinch's leg" : "the rest's leg", b);
    const double taken = a < 1.0 ? 0.9 * a : 1.0;
    axpy(taken, dx_, x_);
    return taken;
  };
  const double a1 = go(true);   // the pinch first
  const double a2 = go(false);  // then the rest of the cloth from there
  Exec::download(host_x_, x_);
  const std::vector<std::vector<double>> keep = yielding_clearances();
  bool ok = true;
  for (int k = 0; k < n_col_ && ok; ++k)
    if ((*colliders_)[k].yielding()) ok = keeps_clear(k, col_end_[k], 1.0, keep);
  gd::log().debug("pinch first: the pinch's leg at {:.4f}, the rest's at {:.4f}: {}", a1, a2,
                  ok ? "kept" : "clear of a pad only in one leg, not kept");
  if (ok) return true;
  Exec::upload(dx_, dx_all);
  copy(x_t_, x_);
  return false;
}

/// The guess for cloth pinched between the pads of one hand (a yield group of two colliders,
/// Collider::yield_group): across the pads, the pads' motions over the step (start pose to end
/// pose), each weighted by the vertex's nearness to it; along their faces, the inertial guess. A
/// free vertex is pinched when at the step's start it lies between the two pads (the pads' outward
/// normals at its closest points face each other, n0 . n1 < -0.5) within kPinchReach contact
/// distances of both. Only Newton's starting point changes (CCD guards it as any guess); but the
/// inertial guess left the stack where it was, so a hand sweeping across its pads' faces drove the
/// trailing pad into it, CCD cut the whole guess back and the pad stopped at a fraction of its
/// motion, step after step (docs/robot.md, "Pads that stop together"). Carrying the cloth round
/// the pinch along too, fading over 5 cm, held no more hands through a T-shirt's fling.
template <class Exec>
void Solver<Exec>::carry_pinched_cloth() {
  std::vector<std::pair<int, int>> hands;  // the two pads of each group
  for (int k = 0; k < n_col_; ++k) {
    const Collider& a = (*colliders_)[k];
    if (!a.yielding() || a.yield_group() < 0) continue;
    for (int j = k + 1; j < n_col_; ++j)
      if ((*colliders_)[j].yielding() && (*colliders_)[j].yield_group() == a.yield_group()) hands.emplace_back(k, j);
  }
  if (hands.empty()) return;
  Exec::download(host_x_, x_);
  Exec::download(host_xt_, x_t_);
  const double reach = kPinchReach * P_.dhat;
  bool moved = false;
  const bool weigh = opt_.pinch_stopping_rule && residual_rule();
  if (weigh) pinch_w_host_.assign(n_, 0.0);
  for (const auto& [k0, k1] : hands) {
    const Collider& c0 = (*colliders_)[k0];
    const Collider& c1 = (*colliders_)[k1];
    const Eigen::Isometry3d s0 = c0.checked_pose(col_t0_), s1 = c1.checked_pose(col_t0_);
    const Eigen::Isometry3d m0 = col_end_[k0] * s0.inverse(), m1 = col_end_[k1] * s1.inverse();
    for (int i = 0; i < n_; ++i) {
      if (kin_fixed_host_[i]) continue;
      const Vec3 p(host_xt_[3 * i], host_xt_[3 * i + 1], host_xt_[3 * i + 2]);
      if (c0.distance_bound(p, s0) > reach || c1.distance_bound(p, s1) > reach) continue;
      const ColliderQuery q0 = c0.query(p, s0);
      if (q0.distance > reach) continue;
      const ColliderQuery q1 = c1.query(p, s1);
      if (q1.distance > reach || !(q0.normal.dot(q1.normal) < -0.5)) continue;
      // Each pad's motion weighted by nearness: a vertex on a pad goes with it, one midway with
      // both halves (the fingers closing or turning squeeze the stack evenly).
      const double d0 = std::max(0.0, q0.distance), d1 = std::max(0.0, q1.distance);
      const double w0 = d0 + d1 > 0 ? d1 / (d0 + d1) : 0.5;
      const Vec3 to = w0 * (m0 * p) + (1 - w0) * (m1 * p);
      // Across the pads only: along their faces the inertial guess stays, so a pinch that slips
      // (too little friction for the load) keeps slipping; carried along the faces too, a
      // frictionless pinch lifted a strip with the hand (the inexact Newton solve stopped near
      // the carried guess, RobotArms.FingersHoldAStripByFrictionAndLiftIt).
      const Vec3 inertial(host_x_[3 * i], host_x_[3 * i + 1], host_x_[3 * i + 2]);
      // Kept clear of the table as the inertial guess is (pads close on lying cloth).
      const Vec3 step = detail::clear_of_table(P_, p, inertial + q0.normal * q0.normal.dot(to - inertial) - p);
      for (int r = 0; r < 3; ++r) host_x_[3 * i + r] = p[r] + step[r];
      moved = true;
      if (weigh && pinch_w_host_[i] == 0) pinch_w_host_[i] = data_->mass[i], pinch_mass_ += data_->mass[i];
    }
  }
  if (moved) Exec::upload(x_, host_x_);
  if (pinch_mass_ > 0) Exec::upload(pinch_w_, pinch_w_host_);
}

/// Collider k's pose at fraction s of its motion over the step.
template <class Exec>
Eigen::Isometry3d Solver<Exec>::pose_along(int k, double s) const {
  return (*colliders_)[k].checked_pose(col_t0_ + s * (col_t1_ - col_t0_));
}

/// Collider k ends this step at `pose` (a yielding one stopped short, a pad in the solve): col_end_
/// and the host copy of the poses (its R1, t1); the caller uploads col_pose_host_.
template <class Exec>
void Solver<Exec>::set_collider_end(int k, const Eigen::Isometry3d& pose) {
  col_end_[k] = pose;
  double* q = col_pose_host_.data() + 24 * k + 12;
  for (int r = 0; r < 3; ++r)
    for (int j = 0; j < 3; ++j) q[3 * r + j] = pose.linear()(r, j);
  for (int r = 0; r < 3; ++r) q[9 + r] = pose.translation()[r];
}

/// After CCD scaled the predictor's motion back, the guess may lie inside a collider's end pose.
/// Moving it out again is not guarded by CCD: where a gripper pad presses a stack of pinched
/// layers, the layer under the pad went onto the layer beneath (they met at 1e-17 m, Newton's step
/// fraction fell to 0 and the fail-safe ran, step after step; docs/robot.md, "Pads that stop
/// short"). A yielding collider stops short instead, at the largest fraction s of its motion over
/// the step (bisection, to 1/4096) at which every free vertex of the guess keeps half the clearance
/// it had from the collider at the step's start (capped at dhat/4, at least the clearance floor). The guess may have to go back too: the guess and the colliders
/// go back together along their paths, x_t + b (x - x_t) (its CCD-checked path: every point of it is
/// free of crossings) and the pose at b of the step's motion, to the largest b at which the guess
/// clears them all; then each collider goes on from b as far as that guess allows. The backend's
/// poses, x_, col_reached_ and col_clear_ follow. The barrier then pushes the whole stack in the
/// Newton solve, and the collider's owner starts the next step where it stopped
/// (Scene::collider_reached). Colliders of one yield group (Collider::yield_group: the two pads of
/// a hand) stop together, at the fraction the least advanced of them reached.
template <class Exec>
void Solver<Exec>::stop_yielding_colliders() {
  Exec::download(host_x_, x_);
  Exec::download(host_xt_, x_t_);
  const std::vector<std::vector<double>> keep = yielding_clearances();
  auto clear = [&](int k, const Eigen::Isometry3d& pose, double b) { return keeps_clear(k, pose, b, keep); };
  std::vector<int> stop;
  auto stops = [&](int k) { return std::find(stop.begin(), stop.end(), k) != stop.end(); };
  // A stopped collider's group (Collider::yield_group: the pads of one hand) stops with it.
  auto add_groups = [&] {
    for (size_t s = 0; s < stop.size(); ++s) {
      const int g = (*colliders_)[stop[s]].yield_group();
      if (g < 0) continue;
      for (int k = 0; k < n_col_; ++k)
        if ((*colliders_)[k].yielding() && (*colliders_)[k].yield_group() == g && !stops(k)) stop.push_back(k);
    }
  };
  for (int k = 0; k < n_col_; ++k)
    if ((*colliders_)[k].yielding() && !clear(k, col_end_[k], 1.0)) stop.push_back(k);
  add_groups();
  if (stop.empty()) {
    for (int k = 0; k < n_col_; ++k) col_clear_[k] = (*colliders_)[k].yielding();
    return;
  }
  // The guess and the stopped colliders go back together along their paths (x_t + u (x - x_t), the
  // pose at u of the step's motion): at u = 0 both are where the last step ended, clear of each
  // other; cloth the predictor moves along with a pad stays clear of it all the way. A yielding
  // collider the guess that went back is no longer clear of joins them, until none is left.
  auto clear_together = [&](double u) {
    return std::all_of(stop.begin(), stop.end(), [&](int k) { return clear(k, pose_along(k, u), u); });
  };
  double b = 1.0;
  for (bool grew = true; grew;) {
    if (!clear_together(0.0)) {  // x_t itself within the floor (or inside): no stop helps, the projection moves it out
      gd::log().debug("yielding colliders: the step's start is within the clearance floor of one; projecting instead");
      return;
    }
    double lo = 0, hi = 1;
    for (int it = 0; it < 12; ++it) {
      const double mid = 0.5 * (lo + hi);
      (clear_together(mid) ? lo : hi) = mid;
    }
    b = lo;
    grew = false;
    for (int k = 0; k < n_col_; ++k)
      if ((*colliders_)[k].yielding() && !stops(k) && !clear(k, col_end_[k], b)) {
        stop.push_back(k);
        grew = true;
      }
    add_groups();
  }
  for (int k = 0; k < n_col_; ++k) col_clear_[k] = (*colliders_)[k].yielding();
  // Then each as far on as the guess at b allows; a group as far as its member that got least far
  // (each member clear there, else where they all went back to: at b every stopped one is clear).
  std::vector<double> reach(n_col_, 1.0);
  for (const int k : stop) {
    double lo = b, hi = 1;
    for (int it = 0; it < 12; ++it) {
      const double mid = 0.5 * (lo + hi);
      (clear(k, pose_along(k, mid), b) ? lo : hi) = mid;
    }
    reach[k] = lo;
  }
  for (const int k : stop) {
    const int g = (*colliders_)[k].yield_group();
    if (g < 0) continue;
    double s = reach[k];
    for (const int j : stop)
      if ((*colliders_)[j].yield_group() == g) s = std::min(s, reach[j]);
    reach[k] = s;
  }
  for (const int k : stop) {
    const int g = (*colliders_)[k].yield_group();
    if (g < 0 || reach[k] <= b) continue;
    bool all_clear = true;
    for (const int j : stop)
      if ((*colliders_)[j].yield_group() == g) all_clear = all_clear && clear(j, pose_along(j, reach[k]), b);
    if (!all_clear)
      for (const int j : stop)
        if ((*colliders_)[j].yield_group() == g) reach[j] = b;
  }
  if (gd::log().should_log(spdlog::level::debug)) log_what_stops(stop, reach, b, keep);
  for (const int k : stop) {
    const double lo = reach[k];
    col_reached_[k] = lo;
    set_collider_end(k, pose_along(k, lo));
    gd::log().debug("collider {} stops at {:.3f} of its motion (guess at {:.3f} of its path)", k, lo, b);
  }
  Exec::upload(col_pose_, col_pose_host_);
  if (b < 1.0) {
    for (size_t j = 0; j < host_x_.size(); ++j) host_x_[j] = host_xt_[j] + b * (host_x_[j] - host_xt_[j]);
    Exec::upload(x_, host_x_);
  }
}

/// Debug log (guess_pinch_first): what bounds a leg's CCD, the table or a self-contact pair; for
/// the pair that allows the least (its step fraction recomputed on the host), its kind, its four
/// vertices, which of them the predictor carried with a pinch (carry_pinched_cloth) and how far
/// each moves in the leg, so a leg cut back by the pinch's own layers tells from one cut by cloth
/// nearby.
template <class Exec>
void Solver<Exec>::log_what_cuts(const char* leg, const CcdBounds& b) {
  if (b.table <= b.self) {
    gd::log().debug("{}: CCD bound {:.4f} by the table (self-contact {:.4f})", leg, b.table, b.self);
    return;
  }
  const ContactPairs c = cand_.to_host();
  std::vector<double> x, dx;
  Exec::download(x, x_);
  Exec::download(dx, dx_);
  auto at = [](const std::vector<double>& v, int i) { return Vec3(v[3 * i], v[3 * i + 1], v[3 * i + 2]); };
  int worst = -1;
  double least = 1.0;
  for (int k = 0; k < c.size(); ++k) {
    const Real alpha = detail::pair_ccd_fraction(c.v.data() + 4 * k, c.type[k], x.data(), dx.data(), P_.ccd_floor);
    if (alpha < least) least = alpha, worst = k;
  }
  if (worst < 0) return;
  const int* v = c.v.data() + 4 * worst;
  auto tag = [&](int i) { return pinched(i) ? "pinched" : (at(dx, i).norm() > 0 ? "moving" : "still"); };
  gd::log().debug("{}: CCD bound {:.4f} by {} pair: vertices {} ({}, moving {:.2e} m), {} ({}, {:.2e}), {} ({}, {:.2e}), "
                  "{} ({}, {:.2e})",
                  leg, b.self, c.type[worst] == 0 ? "a point-triangle" : "an edge-edge", v[0], tag(v[0]), at(dx, v[0]).norm(),
                  v[1], tag(v[1]), at(dx, v[1]).norm(), v[2], tag(v[2]), at(dx, v[2]).norm(), v[3], tag(v[3]),
                  at(dx, v[3]).norm());
}

/// Debug log (stop_yielding_colliders): for each stopped collider, the free vertex or surface
/// sample that keeps it from going further (the closest to losing its clearance just past where it
/// stopped): index, whether a vertex is pinched (carry_pinched_cloth) or a sample's triangle, its
/// clearance kept and due, and where it lies in
/// the collider's frame, so a pad stopped by its own pinch tells from one stopped by cloth round it.
template <class Exec>
void Solver<Exec>::log_what_stops(const std::vector<int>& stop, const std::vector<double>& reach, double b,
                                  const std::vector<std::vector<double>>& keep) const {
  for (const int k : stop) {
    const Collider& c = (*colliders_)[k];
    const double s = std::min(1.0, reach[k] + 1.0 / 4096);
    const Eigen::Isometry3d pose = c.checked_pose(col_t0_ + s * (col_t1_ - col_t0_));
    int worst = -1;
    double worst_margin = INFINITY, worst_d = 0;
    for (int i = 0; i < n_; ++i) {
      if (kin_fixed_host_[i]) continue;
      const double d = c.query(guess_at(i, b), pose).distance;
      if (d - keep[k][i] < worst_margin) worst_margin = d - keep[k][i], worst = i, worst_d = d;
    }
    if (samp_live_ && col_sampled_host_[k])  // the surface samples near it (index n_ + s), as keeps_clear
      for (const int s : samp_near_[k]) {
        if (!(keep[k][n_ + s] > -INFINITY)) continue;
        const double d = c.query(sample_guess_at(s, b), pose).distance;
        if (d - keep[k][n_ + s] < worst_margin) worst_margin = d - keep[k][n_ + s], worst = n_ + s, worst_d = d;
      }
    if (worst < 0) continue;
    const bool sample = worst >= n_;
    const Vec3 p = sample ? sample_at(host_xt_, worst - n_)
                          : Vec3(host_xt_[3 * worst], host_xt_[3 * worst + 1], host_xt_[3 * worst + 2]);
    const Vec3 local = pose.inverse() * p;
    const std::string who = sample ? fmt::format("surface sample {} (triangle {})", worst - n_, samples_.tri[worst - n_])
                                   : fmt::format("vertex {} ({})", worst, pinched(worst) ? "pinched" : "not pinched");
    gd::log().debug("collider {} held at {:.4f} by {}: clearance {:.3e} m past it, due {:.3e}; at the start in its "
                    "frame ({:.4f}, {:.4f}, {:.4f}) m",
                    k, reach[k], who, worst_d, keep[k][worst], local.x(), local.y(), local.z());
  }
}

}  // namespace gd::sim
