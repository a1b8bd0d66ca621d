#pragma once
/// \file
/// Self-contact candidates on the backend: the pairs of the broad phase's last answer (the LBVH
/// queried on the backend, or Embree's on the host) that can come within dhat during a motion
/// x0 -> x1. Member functions of Solver<Exec>, written once for every backend.
///
/// A query's margin is dhat + slack, so its answer serves every later motion that, after one
/// common translation, keeps each vertex within slack/2 of the box it swept in the query: the
/// Newton iterations of a step, cloth moving less than slack/2, cloth falling or carried as a
/// whole. Whether a motion is covered is decided on the backend (its boxes against the query's,
/// six reductions read back together), and so is the filter that keeps the answer's pairs whose
/// boxes of this motion, inflated by dhat, overlap (what a query with margin dhat would report),
/// compacted in the answer's order by an exclusive scan in the same pass that selects the active
/// pairs at the motion's start (select_along: one read-back). With the LBVH the host sees no
/// position and no pair: a query reads back its pair counts.

#include "sim/solver/solver_impl.h"

namespace gd::sim {

/// The broad phase's answer for the motion x0 -> x1: the last query's where it covers the motion,
/// else a new one; select_along then takes the motion's candidates from it. A motion whose query would hold more
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
    if (query_pairs(x0, x1, finite, last ? kNoPairLimit : self_->pair_budget())) {
      copy(mlo_, qlo_);  // what later motions are checked against
      copy(mhi_, qhi_);
      have_query_ = true;
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
    const size_t raw_pairs = static_cast<size_t>(raw_vf_count() + raw_ee_count());
    Exec::resize(raw_stamp_, raw_pairs);
    Exec::fill(raw_stamp_, -1);
    Exec::resize_for_overwrite(raw_dist_, raw_pairs);
    act_raw_known_ = false;  // act_'s raw indices were the old answer's
  }
  return halvings;
}

/// The broad-phase query of the motion x0 -> x1 (margin dhat + slack) with at most max_pairs
/// pairs (false: refused, nothing kept): on the backend, its answer left there, with the LBVH;
/// Embree's on the host (the motion downloaded, its answer uploaded to a device). finite: what
/// motion_covered found; a non-finite motion throws the broad phase's InputError.
template <class Exec>
bool Solver<Exec>::query_pairs(const Vec<double>& x0, const Vec<double>& x1, bool finite, std::size_t max_pairs) {
  const double margin = self_->dhat() + self_->slack();
  if (pair_bp_ == nullptr || !finite) {
    Exec::download(host_q0_, x0);
    Exec::download(host_q1_, x1);
    if (pair_bp_ != nullptr) {  // the broad phase's own error for a non-finite motion
      check_broad_phase_query(n_, host_q0_, host_q1_, margin);
      GD_DEMAND(false, "a motion found non-finite on the backend is finite on the host");
    }
    const bool fits = self_->query(host_q0_, host_q1_, max_pairs);
    if (fits && !Exec::kHostMemory) {  // a host-memory policy reads SelfContact's answer in place
      Exec::upload(raw_vf_, self_->raw().vf);
      Exec::upload(raw_ee_, self_->raw().ee);
    }
    return fits;
  }
  const auto t0 = std::chrono::steady_clock::now();
  const bool fits = pair_bp_->find_on_backend(Exec::ptr(x0), Exec::ptr(x1), margin, &raw_vf_, &raw_ee_, max_pairs);
  self_->count_query(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return fits;
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

namespace detail {

/// The broad phase's answer as the source of a selection (Solver::select_from): a pair is one
/// when its primitives' boxes of the motion (lo/hi, 3 per vertex), inflated by `margin`, overlap:
/// what a query with that margin would report. Its barrier stiffness: `kappa` (per unit mass)
/// times the vertex's mass (VF) or the four vertices' mean (EE); its EE mollifier threshold from
/// the edges' rest squared lengths.
struct AnswerSource {
  static constexpr bool kList = false;
  int nvf;
  const Eigen::Vector2i* vf;
  const Eigen::Vector2i* ee;
  const Eigen::Vector2i* edges;
  const int* tris;
  const double* lo;
  const double* hi;
  const double* mass;
  const double* len2;
  double margin, kappa;

  GD_HD void vertices(int c, int* v, int* type) const {
    if (c < nvf) {
      v[0] = vf[c][0];
      for (int j = 0; j < 3; ++j) v[1 + j] = tris[3 * vf[c][1] + j];
      *type = 0;
    } else {
      const Eigen::Vector2i& e = ee[c - nvf];
      v[0] = edges[e[0]][0], v[1] = edges[e[0]][1], v[2] = edges[e[1]][0], v[3] = edges[e[1]][1];
      *type = 1;
    }
  }
  GD_HD bool pair(int c, int* v, int* type, int* raw) const {
    vertices(c, v, type);
    *raw = c;
    const int na = *type == 0 ? 1 : 2;  // VF: the point against the triangle; EE: edge against edge
    for (int d = 0; d < 3; ++d) {
      double alo = lo[3 * v[0] + d], ahi = hi[3 * v[0] + d], blo = lo[3 * v[na] + d], bhi = hi[3 * v[na] + d];
      for (int k = 1; k < na; ++k) {
        const double l = lo[3 * v[k] + d], h = hi[3 * v[k] + d];
        alo = l < alo ? l : alo, ahi = ahi < h ? h : ahi;  // std::min, std::max
      }
      for (int k = na + 1; k < 4; ++k) {
        const double l = lo[3 * v[k] + d], h = hi[3 * v[k] + d];
        blo = l < blo ? l : blo, bhi = bhi < h ? h : bhi;
      }
      if (alo - margin > bhi || blo - margin > ahi) return false;
    }
    return true;
  }
  GD_HD void write(int c, const PairSlots& to, int k) const {
    int* v = to.v + 4 * k;
    vertices(c, v, to.type + k);
    if (c < nvf) {
      to.kappa[k] = kappa * mass[v[0]], to.eps[k] = 0.0;
    } else {
      const Eigen::Vector2i& e = ee[c - nvf];
      const double m = 0.25 * (mass[v[0]] + mass[v[1]] + mass[v[2]] + mass[v[3]]);
      to.kappa[k] = kappa * m, to.eps[k] = 1e-3 * len2[e[0]] * len2[e[1]];
    }
    to.raw[k] = c;
  }
};

}  // namespace detail

/// The candidates of the motion find_candidates last saw (the answer's pairs whose boxes of the
/// motion, mlo_/mhi_, inflated by dhat, overlap) and the active pairs among them at xs, the
/// motion's start (generation gen), in one selection: one pass over the answer, one read-back.
/// Returns the closest active pair's distance.
template <class Exec>
double Solver<Exec>::select_along(const Vec<double>& xs, int gen) {
  const int nvf = raw_vf_count();
  const int total = have_query_ ? nvf + raw_ee_count() : 0;
  const detail::AnswerSource S{nvf,
                               raw_vf_ptr(),
                               raw_ee_ptr(),
                               Exec::ptr(edges_),
                               Exec::ptr(tris_),
                               Exec::ptr(mlo_),
                               Exec::ptr(mhi_),
                               Exec::ptr(mass_),
                               Exec::ptr(edge_len2_),
                               P_.dhat_self * (1 + 1e-9),
                               kappa_scale_ * P_.kappa_per_mass};
  return select_from(S, total, xs, gen);
}

}  // namespace gd::sim
