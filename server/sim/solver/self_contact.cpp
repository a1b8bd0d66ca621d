#include "sim/solver/self_contact.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "sim/backend/cpu/omp_threads.h"
#include "sim/contact/tri_tri_intersect.h"
#include "sim/contact/untangle.h"
#include "sim/demand.h"
#include "sim/log.h"

namespace gd::sim {
namespace {

/// Pair loops shorter than this stay on the calling thread.
constexpr int kParallelPairs = 1024;

Vec3 at(const std::vector<double>& x, int i) { return Vec3(x[3 * i], x[3 * i + 1], x[3 * i + 2]); }

}  // namespace

void ContactPairs::push(const int* vs, int t, double k, double e) {
  v.insert(v.end(), vs, vs + 4);
  type.push_back(t);
  kappa.push_back(k);
  eps_x.push_back(e);
}

SelfContact::SelfContact(const SceneData& data, Real dhat, Real kappa_per_mass, BroadPhaseKind broad_phase,
                         bool on_device, std::size_t pair_budget)
    : d_(data),
      dhat_(dhat),
      kappa_per_mass_(kappa_per_mass),
      slack_(kBroadPhaseSlack * dhat),
      budget_(pair_budget > 0 ? pair_budget
                              : std::max(kMinPairBudget, kPairsPerVertex * static_cast<std::size_t>(data.n))) {
  // Unique undirected edges of the triangles.
  for (int t = 0; t < d_.triangles(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = d_.tris[3 * t + k], b = d_.tris[3 * t + (k + 1) % 3];
      edges_.emplace_back(std::min(a, b), std::max(a, b));
    }
  std::sort(edges_.begin(), edges_.end(), [](const auto& p, const auto& q) {
    return p[0] != q[0] ? p[0] < q[0] : p[1] < q[1];
  });
  edges_.erase(std::unique(edges_.begin(), edges_.end()), edges_.end());
  for (const auto& e : edges_) edge_len2_.push_back((at(d_.x, e[0]) - at(d_.x, e[1])).squaredNorm());
  if (broad_phase != BroadPhaseKind::kEmbree) {
    bp_ = on_device ? make_cuda_lbvh_broad_phase(d_.tris, edges_, d_.n) : make_lbvh_broad_phase(d_.tris, edges_, d_.n);
  } else {
    bp_ = make_embree_broad_phase(d_.tris, edges_, d_.n);
  }
}

namespace {

/// Whether some translation t moves every box [lo1, hi1] (per coordinate, 3 per vertex) into its
/// [lo0 - r, hi0 + r]: per axis, the spread of the boxes' shifts, max(hi1 - hi0) - min(lo1 - lo0),
/// is at most 2r. A translation changes no distance, so primitives within some distance of each
/// other in the new boxes had boxes within that distance + 2r in the old ones. NaN: false.
bool within_translated_boxes(const std::vector<double>& lo0, const std::vector<double>& hi0, const double* lo1,
                             const double* hi1, size_t size, double r) {
  if (lo0.size() != size || hi0.size() != size || size % 3 != 0) return false;
  for (int d = 0; d < 3; ++d) {
    double up = -std::numeric_limits<double>::infinity(), down = std::numeric_limits<double>::infinity();
    bool finite = true;
    for (size_t k = d; k < size; k += 3) {
      const double a = hi1[k] - hi0[k], b = lo1[k] - lo0[k];
      finite = finite && std::isfinite(a) && std::isfinite(b);
      up = std::max(up, a);
      down = std::min(down, b);
    }
    if (!finite || !(up - down <= 2 * r)) return false;
  }
  return true;
}

}  // namespace

bool SelfContact::covered_by_last_query(const std::vector<double>& x0, const std::vector<double>& x1) {
  if (x1.size() != x0.size()) return false;
  motion_lo_.resize(x0.size());
  motion_hi_.resize(x0.size());
  bool finite = true;  // std::min/max would drop a NaN from the boxes
  for (size_t k = 0; k < x0.size(); ++k) {
    finite = finite && std::isfinite(x0[k]) && std::isfinite(x1[k]);
    motion_lo_[k] = std::min(x0[k], x1[k]);
    motion_hi_[k] = std::max(x0[k], x1[k]);
  }
  return finite && within_translated_boxes(query_lo_, query_hi_, motion_lo_.data(), motion_hi_.data(), x0.size(), 0.5 * slack_);
}

bool SelfContact::find(const std::vector<double>& x0, const std::vector<double>& x1, std::size_t max_pairs) {
  const bool reuse = covered_by_last_query(x0, x1);  // the last query held at most its own bound
  if (reuse) {
    ++reuses_;
  } else {  // the broad phase also checks the sizes and finiteness of x0 and x1
    const auto t0 = std::chrono::steady_clock::now();
    const bool fits = bp_->find(x0, x1, dhat_ + slack_, &raw_, max_pairs);
    bp_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ++queries_;
    ++pair_queries_;  // new raw indices
    if (!fits) {  // no candidates, and nothing for a later motion to reuse
      query_lo_.clear(), query_hi_.clear();
      cand_.clear(), cand_raw_.clear();
      return false;
    }
  }
  if (!reuse) query_lo_ = motion_lo_, query_hi_ = motion_hi_;  // what later motions are checked against
  // Keep the pairs whose boxes of this motion, inflated by dhat, overlap: what a query with
  // margin dhat would report (the slack only made the query's answer last longer).
  const double margin = dhat_ * (1 + 1e-9);
  const double* lo = motion_lo_.data();
  const double* hi = motion_hi_.data();
  auto near = [=](const int* a, int na, const int* b, int nb) {
    for (int d = 0; d < 3; ++d) {
      double alo = lo[3 * a[0] + d], ahi = hi[3 * a[0] + d], blo = lo[3 * b[0] + d], bhi = hi[3 * b[0] + d];
      for (int k = 1; k < na; ++k) alo = std::min(alo, lo[3 * a[k] + d]), ahi = std::max(ahi, hi[3 * a[k] + d]);
      for (int k = 1; k < nb; ++k) blo = std::min(blo, lo[3 * b[k] + d]), bhi = std::max(bhi, hi[3 * b[k] + d]);
      if (alo - margin > bhi || blo - margin > ahi) return false;
    }
    return true;
  };
  const int nvf = static_cast<int>(raw_.vf.size()), nee = static_cast<int>(raw_.ee.size());
  keep_.resize(nvf + nee);
#pragma omp parallel for schedule(static) if (nvf + nee >= kParallelPairs)
  for (int c = 0; c < nvf + nee; ++c) {
    if (c < nvf) {
      const auto& p = raw_.vf[c];
      keep_[c] = near(&p[0], 1, &d_.tris[3 * p[1]], 3);
    } else {
      const auto& p = raw_.ee[c - nvf];
      keep_[c] = near(edges_[p[0]].data(), 2, edges_[p[1]].data(), 2);
    }
  }
  // The kept pairs in raw order (vf pairs, then ee pairs): chunks of the raw list counted, then
  // filled, in parallel (at fold/40000 a query holds up to ~6.6 million raw pairs for ~85,000
  // candidates, and each call re-filters all of them).
  const int raw_total = nvf + nee;
  const int chunks = raw_total >= kParallelPairs ? 4 * std::max(1, omp_threads()) : 1;
  auto chunk_lo = [&](int j) { return static_cast<int>(static_cast<long>(raw_total) * j / chunks); };
  std::vector<int> start(chunks + 1, 0);
#pragma omp parallel for schedule(static) if (chunks > 1)
  for (int j = 0; j < chunks; ++j)
    start[j + 1] = static_cast<int>(std::count(keep_.begin() + chunk_lo(j), keep_.begin() + chunk_lo(j + 1), 1));
  for (int j = 0; j < chunks; ++j) start[j + 1] += start[j];
  const int total = start[chunks];
  cand_.v.resize(4 * static_cast<size_t>(total));
  cand_.type.resize(total), cand_.kappa.resize(total), cand_.eps_x.resize(total);
  cand_raw_.resize(total);
  const Real kappa = kappa_scale_ * kappa_per_mass_;
#pragma omp parallel for schedule(static) if (chunks > 1)
  for (int j = 0; j < chunks; ++j) {
    int k = start[j];
    for (int c = chunk_lo(j); c < chunk_lo(j + 1); ++c) {
      if (!keep_[c]) continue;
      int* v = &cand_.v[4 * static_cast<size_t>(k)];
      if (c < nvf) {
        const auto& p = raw_.vf[c];
        v[0] = p[0], v[1] = d_.tris[3 * p[1]], v[2] = d_.tris[3 * p[1] + 1], v[3] = d_.tris[3 * p[1] + 2];
        cand_.type[k] = 0, cand_.kappa[k] = kappa * d_.mass[v[0]], cand_.eps_x[k] = 0.0;
      } else {
        const auto& p = raw_.ee[c - nvf];
        const auto& a = edges_[p[0]];
        const auto& b = edges_[p[1]];
        v[0] = a[0], v[1] = a[1], v[2] = b[0], v[3] = b[1];
        const double m = 0.25 * (d_.mass[v[0]] + d_.mass[v[1]] + d_.mass[v[2]] + d_.mass[v[3]]);
        cand_.type[k] = 1, cand_.kappa[k] = kappa * m, cand_.eps_x[k] = 1e-3 * edge_len2_[p[0]] * edge_len2_[p[1]];
      }
      cand_raw_[k] = c;
      ++k;
    }
  }
  return true;
}

int SelfContact::find_within_budget(const std::vector<double>& x0, std::vector<double>* x1) {
  GD_DEMAND(x1 != nullptr, "null motion end");
  int halvings = 0;
  auto longest_move = [&] {
    double m = 0;
    for (size_t i = 0; i + 2 < x0.size(); i += 3) {
      const double dx = (*x1)[i] - x0[i], dy = (*x1)[i + 1] - x0[i + 1], dz = (*x1)[i + 2] - x0[i + 2];
      m = std::max(m, dx * dx + dy * dy + dz * dz);
    }
    return std::sqrt(m);
  };
  for (;;) {
    // The unbounded query only once the motion is short: within dhat of the start everywhere.
    const bool last = halvings >= kMaxFloodHalvingsDiverged ||
                      (halvings >= kMaxFloodHalvings && !(longest_move() > static_cast<double>(dhat_)));
    if (find(x0, *x1, last ? kNoPairLimit : budget_)) break;
    for (size_t k = 0; k < x0.size(); ++k) (*x1)[k] = x0[k] + 0.5 * ((*x1)[k] - x0[k]);
    ++halvings;
  }
  if (halvings > 0)
    gd::log().debug("self-contact broad phase: the motion would have held over {} pairs; halved {} times", budget_,
                    halvings);
  halvings_ += halvings;
  return halvings;
}

void SelfContact::set_kappa_scale(Real s) {
  const Real f = s / kappa_scale_;
  for (double& k : cand_.kappa) k *= f;
  kappa_scale_ = s;
}

int SelfContact::count_intersections(const std::vector<double>& x) {
  // Triangle pairs from a query with margin slack at the positions of its time, reused while every
  // vertex stays within slack/2 of its place there after some common translation (as in find()):
  // a pair whose triangles touch at x had boxes within slack of each other then.
  if (!within_translated_boxes(tri_query_x_, tri_query_x_, x.data(), x.data(), x.size(), 0.5 * slack_)) {
    const auto t0 = std::chrono::steady_clock::now();
    bp_->triangle_pairs(x, x, slack_, &tri_raw_);
    bp_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ++queries_;
    tri_query_x_ = x;
  }
  return static_cast<int>(intersecting_pairs(x, d_.tris, tri_raw_).size());  // its own box test first
}

int SelfContact::untangle(std::vector<double>* x, const std::vector<int>& fixed) {
  auto candidates = [&](const std::vector<double>& y) {
    std::vector<Eigen::Vector2i> pairs;
    bp_->triangle_pairs(y, y, 0.0, &pairs);
    return pairs;
  };
  const UntangleResult r = gd::sim::untangle(x, d_.tris, fixed, candidates, 0.25 * dhat_);
  gd::log().debug("untangle: {} -> {} intersecting pairs in {} iterations", r.intersecting_before,
                  r.intersecting_after, r.iterations);
  return r.intersecting_after;
}

}  // namespace gd::sim
