#include "sim/solver/self_contact.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "sim/contact/barrier.h"
#include "sim/contact/distance.h"
#include "sim/contact/friction.h"
#include "sim/contact/tri_tri_intersect.h"
#include "sim/contact/untangle.h"
#include "sim/log.h"

namespace gd::sim {
namespace {

Vec3 at(const std::vector<double>& x, int i) { return Vec3(x[3 * i], x[3 * i + 1], x[3 * i + 2]); }

/// Distance of a pair (VF or EE) at positions x.
double pair_distance(const std::vector<double>& x, const int* v, int type) {
  const double d2 = type == 0 ? point_triangle_distance2(at(x, v[0]), at(x, v[1]), at(x, v[2]), at(x, v[3]), nullptr, nullptr)
                              : edge_edge_distance2(at(x, v[0]), at(x, v[1]), at(x, v[2]), at(x, v[3]), nullptr, nullptr);
  return std::sqrt(std::max(d2, 0.0));
}

}  // namespace

void ContactPairs::push(const int* vs, int t, double k, double e) {
  v.insert(v.end(), vs, vs + 4);
  type.push_back(t);
  kappa.push_back(k);
  eps_x.push_back(e);
}

SelfContact::SelfContact(const SceneData& data, Real dhat, Real kappa_per_mass)
    : d_(data), dhat_(dhat), kappa_per_mass_(kappa_per_mass) {
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
  bp_ = make_embree_broad_phase(d_.tris, edges_, d_.n);
}

void SelfContact::find(const std::vector<double>& x0, const std::vector<double>& x1) {
  const auto t0 = std::chrono::steady_clock::now();
  bp_->find(x0, x1, dhat_, &raw_);
  bp_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  cand_.clear();
  for (const auto& p : raw_.vf) {
    const int v[4] = {p[0], d_.tris[3 * p[1]], d_.tris[3 * p[1] + 1], d_.tris[3 * p[1] + 2]};
    cand_.push(v, 0, kappa_scale_ * kappa_per_mass_ * d_.mass[v[0]], 0.0);
  }
  for (const auto& p : raw_.ee) {
    const auto& a = edges_[p[0]];
    const auto& b = edges_[p[1]];
    const int v[4] = {a[0], a[1], b[0], b[1]};
    const double m = 0.25 * (d_.mass[v[0]] + d_.mass[v[1]] + d_.mass[v[2]] + d_.mass[v[3]]);
    cand_.push(v, 1, kappa_scale_ * kappa_per_mass_ * m, 1e-3 * edge_len2_[p[0]] * edge_len2_[p[1]]);
  }
}

void SelfContact::select_active(const std::vector<double>& x, const std::vector<int>& fixed) {
  active_.clear();
  ContactPairs kept;
  dropped_ = 0;
  // The distances in parallel (the costly part), then the lists in candidate order.
  const int n = cand_.size();
  dist_.resize(n);
#pragma omp parallel for schedule(static) if (n >= 4096)
  for (int c = 0; c < n; ++c) {
    const int* v = &cand_.v[4 * c];
    dist_[c] = fixed[v[0]] && fixed[v[1]] && fixed[v[2]] && fixed[v[3]] ? -1.0 : pair_distance(x, v, cand_.type[c]);
  }
  for (int c = 0; c < n; ++c) {
    const int* v = &cand_.v[4 * c];
    if (fixed[v[0]] && fixed[v[1]] && fixed[v[2]] && fixed[v[3]]) continue;  // nothing to solve
    const double dist = dist_[c];
    if (!(dist > 0)) {
      ++dropped_;
      continue;
    }
    kept.push(v, cand_.type[c], cand_.kappa[c], cand_.eps_x[c]);
    if (dist < dhat_) active_.push(v, cand_.type[c], cand_.kappa[c], cand_.eps_x[c]);
  }
  cand_ = std::move(kept);
}

void SelfContact::set_kappa_scale(Real s) {
  const Real f = s / kappa_scale_;
  for (double& k : cand_.kappa) k *= f;
  for (double& k : active_.kappa) k *= f;
  kappa_scale_ = s;
}

double SelfContact::min_active_distance(const std::vector<double>& x) const {
  double m = std::numeric_limits<double>::infinity();
  const int n = active_.size();
#pragma omp parallel for schedule(static) reduction(min : m) if (n >= 4096)
  for (int c = 0; c < n; ++c) m = std::min(m, pair_distance(x, &active_.v[4 * c], active_.type[c]));
  return m;
}

void SelfContact::build_friction(const std::vector<double>& x_t) {
  friction_.clear();
  for (int c = 0; c < active_.size(); ++c) {
    const int* v = &active_.v[4 * c];
    const Vec3 p0 = at(x_t, v[0]), p1 = at(x_t, v[1]), p2 = at(x_t, v[2]), p3 = at(x_t, v[3]);
    const double dist = pair_distance(x_t, v, active_.type[c]);
    double lambda = contact_normal_force(dist, 0.0, dhat_, active_.kappa[c]);
    if (active_.type[c] == 1) lambda *= ee_mollifier(p0, p1, p2, p3, active_.eps_x[c], nullptr, nullptr);
    if (!(lambda > 0) || !std::isfinite(lambda)) continue;
    const ContactFrictionFrame f =
        active_.type[c] == 0 ? vf_friction_frame(p0, p1, p2, p3) : ee_friction_frame(p0, p1, p2, p3);
    friction_.v.insert(friction_.v.end(), v, v + 4);
    for (int k = 0; k < 4; ++k) friction_.w.push_back(f.w[k]);
    for (int k = 0; k < 6; ++k) friction_.T.push_back(f.T.data()[k]);
    friction_.lambda.push_back(lambda);
  }
}

int SelfContact::count_intersections(const std::vector<double>& x) {
  std::vector<Eigen::Vector2i> pairs;
  bp_->triangle_pairs(x, x, 0.0, &pairs);
  return static_cast<int>(intersecting_pairs(x, d_.tris, pairs).size());
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
