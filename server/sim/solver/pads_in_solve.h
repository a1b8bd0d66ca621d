#pragma once
/// \file
/// Pads in the solve (SceneOptions::pad_stiffness > 0). The predictor stops a hand's pads short
/// where its guess cannot keep the cloth clear of them (predictor.h, stop_yielding_colliders);
/// a kinematic pad then stays there for the whole step, however little the cloth resists, and a
/// hand pulling cloth it holds stalled step after step (docs/robot.md, "Where the T-shirt's robot
/// fold stalls"). Here such a hand becomes one more unknown of Newton's system: s, how far along
/// its step's motion its pads are (both pads of a yield group together, as the predictor stops
/// them), pulled towards s = 1 by a spring of energy K L^2 (1 - s)^2 / 2 (L: the pads' path over
/// the step) and held back by the barrier and friction of the cloth it touches, each a function of
/// the vertex's position relative to the moving pad. The system
///   [A  B] [dx]     [g  ]
///   [B' C] [ds] = - [g_s]
/// is solved by its Schur complement on the hands (one or two unknowns): one more PCG solve per
/// hand, A Y = B, then (C - B'Y) ds = -g_s - B'y0 with y0 = -A^-1 g, and dx = y0 - Y ds. CCD bounds
/// each vertex's motion relative to a moving pad; the line search evaluates the pads where the
/// trial puts them. Member functions of Solver<Exec> (solver_impl.h); the couplings are computed
/// on the host (a few hundred vertices lie within a pad's reach), with the same per-vertex
/// collider term the backend sums (element_terms.h, add_collider_vertex_terms), for the vertices
/// and the surface samples (a sample's row spread over its triangle's corners by its weights).

#include <Eigen/Dense>

#include "sim/solver/solver_impl.h"

namespace gd::sim {

/// After the predictor: every hand whose pads it stopped short joins the solve.
template <class Exec>
void Solver<Exec>::begin_pad_dofs() {
  pad_hands_.clear();
  pad_moved_ = 0;
  if (!(opt_.pad_stiffness > 0) || n_col_ == 0) return;
  for (int k = 0; k < n_col_; ++k) {
    const Collider& c = (*colliders_)[k];
    if (!c.yielding() || !(col_reached_[k] < 1.0)) continue;
    const int g = c.yield_group();
    auto it = std::find_if(pad_hands_.begin(), pad_hands_.end(),
                           [&](const PadHand& h) { return g >= 0 && h.group == g; });
    if (it == pad_hands_.end()) {
      pad_hands_.emplace_back();
      it = pad_hands_.end() - 1;
      it->group = g;
      it->s = col_reached_[k];
    }
    it->pads.push_back(k);
    it->s = std::min(it->s, col_reached_[k]);
  }
  for (PadHand& h : pad_hands_) {
    double path = 0;
    for (const int k : h.pads) path += (pose_along(k, 1.0).translation() - pose_along(k, 0.0).translation()).norm();
    path /= static_cast<double>(h.pads.size());
    h.k_path2 = opt_.pad_stiffness * path * path;
  }
  pad_hands_.erase(std::remove_if(pad_hands_.begin(), pad_hands_.end(), [](const PadHand& h) { return !(h.k_path2 > 0); }),
                   pad_hands_.end());
  if (pad_hands_.empty()) return;
  set_pads_at(0.0);
  gd::log().debug("pads in the solve: {} hand(s)", pad_hands_.size());
}

/// Each hand's pads at s + alpha ds (clamped to its step), their end poses uploaded.
template <class Exec>
void Solver<Exec>::set_pads_at(double alpha) {
  for (const PadHand& h : pad_hands_) {
    const double s = std::clamp(h.s + alpha * h.ds, 0.0, 1.0);
    for (const int k : h.pads) {
      set_collider_end(k, pose_along(k, s));
      col_reached_[k] = s;
    }
  }
  Exec::upload(col_pose_, col_pose_host_);
}

/// The hands' springs at s + alpha ds.
template <class Exec>
double Solver<Exec>::pad_spring_energy(double alpha) const {
  double e = 0;
  for (const PadHand& h : pad_hands_) {
    const double lag = 1.0 - std::clamp(h.s + alpha * h.ds, 0.0, 1.0);
    e += 0.5 * h.k_path2 * lag * lag;
  }
  return e;
}

/// The hands' part of the directional derivative g·d.
template <class Exec>
double Solver<Exec>::pad_slope() const {
  double slope = 0;
  for (const PadHand& h : pad_hands_) slope += h.grad * h.ds;
  return slope;
}

/// Each hand's gradient, Hessian and coupling to the cloth at the current iterate: the spring,
/// and for every free vertex within a pad's reach the barrier and friction of that pad alone. A
/// pad moved by ds v (v: its motion per unit s at the vertex) changes a term as the vertex moved by
/// -ds v would (to first order: the pad's turn over a step is small), so with the term's gradient
/// g and PSD Hessian H: dE/ds = -g.v, d2E/ds2 = v'Hv, d2E/dx ds = -Hv (the term's Hessian in (x, s)
/// is J'HJ with J = [I, -v]: PSD).
template <class Exec>
void Solver<Exec>::pad_couplings() {
  Exec::download(host_x_, x_);
  Exec::download(host_xt_, x_t_);
  const detail::Params P = P_;
  const ColliderMeshView mesh{col_vertices_host_.data(), col_tris_host_.data()};
  for (PadHand& h : pad_hands_) {
    h.grad = -h.k_path2 * (1.0 - h.s);
    h.hess = h.k_path2;
    h.coupling.assign(3 * static_cast<size_t>(n_), 0.0);
    h.rate.clear();
    for (const int k : h.pads) {
      const Collider& c = (*colliders_)[k];
      const Eigen::Isometry3d at = pose_along(k, h.s), start = c.checked_pose(col_t0_);
      const double eps = h.s + 1e-3 <= 1.0 ? 1e-3 : -1e-3;
      const Eigen::Isometry3d M = pose_along(k, h.s + eps) * at.inverse();  // a point from s to s + eps
      Eigen::Matrix<double, 3, 4> rate;  // the pad's displacement per unit s at world point p: A p + b
      rate.leftCols<3>() = (M.linear() - Mat3::Identity()) / eps;
      rate.col(3) = M.translation() / eps;
      h.rate.push_back(rate);
      for (int i = 0; i < n_; ++i) {
        if (kin_fixed_host_[i]) continue;
        const Vec3 p(host_x_[3 * i], host_x_[3 * i + 1], host_x_[3 * i + 2]);
        const Vec3 pt(host_xt_[3 * i], host_xt_[3 * i + 1], host_xt_[3 * i + 2]);
        if (c.distance_bound(p, at) > P.dhat && c.distance_bound(pt, start) > P.dhat) continue;
        Real e = 0;
        Vec3 g = Vec3::Zero();
        Mat3 H = Mat3::Zero();
        detail::add_collider_vertex_terms(P, p, pt, col_pose_host_.data() + 24 * k, col_shape_host_[k], mesh,
                                          P.kappa_per_mass * data_->mass[i] * col_kappa_host_[k], col_mu_host_[k],
                                          &e, &g, &H);
        const Vec3 v = rate.leftCols<3>() * p + rate.col(3);
        h.grad -= g.dot(v);
        h.hess += v.dot(H * v);
        const Vec3 b = -(H * v);
        for (int r = 0; r < 3; ++r) h.coupling[3 * i + r] += b[r];
      }
      if (!samp_live_ || !col_sampled_host_[k]) continue;
      const double* pose = col_pose_host_.data() + 24 * k;
      for (int t = 0; t < data_->triangles(); ++t) {  // the surface samples, as the backend sums them
        if (samples_.tri_ptr[t] == samples_.tri_ptr[t + 1]) continue;
        const int* tv = data_->tris.data() + 3 * t;
        Vec3 a[3], at0[3];
        for (int j = 0; j < 3; ++j)
          for (int r = 0; r < 3; ++r) a[j][r] = host_x_[3 * tv[j] + r], at0[j][r] = host_xt_[3 * tv[j] + r];
        if (!detail::triangle_near_collider(a, at0, pose, col_shape_host_[k], P.dhat)) continue;
        for (int s = samples_.tri_ptr[t]; s < samples_.tri_ptr[t + 1]; ++s) {
          if (std::binary_search(samp_off_.begin(), samp_off_.end(), s)) continue;
          const double* w = samples_.w.data() + 3 * s;
          const Vec3 p = w[0] * a[0] + w[1] * a[1] + w[2] * a[2], pt = w[0] * at0[0] + w[1] * at0[1] + w[2] * at0[2];
          Real e = 0;
          Vec3 g = Vec3::Zero();
          Mat3 H = Mat3::Zero();
          detail::add_collider_vertex_terms(P, p, pt, pose, col_shape_host_[k], mesh,
                                            P.kappa_per_mass * samples_.mass[s] * col_kappa_host_[k], col_mu_host_[k], &e,
                                            &g, &H);
          if (e == 0) continue;
          const Vec3 v = rate.leftCols<3>() * p + rate.col(3);
          h.grad -= g.dot(v);
          h.hess += v.dot(H * v);
          const Vec3 b = -(H * v);
          for (int j = 0; j < 3; ++j)
            if (!kin_fixed_host_[tv[j]])
              for (int r = 0; r < 3; ++r) h.coupling[3 * tv[j] + r] += w[j] * b[r];
        }
      }
    }
  }
}

/// The hands' steps ds from their Schur complement S ds = r, with an active set at both ends of
/// their motion: a hand at s = 1 whose step would take it past its commanded pose, or at s = 0
/// whose step would take it back along a path it has already made, stays there (ds = 0) and the
/// others, and the cloth, are solved again without it. Bounding the step length there instead
/// (pad_step_bound: (1 - s) / ds or s / -ds = 0) left every later iteration the same direction
/// and none of it: at s = 1 the cloth a hand held never got its correction (docs/robot.md, "A hand
/// at the end of its step"); at s = 0 the step of length 0 passed as converged and the whole
/// garment stood still for as long as the cloth pushed the pads back ("A hand at the other end of
/// its step").
template <class Exec>
Eigen::VectorXd Solver<Exec>::solve_pad_complement(const Eigen::MatrixXd& S, const Eigen::VectorXd& r) const {
  const int m = static_cast<int>(r.size());
  std::vector<bool> held(m, false);
  Eigen::VectorXd ds = Eigen::VectorXd::Zero(m);
  for (int round = 0; round <= m; ++round) {
    std::vector<int> free;
    for (int a = 0; a < m; ++a)
      if (!held[a]) free.push_back(a);
    ds.setZero();
    if (free.empty()) break;
    const int f = static_cast<int>(free.size());
    Eigen::MatrixXd Sf(f, f);
    Eigen::VectorXd rf(f);
    for (int a = 0; a < f; ++a) {
      rf(a) = r(free[a]);
      for (int b = 0; b < f; ++b) Sf(a, b) = S(free[a], free[b]);
    }
    Eigen::LDLT<Eigen::MatrixXd> ldlt(Sf);
    Eigen::VectorXd d(f);
    if (ldlt.info() == Eigen::Success && ldlt.isPositive() && (ldlt.vectorD().array() > 0).all()) {
      d = ldlt.solve(rf);
    } else {  // an inexact Y can spoil the complement: each hand on its own spring and the cloth's push
      for (int a = 0; a < f; ++a) d(a) = rf(a) / std::max(Sf(a, a), pad_hands_[free[a]].k_path2);
    }
    bool changed = false;
    for (int a = 0; a < f; ++a) {
      const PadHand& h = pad_hands_[free[a]];
      ds(free[a]) = d(a);
      const bool past_end = h.s >= 1.0 - kPadEndTolerance && d(a) > 0;
      const bool before_start = h.s <= kPadEndTolerance && d(a) < 0;
      if (past_end || before_start) {
        held[free[a]] = true;
        changed = true;
      }
    }
    if (!changed) return ds;
  }
  for (int a = 0; a < m; ++a)
    if (held[a]) ds(a) = 0.0;
  return ds;
}

/// Newton's direction with the hands in it (the Schur complement above), or solve_linear's alone
/// where no hand is in the solve. Leaves each hand's ds and each pad's motion bound for CCD
/// (col_move_). Returns the PCG iterations of all its solves.
template <class Exec>
int Solver<Exec>::solve_with_pads(double first_step) {
  int iters = solve_linear(first_step);  // y0 = -A^-1 g, in dx_
  if (pad_hands_.empty()) return iters;
  pad_couplings();
  const int m = static_cast<int>(pad_hands_.size());
  const size_t n3 = 3 * static_cast<size_t>(n_);
  std::vector<double> y0, g_saved, rhs(n3);
  Exec::download(y0, dx_);
  Exec::download(g_saved, g_);
  std::vector<std::vector<double>> Y(m);
  for (int a = 0; a < m; ++a) {  // A Y_a = B_a: the cloth's answer to hand a moving by one unit
    for (size_t j = 0; j < n3; ++j) rhs[j] = -pad_hands_[a].coupling[j];
    Exec::upload(g_, rhs);
    iters += solve_linear(0.0);
    Exec::download(Y[a], dx_);
  }
  Exec::upload(g_, g_saved);
  auto dot = [n3](const std::vector<double>& u, const std::vector<double>& w) {
    double acc = 0;
    for (size_t j = 0; j < n3; ++j) acc += u[j] * w[j];
    return acc;
  };
  Eigen::MatrixXd S(m, m);
  Eigen::VectorXd r(m);
  for (int a = 0; a < m; ++a) {
    r(a) = -pad_hands_[a].grad - dot(pad_hands_[a].coupling, y0);
    for (int b = 0; b < m; ++b) S(a, b) = (a == b ? pad_hands_[a].hess : 0.0) - dot(pad_hands_[a].coupling, Y[b]);
  }
  S = (0.5 * (S + S.transpose())).eval();
  Eigen::VectorXd ds = solve_pad_complement(S, r);
  for (int a = 0; a < m; ++a) {
    pad_hands_[a].ds = ds(a);
    for (size_t j = 0; j < n3; ++j) y0[j] -= Y[a][j] * ds(a);
  }
  for (size_t j = 0; j < n3; ++j)
    if (kin_fixed_host_[j / 3]) y0[j] = 0.0;
  Exec::upload(dx_, y0);
  // Each pad's displacement for the whole direction, affine in the point (CCD takes each vertex's
  // motion relative to it: step_bounds.h).
  std::vector<double> move = still_moves();
  for (const PadHand& h : pad_hands_) {
    for (size_t p = 0; p < h.pads.size(); ++p) {
      const Mat3 A = h.ds * h.rate[p].template leftCols<3>();
      const Vec3 b = h.ds * h.rate[p].col(3);
      double* m = move.data() + detail::kColMove * h.pads[p];
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) m[3 * r + c] = A(r, c);
      for (int r = 0; r < 3; ++r) m[9 + r] = b[r];
      m[12] = A.norm();  // Frobenius: at least the operator norm
    }
  }
  Exec::upload(col_move_, move);
  if (gd::log().should_log(spdlog::level::trace))
    for (int a = 0; a < m; ++a)
      gd::log().trace("pads in the solve: hand {} at s {:.4f}, ds {:.4g} (gradient {:.3g}, complement {:.3g})", a,
                      pad_hands_[a].s, ds(a), pad_hands_[a].grad, S(a, a));
  return iters;
}

/// The largest step fraction that keeps every hand within its step's motion (0 <= s <= 1).
template <class Exec>
double Solver<Exec>::pad_step_bound() const {
  double alpha = 1.0;
  for (const PadHand& h : pad_hands_) {
    if (h.ds > 0 && h.s + h.ds > 1.0) alpha = std::min(alpha, (1.0 - h.s) / h.ds);
    if (h.ds < 0 && h.s + h.ds < 0.0) alpha = std::min(alpha, h.s / -h.ds);
  }
  return std::max(alpha, 0.0);
}

/// The accepted step: each hand to s + alpha ds, its pads there.
template <class Exec>
void Solver<Exec>::move_pads(double alpha) {
  if (pad_hands_.empty()) return;
  pad_moved_ = 0;
  for (PadHand& h : pad_hands_) {
    const double s = std::clamp(h.s + alpha * h.ds, 0.0, 1.0);
    pad_moved_ = std::max(pad_moved_, std::abs(s - h.s) * std::sqrt(h.k_path2 / opt_.pad_stiffness));
    h.s = s;
    h.ds = 0;
  }
  set_pads_at(0.0);
  still_colliders();
}

/// No collider moves within Newton's iterations (View::col_move).
template <class Exec>
void Solver<Exec>::still_colliders() {
  Exec::upload(col_move_, still_moves());
}

/// View::col_move for colliders that do not move within Newton's iterations.
template <class Exec>
std::vector<double> Solver<Exec>::still_moves() const {
  std::vector<double> move(detail::kColMove * static_cast<size_t>(n_col_), 0.0);
  for (int k = 0; k < n_col_; ++k) move[detail::kColMove * k + 12] = -1;
  return move;
}

/// Whether the hands' last move was within Newton's tolerance (no hand in the solve: true).
template <class Exec>
bool Solver<Exec>::pads_settled() const {
  return pad_hands_.empty() || pad_moved_ <= opt_.newton_atol * P_.h;
}

}  // namespace gd::sim
