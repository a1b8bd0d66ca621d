#pragma once
/// \file
/// The self-contact stage: the candidates along each motion (candidates.h) and the active pairs
/// among them (active_set.h), adaptive barrier stiffness, the intersection count and the
/// untangling fail-safe.
/// Member functions of Solver<Exec> (solver_impl.h), written once for every backend.

#include "sim/solver/solver_impl.h"

namespace gd::sim {

/// Active pairs (closer than dhat) at the current x, with their Hessian storage.
template <class Exec>
void Solver<Exec>::select_contacts() {
  if (!self_) return;
  stiffen_pressed_pairs(select_active(x_, x_gen_));  // active_set.h
  Exec::resize_for_overwrite(act_H_, kPairBlockValues * static_cast<size_t>(act_.n));
  Exec::resize_for_overwrite(act_gd_, 48 * static_cast<size_t>(act_.n));
}

/// Candidates along the Newton step x -> x + dx (for CCD and the line search; candidates.h) and
/// the active pairs at x among them. A step whose query would flood the pair budget is halved
/// first, dx too. False (nothing done) when dx is not finite: a linear solve that broke down (a
/// robot's pinch pressed to 1e-16 m once gave one), which the broad phase would refuse as bad input.
template <class Exec>
bool Solver<Exec>::find_contacts_along_step() {
  if (!self_) return true;
  Exec::resize_for_overwrite(x1_, 3 * static_cast<size_t>(n_));
  const double* x = Exec::ptr(x_);
  double* dx = Exec::ptr(dx_);
  double* x1 = Exec::ptr(x1_);
  Exec::for_each(3 * n_, [=] GD_HD_LAMBDA(int k) { x1[k] = dx[k] + x[k]; }, Exec::kParallelMinVector);  // the step's end
  const int halvings = find_candidates(x_, x1_, true);
  if (halvings < 0) return false;
  if (halvings > 0) Exec::for_each(3 * n_, [=] GD_HD_LAMBDA(int k) { dx[k] = x1[k] - x[k]; }, Exec::kParallelMinVector);
  select_along(x_, x_gen_);  // candidates along the step, active pairs at x
  return true;
}

/// IPC-style adaptive stiffness of the self-contact barrier: it starts so that a vertex's
/// weight rests at dhat/2, but grippers and stacked layers press harder. When a pair's gap
/// closes below a tenth of dhat the stiffness doubles (up to 1e4 x); when every active pair is
/// more than kRelaxGapFraction dhat apart again (nothing pressed; no pair at all counts too) it
/// halves, back down to 1 x. Kept stiff, the barrier made Newton stop at its iteration cap in
/// every later step, and the motion crept: a sleeve stood 33 cm tall for seconds after a fold,
/// then fell to 8 cm in 0.5 s once the stiffness was back at 1 x (docs/validation.md).
/// (The table keeps its weight-calibrated stiffness: cloth rests on it under gravity alone.)
/// min_distance: the closest active pair at the end of the step.
template <class Exec>
void Solver<Exec>::adapt_barrier_stiffness(double min_distance) {
  if (!self_) return;
  if (min_distance < 0.1 * P_.dhat_self) {
    scale_barrier_stiffness(2);
  } else if (min_distance > kRelaxGapFraction * P_.dhat_self) {
    scale_barrier_stiffness(0.5);
  }
}

/// Within the step, before each Newton iteration: while a pair is closer than
/// kPressedGapFloors CCD floors (10 um at dhat = 1 mm) the barrier stiffness doubles (up to the
/// same 1e4 x). A grip or a stack pressing harder than the barrier can hold at that gap would
/// otherwise squeeze the pair towards the floor, where CCD lets it close by half per iteration,
/// until rounding decides the exact intersection test. Doubling per iteration rather than per
/// step lifts the equilibrium gap (kappa dhat^2 / force) before the pair gets there.
/// closest: the closest active pair at the iterate.
template <class Exec>
void Solver<Exec>::stiffen_pressed_pairs(double closest) {
  if (kappa_scale_ < kKappaScaleMax && closest < kPressedGapFloors * P_.ccd_floor) scale_barrier_stiffness(2);
}

/// Multiplies the self-contact barrier stiffness by `factor`, kept within [1, kKappaScaleMax];
/// the current candidate and active pairs take the new stiffness at once.
template <class Exec>
void Solver<Exec>::scale_barrier_stiffness(double factor) {
  const double scale = std::clamp(kappa_scale_ * factor, 1.0, kKappaScaleMax);
  if (scale == kappa_scale_) return;
  scale_pair_stiffness(scale / kappa_scale_);  // candidates found later take kappa_scale_ itself
  kappa_scale_ = scale;
}

/// Exact count of intersecting triangle pairs after the step (on the host); the untangling
/// fail-safe runs when there are any.
template <class Exec>
void Solver<Exec>::check_intersections(StepStats* st) {
  if (!self_ || !opt_.check_intersections) return;
  Exec::download(host_x_, x_);
  timed(st->stage.intersections, [&] { st->intersecting_pairs = self_->count_intersections(host_x_); });
  st->intersecting_found = st->intersecting_pairs;
  if (st->intersecting_pairs > 0 && opt_.untangle) {
    st->untangled = true;
    timed(st->stage.untangle, [&] { st->intersecting_pairs = self_->untangle(&host_x_, kin_fixed_host_); });
    Exec::upload(x_, host_x_);
    moved_x();
  }
}

/// Largest grip spring pull over the held vertices, N.
template <class Exec>
double Solver<Exec>::max_grip_force() {
  const detail::View V = view();
  const detail::Params P = P_;
  const double* x = Exec::ptr(x_);
  return Exec::max(n_, [=] GD_HD_LAMBDA(int i) {
    return V.kin[i] ? grip_spring_force(detail::load3(x, i), detail::load3(V.kin_target, i),
                                        detail::grip_stiffness(P, V.mass[i]), P.kin_force_max)
                    : 0.0;
  });
}

namespace detail {
/// The barrier's gradient at free vertex i against collider c at its end-of-step pose: the
/// reaction the collider receives from that vertex (zero beyond dhat; zero for a vertex inside).
GD_HD Vec3 collider_reaction(const View& V, const Params& P, const double* x, int c, int i) {
  const double* q = V.col_pose + 24 * c;
  const Mat3 R1 = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(q + 12);
  const Vec3 t1(q[21], q[22], q[23]);
  Vec3 g;
  const Real e = point_collider_energy(load3(x, i), R1, t1, V.col_shape[c], 0.0, P.dhat,
                                       P.kappa_per_mass * V.mass[i] * V.col_kappa[c], &g, nullptr, HessianKind::kNone,
                                       &V.col_mesh);
  return e > 0 && std::isfinite(e) ? g : Vec3::Zero();
}
/// The reaction collider c receives from the surface samples of triangle t at x (zero unless c is
/// sampled), each sample's barrier gradient scaled by its mass; with `z` (non-null), only the samples
/// whose push along *z has the sign `sign`; `count` (non-null) gets how many samples push.
GD_HD Vec3 samples_reaction(const View& V, const Params& P, const double* x, int c, int t, const Vec3* z = nullptr,
                            int sign = 1, int* count = nullptr) {
  if (count) *count = 0;
  Vec3 sum = Vec3::Zero();
  const int first = V.samp_ptr[t], last = V.samp_ptr[t + 1];
  if (first == last || !V.col_sampled[c]) return sum;
  const int* v = V.tris + 3 * t;
  const Vec3 a[3] = {load3(x, v[0]), load3(x, v[1]), load3(x, v[2])};
  if (!triangle_within(V, c, a, P.dhat)) return sum;
  const double* q = V.col_pose + 24 * c;
  const Mat3 R1 = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(q + 12);
  const Vec3 t1(q[21], q[22], q[23]);
  for (int s = first; s < last; ++s) {
    if (!V.samp_on[s]) continue;
    Vec3 g;
    const Real e = point_collider_energy(sample_point(V, x, s), R1, t1, V.col_shape[c], 0.0, P.dhat,
                                         P.kappa_per_mass * V.samp_mass[s] * V.col_kappa[c], &g, nullptr,
                                         HessianKind::kNone, &V.col_mesh);
    if (!(e > 0 && std::isfinite(e))) continue;
    if (z && !(sign * g.dot(*z) > 0)) continue;
    sum += g;
    if (count) ++*count;
  }
  return sum;
}
/// Collider c's local z axis at its end-of-step pose (world frame).
GD_HD Vec3 collider_z(const View& V, int c) {
  const double* q = V.col_pose + 24 * c + 12;  // R1, row-major: its third column
  return Vec3(q[2], q[5], q[8]);
}
}  // namespace detail

/// Barrier force on each collider from the cloth (SolverBase::collider_forces): the reaction to
/// the barrier's push on each free vertex and surface sample, at the colliders' end-of-step poses.
template <class Exec>
std::vector<double> Solver<Exec>::collider_forces() {
  std::vector<double> out(3 * static_cast<size_t>(n_col_), 0.0);
  if (n_col_ == 0) return out;
  const detail::View V = view();
  const detail::Params P = P_;
  const double* x = Exec::ptr(x_);
  for (int c = 0; c < n_col_; ++c)
    for (int k = 0; k < 3; ++k)
      out[3 * c + k] = Exec::sum(n_ + (V.n_samp > 0 ? V.nt : 0), [=] GD_HD_LAMBDA(int i) {
        if (i >= V.n) return static_cast<double>(detail::samples_reaction(V, P, x, c, i - V.n)[k]);
        return V.fixed[i] ? 0.0 : static_cast<double>(detail::collider_reaction(V, P, x, c, i)[k]);
      });
  return out;
}

/// Each collider's push along its own z axis split by sign (SolverBase::collider_pushes): the
/// vertices and surface samples pushing it towards +z and their sum, those pushing it towards -z
/// and theirs.
template <class Exec>
std::vector<double> Solver<Exec>::collider_pushes() {
  std::vector<double> out(4 * static_cast<size_t>(n_col_), 0.0);
  if (n_col_ == 0) return out;
  const detail::View V = view();
  const detail::Params P = P_;
  const double* x = Exec::ptr(x_);
  for (int c = 0; c < n_col_; ++c)
    for (const int sign : {1, -1}) {
      // The vertices, then (by triangle) the surface samples: the push and how many points push.
      const auto push = [=] GD_HD_LAMBDA(int i, int* count) {
        const Vec3 z = detail::collider_z(V, c);
        if (i >= V.n) return detail::samples_reaction(V, P, x, c, i - V.n, &z, sign, count).dot(z);
        *count = 0;
        if (V.fixed[i]) return 0.0;
        const double f = detail::collider_reaction(V, P, x, c, i).dot(z);
        if (!(sign * f > 0)) return 0.0;
        *count = 1;
        return f;
      };
      const int points = n_ + (V.n_samp > 0 ? V.nt : 0);
      out[4 * c + (sign > 0 ? 0 : 1)] = Exec::sum(points, [=] GD_HD_LAMBDA(int i) {
        int count = 0;
        return push(i, &count);
      });
      out[4 * c + (sign > 0 ? 2 : 3)] = Exec::sum(points, [=] GD_HD_LAMBDA(int i) {
        int count = 0;
        push(i, &count);
        return static_cast<double>(count);
      });
    }
  return out;
}

template <class Exec>
std::string Solver<Exec>::infinite_terms() {
  const detail::View V = view();
  const detail::Params P = P_;
  const double* x = Exec::ptr(x_);
  std::string out;
  for (int c = 0; c < n_col_; ++c) {
    const double inside = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) {
      if (V.fixed[i]) return 0.0;
      const double* q = V.col_pose + 24 * c;
      const Mat3 R1 = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(q + 12);
      const Vec3 t1(q[21], q[22], q[23]);
      const Real e = point_collider_energy(detail::load3(x, i), R1, t1, V.col_shape[c], 0.0, P.dhat, 1.0, nullptr,
                                           nullptr, HessianKind::kNone, &V.col_mesh);
      return std::isfinite(e) ? 0.0 : 1.0;
    });
    if (inside > 0) out += fmt::format("{} vertices inside collider {}; ", inside, c);
    const double samples = Exec::sum(V.n_samp, [=] GD_HD_LAMBDA(int s) {
      if (!V.col_sampled[c] || !V.samp_on[s]) return 0.0;  // a diagnostic: every sample
      const double* q = V.col_pose + 24 * c;
      const Mat3 R1 = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(q + 12);
      const Vec3 t1(q[21], q[22], q[23]);
      const Real e = point_collider_energy(detail::sample_point(V, x, s), R1, t1, V.col_shape[c], 0.0, P.dhat, 1.0,
                                           nullptr, nullptr, HessianKind::kNone, &V.col_mesh);
      return std::isfinite(e) ? 0.0 : 1.0;
    });
    if (samples > 0) out += fmt::format("{} surface samples inside collider {}; ", samples, c);
  }
  if (P_.table) {
    const double below = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) {
      const Real e = plane_barrier_energy(detail::load3(x, i), P.table_n, P.table_offset, P.dhat, 1.0, nullptr, nullptr);
      return V.fixed[i] || std::isfinite(e) ? 0.0 : 1.0;
    });
    if (below > 0) out += fmt::format("{} vertices at or below the table; ", below);
  }
  if (self_) out += fmt::format("closest self-contact pair {:.3g} m", min_active_distance(x_, x_gen_));
  return out.empty() ? "no barrier (a non-finite position or element)" : out;
}

template <class Exec>
bool Solver<Exec>::inside_a_collider(const std::vector<double>& x, bool samples) const {
  for (int k = 0; k < n_col_; ++k) {
    const Collider& c = (*colliders_)[k];
    const Eigen::Isometry3d& pose = col_end_[k];
    for (int i = 0; i < n_; ++i) {
      if (kin_fixed_host_[i]) continue;
      const Vec3 p(x[3 * i], x[3 * i + 1], x[3 * i + 2]);
      if (c.inside(p, pose)) return true;
    }
    if (samples && samples_inside(k, x, pose)) return true;
  }
  return false;
}

}  // namespace gd::sim
