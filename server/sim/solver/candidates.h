#pragma once
/// \file
/// Self-contact candidates on the backend: the pairs of the broad phase's last answer
/// (SelfContact::query, on the host) that can come within dhat during a motion x0 -> x1. Member
/// functions of Solver<Exec>, written once for every backend.
///
/// A query's margin is dhat + slack, so its answer serves every later motion that, after one
/// common translation, keeps each vertex within slack/2 of the box it swept in the query: the
/// Newton iterations of a step, cloth moving less than slack/2, cloth falling or carried as a
/// whole. Whether a motion is covered is decided on the backend (its boxes against the query's,
/// six reductions read back together), and so is the filter that keeps the answer's pairs whose
/// boxes of this motion, inflated by dhat, overlap (what a query with margin dhat would report),
/// compacted in the answer's order by an exclusive scan. The host sees positions only when a new
/// query runs.

#include "sim/solver/solver_impl.h"

namespace gd::sim {

/// Candidates for the motion x0 -> x1 into cand_ (all pairs, before select_active), from the last
/// query where it covers the motion, else from a new one. A motion whose query would hold more
/// than the pair budget is halved (x1 moves halfway back towards x0: SelfContact::query's
/// comment), at least SelfContact::kMaxFloodHalvings times and then on until no vertex moves
/// farther than dhat (at most kMaxFloodHalvingsDiverged times), then asked without a bound.
/// Returns the halvings (0: x1 untouched), or -1 (nothing done) when the motion is not finite
/// and refuse_non_finite; otherwise a non-finite motion reaches the broad phase, which throws
/// InputError.
template <class Exec>
int Solver<Exec>::find_candidates(const Vec<double>& x0, Vec<double>& x1, bool refuse_non_finite) {
  const long queries_before = self_->pair_queries();
  int halvings = 0;
  for (;;) {
    bool finite = true;
    if (motion_covered(x0, x1, &finite)) {  // the last query's answer serves
      self_->count_reuse();
      break;
    }
    if (!finite && refuse_non_finite) return -1;
    // The unbounded query only once the motion is short: within dhat of the start everywhere.
    const bool last = halvings >= SelfContact::kMaxFloodHalvingsDiverged ||
                      (halvings >= SelfContact::kMaxFloodHalvings && !(longest_move(x0, x1) > P_.dhat_self));
    Exec::download(host_q0_, x0);
    Exec::download(host_q1_, x1);
    if (self_->query(host_q0_, host_q1_, last ? kNoPairLimit : self_->pair_budget())) {
      copy(mlo_, qlo_);  // what later motions are checked against
      copy(mhi_, qhi_);
      have_query_ = true;
      if constexpr (!Exec::kHostMemory) {  // the host reads SelfContact's answer in place
        Exec::upload(raw_vf_, self_->raw().vf);
        Exec::upload(raw_ee_, self_->raw().ee);
      }
      break;
    }
    have_query_ = false;  // a refused query leaves nothing to reuse
    const double* a = Exec::ptr(x0);
    double* b = Exec::ptr(x1);
    Exec::for_each(3 * n_, [=] GD_HD_LAMBDA(int k) { b[k] = a[k] + 0.5 * (b[k] - a[k]); }, Exec::kParallelMinVector);
    ++halvings;
  }
  if (halvings > 0) {
    gd::log().debug("self-contact broad phase: the motion would have held over {} pairs; halved {} times",
                    self_->pair_budget(), halvings);
    self_->count_halvings(halvings);
  }
  if (self_->pair_queries() != queries_before) {  // a new answer: the distances kept are the old one's
    Exec::resize(raw_stamp_, static_cast<size_t>(self_->raw_pairs()));
    Exec::fill(raw_stamp_, -1);
    Exec::resize_for_overwrite(raw_dist_, static_cast<size_t>(self_->raw_pairs()));
    act_raw_known_ = false;  // act_'s raw indices were the old answer's
  }
  keep_candidates();
  return halvings;
}

/// The motion's boxes (per coordinate, the smaller and the larger of x0 and x1) into mlo_/mhi_, and
/// whether the last query covers the motion: some translation moves every box into its box in the
/// query grown by slack/2 on every side, i.e. per axis the spread of the boxes' shifts,
/// max(hi1 - hi0) - min(lo1 - lo0), is at most slack. *finite: x0, x1 and the shifts are finite.
template <class Exec>
bool Solver<Exec>::motion_covered(const Vec<double>& x0, const Vec<double>& x1, bool* finite) {
  const int m = 3 * n_;
  Exec::resize_for_overwrite(mlo_, static_cast<size_t>(m));
  Exec::resize_for_overwrite(mhi_, static_cast<size_t>(m));
  const double* a = Exec::ptr(x0);
  const double* b = Exec::ptr(x1);
  double* lo = Exec::ptr(mlo_);
  double* hi = Exec::ptr(mhi_);
  const bool query = have_query_;
  const double* qlo = query ? Exec::ptr(qlo_) : nullptr;
  const double* qhi = query ? Exec::ptr(qhi_) : nullptr;
  double* red = Exec::ptr(red_);
  Exec::for_each(m, [=] GD_HD_LAMBDA(int k) {
    lo[k] = b[k] < a[k] ? b[k] : a[k];  // std::min(a, b)
    hi[k] = a[k] < b[k] ? b[k] : a[k];  // std::max(a, b)
  }, Exec::kParallelMinVector);
  Exec::max_to(m, [=] GD_HD_LAMBDA(int k) {
    bool ok = std::isfinite(a[k]) && std::isfinite(b[k]);
    if (query) ok = ok && std::isfinite(hi[k] - qhi[k]) && std::isfinite(lo[k] - qlo[k]);
    return ok ? 0.0 : 1.0;
  }, red + kRedMotionNonFinite, Exec::kParallelMinVector);
  if (query) {
    for (int d = 0; d < 3; ++d) {
      Exec::min_to(n_, [=] GD_HD_LAMBDA(int i) { return -(hi[3 * i + d] - qhi[3 * i + d]); }, red + kRedMotionUp + d,
                   Exec::kParallelMinVector);
      Exec::min_to(n_, [=] GD_HD_LAMBDA(int i) { return lo[3 * i + d] - qlo[3 * i + d]; }, red + kRedMotionDown + d,
                   Exec::kParallelMinVector);
    }
  }
  const double* r = read_reductions();
  *finite = r[kRedMotionNonFinite] == 0.0;
  if (!query || !*finite) return false;
  const double spread = 2 * (0.5 * self_->slack());
  for (int d = 0; d < 3; ++d) {
    const double up = -r[kRedMotionUp + d], down = r[kRedMotionDown + d];
    if (!(up - down <= spread)) return false;
  }
  return true;
}

/// Largest distance a vertex moves from x0 to x1, m.
template <class Exec>
double Solver<Exec>::longest_move(const Vec<double>& x0, const Vec<double>& x1) {
  const double* a = Exec::ptr(x0);
  const double* b = Exec::ptr(x1);
  Exec::max_to(n_, [=] GD_HD_LAMBDA(int i) {
    const double dx = b[3 * i] - a[3 * i], dy = b[3 * i + 1] - a[3 * i + 1], dz = b[3 * i + 2] - a[3 * i + 2];
    return dx * dx + dy * dy + dz * dz;
  }, Exec::ptr(red_) + kRedMotionUp);
  return std::sqrt(read_reductions()[kRedMotionUp]);
}

/// The last answer's pairs whose boxes of this motion (mlo_/mhi_), inflated by dhat, overlap,
/// into cand_ in the answer's order, each with its barrier stiffness (per unit mass times the
/// vertex's mass, VF, or the four vertices' mean, EE) and EE mollifier threshold.
template <class Exec>
void Solver<Exec>::keep_candidates() {
  const ContactCandidates& raw = self_->raw();
  const int nvf = static_cast<int>(raw.vf.size()), total = nvf + static_cast<int>(raw.ee.size());
  if (!have_query_ || total == 0) {
    cand_.resize_for_overwrite(0);
    return;
  }
  grow_for_overwrite(raw_flag_, static_cast<size_t>(total));
  grow_for_overwrite(raw_pos_, static_cast<size_t>(total));
  const Eigen::Vector2i* vf = raw_vf_ptr();
  const Eigen::Vector2i* ee = raw_ee_ptr();
  const Eigen::Vector2i* edges = Exec::ptr(edges_);
  const int* tris = Exec::ptr(tris_);
  const double* lo = Exec::ptr(mlo_);
  const double* hi = Exec::ptr(mhi_);
  int* flag = Exec::ptr(raw_flag_);
  int* pos = Exec::ptr(raw_pos_);
  const double margin = P_.dhat_self * (1 + 1e-9);
  Exec::for_each(total, [=] GD_HD_LAMBDA(int c) {
    int a[2], b[3], na, nb;
    if (c < nvf) {
      a[0] = vf[c][0], na = 1;
      for (int k = 0; k < 3; ++k) b[k] = tris[3 * vf[c][1] + k];
      nb = 3;
    } else {
      const Eigen::Vector2i& e = ee[c - nvf];
      a[0] = edges[e[0]][0], a[1] = edges[e[0]][1], b[0] = edges[e[1]][0], b[1] = edges[e[1]][1];
      na = nb = 2;
    }
    bool near = true;
    for (int d = 0; d < 3 && near; ++d) {
      double alo = lo[3 * a[0] + d], ahi = hi[3 * a[0] + d], blo = lo[3 * b[0] + d], bhi = hi[3 * b[0] + d];
      for (int k = 1; k < na; ++k) {
        const double l = lo[3 * a[k] + d], h = hi[3 * a[k] + d];
        alo = l < alo ? l : alo, ahi = ahi < h ? h : ahi;
      }
      for (int k = 1; k < nb; ++k) {
        const double l = lo[3 * b[k] + d], h = hi[3 * b[k] + d];
        blo = l < blo ? l : blo, bhi = bhi < h ? h : bhi;
      }
      if (alo - margin > bhi || blo - margin > ahi) near = false;
    }
    flag[c] = pos[c] = near ? 1 : 0;
  }, Exec::kParallelMin);
  Exec::exclusive_scan(raw_pos_, total);
  double* red = Exec::ptr(red_);
  Exec::for_each(1, [=] GD_HD_LAMBDA(int) { red[kRedCandidates] = pos[total - 1] + flag[total - 1]; }, 2);
  cand_.resize_for_overwrite(static_cast<int>(read_reductions()[kRedCandidates]));
  const detail::PairSlots K = cand_.slots();
  const double* mass = Exec::ptr(mass_);
  const double* len2 = Exec::ptr(edge_len2_);
  const double kappa = kappa_scale_ * P_.kappa_per_mass;
  Exec::for_each(total, [=] GD_HD_LAMBDA(int c) {
    if (!flag[c]) return;
    const int k = pos[c];
    int* v = K.v + 4 * k;
    if (c < nvf) {
      v[0] = vf[c][0];
      for (int j = 0; j < 3; ++j) v[1 + j] = tris[3 * vf[c][1] + j];
      K.type[k] = 0, K.kappa[k] = kappa * mass[v[0]], K.eps[k] = 0.0;
    } else {
      const Eigen::Vector2i& e = ee[c - nvf];
      v[0] = edges[e[0]][0], v[1] = edges[e[0]][1], v[2] = edges[e[1]][0], v[3] = edges[e[1]][1];
      const double m = 0.25 * (mass[v[0]] + mass[v[1]] + mass[v[2]] + mass[v[3]]);
      K.type[k] = 1, K.kappa[k] = kappa * m, K.eps[k] = 1e-3 * len2[e[0]] * len2[e[1]];
    }
    K.raw[k] = c;
  }, Exec::kParallelMin);
}

}  // namespace gd::sim
