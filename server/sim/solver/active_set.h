#pragma once
/// \file
/// The self-contact active set on the backend: which candidates are closer than dhat at some
/// positions (select_active), the closest active pair (min_active_distance) and the lagged
/// friction frames of the active pairs (build_friction). Member functions of Solver<Exec>, one
/// code path for every backend: a loop over the pairs, then exclusive scans that give each kept
/// pair its place, so the lists come out in candidate order on any thread count and on the GPU,
/// and the host reads back only their lengths (one round trip per selection).
///
/// A pair's distance measured at some positions is kept per pair of the broad phase's answer
/// (its raw index) with the positions' generation (x_gen_: bumped whenever x_ changes),
/// so the line search's accepted point (store_candidate_distances) and a second selection at the
/// same iterate (the candidates along the Newton direction) measure nothing twice.

#include "sim/solver/solver_impl.h"

namespace gd::sim {

/// Active pairs at xs (positions of generation `gen`): the candidates closer than dhat with at
/// least one free vertex. Candidates with no free vertex, and pairs already at zero distance
/// (driven there by kinematic vertices: the untangling fail-safe's), leave the candidate list
/// too. Returns the closest active pair's distance (infinity when none).
template <class Exec>
double Solver<Exec>::select_active(const Vec<double>& xs, int gen) {
  return select_from(detail::ListSource{cand_.view()}, cand_.n, xs, gen);
}

/// select_active over the pairs of a source (detail::ListSource: the candidate list;
/// detail::AnswerSource: the broad phase's answer filtered to a motion, candidates.h): the
/// pairs the source keeps with a positive distance become the candidates, those closer than dhat
/// the active pairs, both in the source's order.
template <class Exec>
template <class Source>
double Solver<Exec>::select_from(const Source& S, int n, const Vec<double>& xs, int gen) {
  if (n == 0) {
    cand_.resize_for_overwrite(0);
    act_.resize_for_overwrite(0);
    act_raw_known_ = true;
    return std::numeric_limits<double>::infinity();
  }
  grow_for_overwrite(pair_d_, static_cast<size_t>(n));
  grow_for_overwrite(keep_pos_, static_cast<size_t>(n));
  grow_for_overwrite(act_pos_, static_cast<size_t>(n));
  const double* x = Exec::ptr(xs);
  const int* fixed = Exec::ptr(fixed_);
  double* rd = Exec::ptr(raw_dist_);
  int* rs = Exec::ptr(raw_stamp_);
  double* d = Exec::ptr(pair_d_);
  int* keep = Exec::ptr(keep_pos_);
  int* act = Exec::ptr(act_pos_);
  double* red = Exec::ptr(red_);
  const double dhat = P_.dhat_self;
  // Each pair's distance (kept, certainly beyond dhat, or measured; -1: not the source's, or no
  // free vertex) and its two flags.
  Exec::for_each(n, [=] GD_HD_LAMBDA(int c) {
    int v[4], type, r;
    double dist = -1.0;
    if (!S.pair(c, v, &type, &r)) {
      // not a candidate of this motion
    } else if (fixed[v[0]] && fixed[v[1]] && fixed[v[2]] && fixed[v[3]]) {
      // nothing to solve
    } else if (rs[r] == gen) {  // each raw pair is at most one pair of the source: no two threads share r
      dist = rd[r];
    } else if (pair_certainly_beyond(detail::load3(x, v[0]), detail::load3(x, v[1]), detail::load3(x, v[2]),
                                     detail::load3(x, v[3]), type, dhat)) {
      dist = INFINITY;  // a candidate, not active (not measured)
    } else {
      dist = detail::pair_distance(v, type, x);
      rd[r] = dist;
      rs[r] = gen;
    }
    d[c] = dist;
    keep[c] = dist > 0 ? 1 : 0;
    act[c] = dist > 0 && dist < dhat ? 1 : 0;
  }, Exec::kParallelMinHeavy);
  Exec::min_to(n, [=] GD_HD_LAMBDA(int c) { return act[c] ? d[c] : INFINITY; }, red + kRedClosest);
  // Places in the two lists, and their lengths, read back with the closest distance.
  Exec::exclusive_scan(keep_pos_, n);
  Exec::exclusive_scan(act_pos_, n);
  Exec::for_each(1, [=] GD_HD_LAMBDA(int) {
    const double last = d[n - 1];
    red[kRedCandidates] = keep[n - 1] + (last > 0 ? 1 : 0);
    red[kRedActive] = act[n - 1] + (last > 0 && last < dhat ? 1 : 0);
  }, 2);
  const double* r = read_reductions();
  const double closest = r[kRedClosest];
  const int kept = static_cast<int>(r[kRedCandidates]);
  // A list that keeps every pair stays where it is (nearly always: candidates are dropped only
  // at zero distance or with no free vertex).
  const bool compact = !Source::kList || kept < n;
  if (compact) cand_next_.resize_for_overwrite(kept);
  act_.resize_for_overwrite(static_cast<int>(r[kRedActive]));
  const detail::PairSlots K = compact ? cand_next_.slots() : detail::PairSlots{}, A = act_.slots();
  Exec::for_each(n, [=] GD_HD_LAMBDA(int c) {
    const double dist = d[c];
    if (!(dist > 0)) return;
    if (compact) S.write(c, K, keep[c]);
    if (dist < dhat) S.write(c, A, act[c]);
  }, Exec::kParallelMinHeavy);
  if (compact) cand_.swap(cand_next_);
  act_raw_known_ = true;
  return closest;
}

/// Smallest distance over the active pairs at xs (generation gen), infinity when none.
template <class Exec>
double Solver<Exec>::min_active_distance(const Vec<double>& xs, int gen) {
  const int n = act_.n;
  if (n == 0) return std::numeric_limits<double>::infinity();
  const detail::PairView A = act_.view();
  const double* x = Exec::ptr(xs);
  const double* rd = Exec::ptr(raw_dist_);
  const int* rs = Exec::ptr(raw_stamp_);
  const bool known = act_raw_known_;
  Exec::min_to(n, [=] GD_HD_LAMBDA(int c) {
    const int r = A.raw[c];
    return known && rs[r] == gen ? rd[r] : detail::pair_distance(A.v + 4 * c, A.type[c], x);
  }, Exec::ptr(red_) + kRedClosest, Exec::kParallelMinHeavy);
  return read_reductions()[kRedClosest];
}

/// Lagged friction of the active pairs at xs (x_t, generation gen): each pair's normal force and
/// closest-point frame (contact/friction.h), the pairs with a positive finite force kept in
/// active-pair order.
template <class Exec>
void Solver<Exec>::build_friction(const Vec<double>& xs, int gen) {
  const int n = act_.n;
  n_fr_ = 0;
  if (n > 0) {
    grow_for_overwrite(fr_scratch_, 11 * static_cast<size_t>(n));  // lambda, 4 weights, 6 of T
    grow_for_overwrite(fr_pos_, static_cast<size_t>(n));
    const detail::PairView A = act_.view();
    const double* x = Exec::ptr(xs);
    const double* rd = Exec::ptr(raw_dist_);
    const int* rs = Exec::ptr(raw_stamp_);
    const bool known = act_raw_known_;
    const double dhat = P_.dhat_self;
    double* out = Exec::ptr(fr_scratch_);
    int* pos = Exec::ptr(fr_pos_);
    double* red = Exec::ptr(red_);
    Exec::for_each(n, [=] GD_HD_LAMBDA(int c) {
      double* o = out + 11 * static_cast<size_t>(c);
      const int* v = A.v + 4 * c;
      const Vec3 p0 = detail::load3(x, v[0]), p1 = detail::load3(x, v[1]), p2 = detail::load3(x, v[2]),
                 p3 = detail::load3(x, v[3]);
      const int r = A.raw[c];
      const double dist = known && rs[r] == gen ? rd[r] : detail::pair_distance(v, A.type[c], x);
      double lambda = contact_normal_force(dist, 0.0, dhat, A.kappa[c]);
      if (A.type[c] == 1) lambda *= ee_mollifier(p0, p1, p2, p3, A.eps[c], nullptr, nullptr);
      o[0] = lambda;
      pos[c] = lambda > 0 && std::isfinite(lambda) ? 1 : 0;
      if (!pos[c]) return;
      const ContactFrictionFrame f = A.type[c] == 0 ? vf_friction_frame(p0, p1, p2, p3) : ee_friction_frame(p0, p1, p2, p3);
      for (int k = 0; k < 4; ++k) o[1 + k] = f.w[k];
      for (int k = 0; k < 6; ++k) o[5 + k] = f.T.data()[k];
    }, Exec::kParallelMinHeavy);
    Exec::exclusive_scan(fr_pos_, n);
    Exec::for_each(1, [=] GD_HD_LAMBDA(int) {
      const double l = out[11 * static_cast<size_t>(n - 1)];
      red[kRedFrictionPairs] = pos[n - 1] + (l > 0 && std::isfinite(l) ? 1 : 0);
    }, 2);
    n_fr_ = static_cast<int>(read_reductions()[kRedFrictionPairs]);
  }
  const size_t m = static_cast<size_t>(n_fr_);
  grow_for_overwrite(fr_v_, 4 * m);
  grow_for_overwrite(fr_w_, 4 * m);
  grow_for_overwrite(fr_T_, 6 * m);
  grow_for_overwrite(fr_lambda_, m);
  grow_for_overwrite(fr_H_, kPairBlockValues * m);
  grow_for_overwrite(fr_gd_, 48 * m);
  if (n_fr_ == 0) return;
  const detail::PairView A = act_.view();
  const double* in = Exec::ptr(fr_scratch_);
  const int* pos = Exec::ptr(fr_pos_);
  int* fv = Exec::ptr(fr_v_);
  double* fw = Exec::ptr(fr_w_);
  double* fT = Exec::ptr(fr_T_);
  double* fl = Exec::ptr(fr_lambda_);
  Exec::for_each(n, [=] GD_HD_LAMBDA(int c) {
    const double* o = in + 11 * static_cast<size_t>(c);
    if (!(o[0] > 0) || !std::isfinite(o[0])) return;
    const int k = pos[c];
    for (int a = 0; a < 4; ++a) fv[4 * k + a] = A.v[4 * c + a], fw[4 * k + a] = o[1 + a];
    for (int a = 0; a < 6; ++a) fT[6 * k + a] = o[5 + a];
    fl[k] = o[0];
  }, Exec::kParallelMinHeavy);
}

/// The line search's accepted point (x_, generation gen): the candidates' squared distances its
/// evaluation measured (cand_d2_, negative: not measured) kept for the selections there.
template <class Exec>
void Solver<Exec>::store_candidate_distances(int gen) {
  const detail::PairView C = cand_.view();
  const double* d2 = Exec::ptr(cand_d2_);
  double* rd = Exec::ptr(raw_dist_);
  int* rs = Exec::ptr(raw_stamp_);
  Exec::for_each(C.n, [=] GD_HD_LAMBDA(int c) {
    if (d2[c] < 0) return;  // not measured (NaN is: pair_distance gives NaN for it too)
    const int r = C.raw[c];
    rd[r] = sqrt(d2[c]);  // pair_distance's arithmetic
    rs[r] = gen;
  });
}

/// The candidate and active pairs' barrier stiffness times `factor` (adaptive stiffness).
template <class Exec>
void Solver<Exec>::scale_pair_stiffness(double factor) {
  for (DevicePairs* L : {&cand_, &act_}) {
    double* k = Exec::ptr(L->kappa);
    Exec::for_each(L->n, [=] GD_HD_LAMBDA(int c) { k[c] *= factor; });
  }
}

template <class Exec>
typename Solver<Exec>::FrictionPairs Solver<Exec>::friction_pairs() const {
  FrictionPairs f;
  if (n_fr_ == 0) return f;
  Exec::download(f.v, fr_v_), Exec::download(f.w, fr_w_), Exec::download(f.T, fr_T_), Exec::download(f.lambda, fr_lambda_);
  const size_t m = static_cast<size_t>(n_fr_);
  f.v.resize(4 * m), f.w.resize(4 * m), f.T.resize(6 * m), f.lambda.resize(m);
  return f;
}

}  // namespace gd::sim
