#include "sim/contact/cuts.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <string>
#include <utility>

#include "sim/contact/distance.h"
#include "sim/contact/tri_tri_intersect.h"
#include "sim/demand.h"

namespace gd::sim {
namespace {

using Box3 = Eigen::AlignedBox<Real, 3>;

/// Whether the closed segment a-b meets the closed box [-h, h] (slab clipping).
bool segment_meets_box(const Vec3& a, const Vec3& b, const Vec3& h) {
  Real lo = 0, hi = 1;
  const Vec3 d = b - a;
  for (int i = 0; i < 3; ++i) {
    if (d[i] == 0) {
      if (std::abs(a[i]) > h[i]) return false;
      continue;
    }
    Real t0 = (-h[i] - a[i]) / d[i], t1 = (h[i] - a[i]) / d[i];
    if (t0 > t1) std::swap(t0, t1);
    lo = std::max(lo, t0), hi = std::min(hi, t1);
    if (lo > hi) return false;
  }
  return true;
}

/// The collider's own edges in world coordinates: a box's 12, a capsule's axis.
std::vector<std::pair<Vec3, Vec3>> collider_edges(const ColliderShape& s, const Eigen::Isometry3d& pose) {
  std::vector<std::pair<Vec3, Vec3>> out;
  if (s.type == ColliderType::kCapsule) {
    out.emplace_back(pose * Vec3(0, 0, -s.half_length), pose * Vec3(0, 0, s.half_length));
    return out;
  }
  const Vec3& h = s.half_extents;
  for (int axis = 0; axis < 3; ++axis)
    for (int c = 0; c < 4; ++c) {
      const int u = (axis + 1) % 3, w = (axis + 2) % 3;
      Vec3 a, b;
      a[axis] = -h[axis], b[axis] = h[axis];
      a[u] = b[u] = (c & 1 ? 1 : -1) * h[u];
      a[w] = b[w] = (c & 2 ? 1 : -1) * h[w];
      out.emplace_back(pose * a, pose * b);
    }
  return out;
}

}  // namespace

ColliderCuts collider_cuts(const Collider& collider, const Eigen::Isometry3d& pose, const std::vector<Vec3>& x,
                           const std::vector<Eigen::Vector3i>& tris) {
  const ColliderShape& s = collider.shape();
  if (s.type != ColliderType::kBox && s.type != ColliderType::kCapsule)
    throw InputError("collider_cuts: only box and capsule colliders are covered");
  const int n = static_cast<int>(x.size());
  for (const Eigen::Vector3i& t : tris)
    for (int k = 0; k < 3; ++k)
      if (t[k] < 0 || t[k] >= n)
        throw InputError("collider_cuts: triangle index " + std::to_string(t[k]) + " out of range for " +
                         std::to_string(n) + " vertices");
  // The collider's world box, to skip elements far from it.
  Box3 near;
  const Vec3 r = s.type == ColliderType::kBox ? s.half_extents : Vec3(s.radius, s.radius, s.radius + s.half_length);
  for (int c = 0; c < 8; ++c)
    near.extend(pose * Vec3(c & 1 ? r.x() : -r.x(), c & 2 ? r.y() : -r.y(), c & 4 ? r.z() : -r.z()));
  const Eigen::Isometry3d inv = pose.inverse();
  // The depth below the surface of a cloth edge through the collider (asked only of those `inside`).
  auto depth = [&](const Vec3& a, const Vec3& b) -> Real {
    const Vec3 la = inv * a, lb = inv * b;
    if (s.type == ColliderType::kCapsule) {
      const Vec3 q(0, 0, s.half_length);
      return s.radius - std::sqrt(edge_edge_distance2(la, lb, -q, q, nullptr, nullptr));
    }
    // The box's signed distance is convex, so along the edge it has one minimum: golden section.
    auto sdf = [&](Real t) { return box_distance(la + t * (lb - la), s.half_extents, nullptr, nullptr); };
    Real lo = 0, hi = 1;
    const Real g = Real(0.5) * (std::sqrt(Real(5)) - 1);
    Real m1 = hi - g * (hi - lo), m2 = lo + g * (hi - lo), f1 = sdf(m1), f2 = sdf(m2);
    for (int it = 0; it < 40; ++it) {  // the bracket shrinks to 0.618^40 = 5e-9 of the edge
      if (f1 < f2) {
        hi = m2, m2 = m1, f2 = f1, m1 = hi - g * (hi - lo), f1 = sdf(m1);
      } else {
        lo = m1, m1 = m2, f1 = f2, m2 = lo + g * (hi - lo), f2 = sdf(m2);
      }
    }
    return std::max(Real(0), -std::min({f1, f2, sdf(0), sdf(1)}));
  };
  // The depth below the surface of a triangle the collider's edge passes through: a capsule's
  // axis through it puts it a radius deep; in a box, the deepest of a grid of points over it (the
  // box's distance is convex; the grid's spacing is a sixteenth of the triangle's edges).
  auto face_depth = [&](const Vec3& a, const Vec3& b, const Vec3& c) -> Real {
    if (s.type == ColliderType::kCapsule) return s.radius;
    constexpr int kN = 16;
    Real lowest = 0;
    for (int i = 0; i <= kN; ++i)
      for (int j = 0; i + j <= kN; ++j) {
        const Vec3 p = a + (Real(i) / kN) * (b - a) + (Real(j) / kN) * (c - a);
        lowest = std::min(lowest, box_distance(inv * p, s.half_extents, nullptr, nullptr));
      }
    return -lowest;
  };
  auto inside = [&](const Vec3& a, const Vec3& b) {
    if (s.type == ColliderType::kBox) return segment_meets_box(inv * a, inv * b, s.half_extents);
    const Vec3 q(0, 0, s.half_length);
    return edge_edge_distance2(inv * a, inv * b, -q, q, nullptr, nullptr) <= s.radius * s.radius;
  };
  const std::vector<std::pair<Vec3, Vec3>> own = collider_edges(s, pose);
  ColliderCuts cuts;
  std::vector<std::pair<int, int>> edges;  // of the triangles near the collider, each once
  for (const Eigen::Vector3i& t : tris) {
    Box3 tb(x[t[0]]);
    tb.extend(x[t[1]]).extend(x[t[2]]);
    if (!tb.intersects(near)) continue;
    for (int k = 0; k < 3; ++k) edges.emplace_back(std::minmax(t[k], t[(k + 1) % 3]));
    for (const auto& [a, b] : own)
      if (segment_triangle_intersect(a, b, x[t[0]], x[t[1]], x[t[2]], nullptr)) {
        ++cuts.faces_pierced;
        cuts.depth = std::max(cuts.depth, double(face_depth(x[t[0]], x[t[1]], x[t[2]])));
        break;
      }
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  for (const auto& [i, j] : edges)
    if (inside(x[i], x[j])) {
      ++cuts.edges_through;
      cuts.depth = std::max(cuts.depth, double(depth(x[i], x[j])));
    }
  return cuts;
}

}  // namespace gd::sim
