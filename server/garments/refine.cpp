#include "garments/refine.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <map>
#include <tuple>
#include <utility>

#include "sim/demand.h"

namespace gd::garments {

namespace {

/// Whether a triangle (its corners `f` in `m`) has a corner or its centroid within `radius` of one
/// of `centres`: the triangles refine_near refines and edge_near measures.
bool near_centres(const sim::Mesh& m, const Eigen::Vector3i& f, const std::vector<Vec3>& centres, Real radius) {
  const Vec3 c = (m.x[f[0]] + m.x[f[1]] + m.x[f[2]]) / 3.0;
  for (const Vec3& centre : centres) {
    if ((c - centre).norm() <= radius) return true;
    for (int k = 0; k < 3; ++k)
      if ((m.x[f[k]] - centre).norm() <= radius) return true;
  }
  return false;
}

using EdgeKey = std::pair<int, int>;  // an undirected edge, smaller vertex first
EdgeKey key(int a, int b) { return a < b ? EdgeKey{a, b} : EdgeKey{b, a}; }

/// Refinement state over one garment's mesh: the edges' triangles and the midpoints made so far.
class Refiner {
 public:
  Refiner(Garment& g, const RefineRegion& r) : g_(g), m_(g.mesh), r_(r) {
    for (int t = 0; t < static_cast<int>(m_.tris.size()); ++t) add_triangle_edges(t);
  }

  /// Bisects every triangle near a centre until its longest edge is at most the region's edge.
  void run(long max_added) {
    const long start = static_cast<long>(m_.x.size());
    for (bool changed = true; changed;) {
      changed = false;
      for (int t = 0; t < static_cast<int>(m_.tris.size()); ++t)
        if (near(t) && length2(longest(t)) > r_.edge * r_.edge) {
          refine(t);
          changed = true;
          if (static_cast<long>(m_.x.size()) - start > max_added)
            throw TooManyVertices(fmt::format("refining within {} m of the given points to {} m edges would make more "
                                              "than {} vertices (the garment had {}); use a larger edge or a smaller "
                                              "radius", r_.radius, r_.edge, start + max_added, start));
        }
    }
    fix_edge_lists();
  }

 private:
  /// Rivara's LEPP: bisect t's longest edge once the triangle across it has that edge as its own
  /// longest (refining that neighbour first, and so on along edges that only grow, so it ends).
  void refine(int t) {
    for (;;) {
      const EdgeKey e = longest(t);
      const int n = across(e, t);
      if (n < 0 || longest(n) == e) {
        split(e);
        return;
      }
      refine(n);
    }
  }

  double length2(const EdgeKey& e) const { return (m_.x[e.first] - m_.x[e.second]).squaredNorm(); }

  /// A total order on edges (length, then vertices): both triangles of an edge agree on whether
  /// it is their longest.
  bool shorter(const EdgeKey& a, const EdgeKey& b) const {
    const double la = length2(a), lb = length2(b);
    return la != lb ? la < lb : a < b;
  }

  EdgeKey longest(int t) const {
    const auto& f = m_.tris[t];
    EdgeKey best = key(f[0], f[1]);
    for (int k = 1; k < 3; ++k)
      if (const EdgeKey e = key(f[k], f[(k + 1) % 3]); shorter(best, e)) best = e;
    return best;
  }

  int across(const EdgeKey& e, int t) const {
    const auto& pair = edge_tris_.at(e);
    return pair[0] == t ? pair[1] : pair[0];
  }

  bool near(int t) const { return near_centres(m_, m_.tris[t], r_.centres, r_.radius); }

  void add_edge(const EdgeKey& e, int t) {
    auto [it, fresh] = edge_tris_.try_emplace(e, std::array<int, 2>{t, -1});
    if (!fresh) {
      GD_DEMAND(it->second[1] < 0, "refine_near: a non-manifold edge (the garment passed validate_mesh)");
      it->second[1] = t;
    }
  }
  void replace_edge_triangle(const EdgeKey& e, int from, int to) {
    auto& pair = edge_tris_.at(e);
    (pair[0] == from ? pair[0] : pair[1]) = to;
  }
  void add_triangle_edges(int t) {
    const auto& f = m_.tris[t];
    for (int k = 0; k < 3; ++k) add_edge(key(f[k], f[(k + 1) % 3]), t);
  }

  /// Splits edge e at its midpoint in both its triangles (each into two, orientation kept).
  void split(const EdgeKey& e) {
    const int mid = static_cast<int>(m_.x.size());
    m_.x.push_back(0.5 * (m_.x[e.first] + m_.x[e.second]));
    const bool uv_per_vertex = !m_.uv.empty() && m_.uv_tris.empty();
    if (uv_per_vertex) m_.uv.push_back(0.5 * (m_.uv[e.first] + m_.uv[e.second]));
    midpoint_[e] = mid;
    const std::array<int, 2> tris = edge_tris_.at(e);
    edge_tris_.erase(e);
    for (int t : tris) {
      if (t < 0) continue;
      const Eigen::Vector3i f = m_.tris[t];
      int k = 0;
      while (key(f[k], f[(k + 1) % 3]) != e) ++k;
      const int p = f[k], q = f[(k + 1) % 3], r = f[(k + 2) % 3];
      const int child = static_cast<int>(m_.tris.size());
      m_.tris[t] = Eigen::Vector3i(p, mid, r);
      m_.tris.emplace_back(mid, q, r);
      if (!m_.uv_tris.empty()) {  // a seam's vertex has one pattern point per panel: the midpoint of this side's
        const Eigen::Vector3i u = m_.uv_tris[t];
        const int up = u[k], uq = u[(k + 1) % 3], ur = u[(k + 2) % 3];
        auto [it, fresh] = uv_midpoint_.try_emplace(key(up, uq), static_cast<int>(m_.uv.size()));
        if (fresh) m_.uv.push_back(0.5 * (m_.uv[up] + m_.uv[uq]));
        m_.uv_tris[t] = Eigen::Vector3i(up, it->second, ur);
        m_.uv_tris.emplace_back(it->second, uq, ur);
      }
      if (!g_.triangle_panel.empty()) g_.triangle_panel.push_back(g_.triangle_panel[t]);
      add_edge(key(p, mid), t);
      add_edge(key(mid, q), child);
      add_edge(key(mid, r), t);
      add_edge(key(mid, r), child);
      replace_edge_triangle(key(q, r), t, child);
    }
  }

  /// The vertices strictly between a and b after the splits, in order from a.
  void chain(int a, int b, std::vector<int>* out) const {
    const auto it = midpoint_.find(key(a, b));
    if (it == midpoint_.end()) return;
    chain(a, it->second, out);
    out->push_back(it->second);
    chain(it->second, b, out);
  }

  /// Creases, elastic edges and seams that ran along a split edge now run along its halves.
  void fix_edge_lists() {
    auto halves = [&](int a, int b) {
      std::vector<int> v{a};
      chain(a, b, &v);
      v.push_back(b);
      return v;
    };
    std::vector<sim::Crease> creases;
    for (const sim::Crease& c : m_.creases) {
      const std::vector<int> v = halves(c.a, c.b);
      for (size_t i = 0; i + 1 < v.size(); ++i) creases.push_back({v[i], v[i + 1], c.bend_scale});
    }
    m_.creases = std::move(creases);
    std::vector<sim::ElasticEdge> elastic;
    for (const sim::ElasticEdge& e : m_.elastic_edges) {
      const std::vector<int> v = halves(e.a, e.b);
      for (size_t i = 0; i + 1 < v.size(); ++i) elastic.push_back({v[i], v[i + 1], e.ratio});
    }
    m_.elastic_edges = std::move(elastic);
    for (SeamInfo& s : g_.seams) {
      std::vector<int> v;
      for (size_t i = 0; i < s.vertices.size(); ++i) {
        v.push_back(s.vertices[i]);
        if (i + 1 < s.vertices.size()) chain(s.vertices[i], s.vertices[i + 1], &v);
      }
      s.vertices = std::move(v);
    }
  }

  Garment& g_;
  sim::Mesh& m_;
  const RefineRegion& r_;
  std::map<EdgeKey, std::array<int, 2>> edge_tris_;  // each edge's triangles (-1: a boundary edge)
  std::map<EdgeKey, int> midpoint_;                  // split edges' midpoints
  std::map<EdgeKey, int> uv_midpoint_;               // split pattern edges' midpoints (uv_tris meshes)
};

}  // namespace

int refine_near(Garment& g, const RefineRegion& region) {
  if (!(std::isfinite(region.radius) && region.radius > 0))
    throw sim::InputError(fmt::format("the refinement radius must be a positive number of metres (got {})", region.radius));
  if (!(std::isfinite(region.edge) && region.edge >= 1e-3))
    throw sim::InputError(fmt::format("the refined edge must be at least 1 mm (got {} m)", region.edge));
  const int before = static_cast<int>(g.mesh.x.size());
  if (region.centres.empty()) return 0;
  const long budget = region.max_vertices > 0 ? region.max_vertices - before : 200000;
  if (budget < 0)
    throw TooManyVertices(fmt::format("the garment has {} vertices before refining, over the limit of {}", before,
                                      region.max_vertices));
  Refiner(g, region).run(budget);
  sim::validate_mesh(g.mesh);
  return static_cast<int>(g.mesh.x.size()) - before;
}

Real edge_near(const Garment& g, const std::vector<Vec3>& centres, Real radius) {
  const sim::Mesh& m = g.mesh;
  std::vector<Real> edges;
  for (const auto& f : m.tris) {
    if (!near_centres(m, f, centres, radius)) continue;
    Real longest = 0;
    for (int k = 0; k < 3; ++k) longest = std::max(longest, (m.x[f[k]] - m.x[f[(k + 1) % 3]]).norm());
    edges.push_back(longest);
  }
  if (edges.empty()) return 0;
  const auto mid = edges.begin() + static_cast<std::ptrdiff_t>(edges.size() / 2);
  std::nth_element(edges.begin(), mid, edges.end());
  return *mid;
}

std::vector<Vec3> grasp_landmarks(const Landmarks& l, bool fold) {
  std::vector<Vec3> c = {l.left_shoulder, l.right_shoulder};
  if (fold) c.insert(c.end(), {l.left_hem, l.right_hem});
  if (fold && l.has_hood) c.insert(c.end(), {l.left_hood, l.right_hood});
  return c;
}

}  // namespace gd::garments
