#include "sim/solver/self_contact.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>

#include "sim/contact/tri_tri_intersect.h"
#include "sim/contact/untangle.h"
#include "sim/demand.h"
#include "sim/log.h"

namespace gd::sim {
namespace {

Vec3 at(const std::vector<double>& x, int i) { return Vec3(x[3 * i], x[3 * i + 1], x[3 * i + 2]); }

}  // namespace

SelfContact::SelfContact(const SceneData& data, Real dhat, BroadPhaseKind broad_phase, bool on_device,
                         std::size_t pair_budget)
    : SelfContact(data, dhat,
                  [&](const std::vector<int>& tris, const std::vector<Eigen::Vector2i>& edges, int n) {
                    if (broad_phase == BroadPhaseKind::kEmbree) return make_embree_broad_phase(tris, edges, n);
                    return on_device ? make_cuda_lbvh_broad_phase(tris, edges, n) : make_lbvh_broad_phase(tris, edges, n);
                  },
                  pair_budget) {}

SelfContact::SelfContact(const SceneData& data, Real dhat, const BroadPhaseFactory& make, std::size_t pair_budget)
    : d_(data),
      dhat_(dhat),
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
  bp_ = make(d_.tris, edges_, d_.n);
  GD_DEMAND(bp_ != nullptr, "the broad-phase factory made nothing");
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

bool SelfContact::query(const std::vector<double>& x0, const std::vector<double>& x1, std::size_t max_pairs) {
  // the broad phase checks the sizes and finiteness of x0 and x1
  const auto t0 = std::chrono::steady_clock::now();
  const bool fits = bp_->find(x0, x1, dhat_ + slack_, &raw_, max_pairs);
  bp_seconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ++queries_;
  ++pair_queries_;  // new raw indices
  return fits;
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
