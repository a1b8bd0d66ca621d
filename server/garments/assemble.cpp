#include "garments/assemble.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>

#include "garments/mesher.h"
#include "sim/demand.h"
#include "sim/log.h"

namespace gd::garments {
namespace {

/// The mesher's edge-length bound relative to the boundary spacing: Delaunay refinement with an
/// upper bound on the longest edge gives a mean edge of roughly 0.7 of the bound.
constexpr Real kMaxEdgeFactor = 1.45;
constexpr int kMaxRemesh = 30;
constexpr int kFrontBit = 1, kBackBit = 2;

Real segment_distance(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 d = b - a;
  const Real t = std::clamp((p - a).dot(d) / d.squaredNorm(), Real(0), Real(1));
  return (a + t * d - p).norm();
}

using NodeKey = std::pair<long long, long long>;
NodeKey node_key(const Vec2& p) { return {std::llround(p.x() * 1e8), std::llround(p.y() * 1e8)}; }

/// Panel p's constraint input for the mesher, and the curve sample each input point came from.
struct PanelInput {
  std::vector<Vec2> boundary;
  std::vector<std::vector<Vec2>> folds;
  std::vector<std::pair<int, int>> source;  // per input point: (curve, sample index)
};

PanelInput panel_input(const Pattern& pat, const std::vector<std::vector<Vec2>>& samples, int p) {
  PanelInput in;
  for (const CurveRef& r : pat.panels[p].outline) {
    const std::vector<Vec2>& s = samples[r.curve];
    const int n = int(s.size());
    for (int k = 0; k + 1 < n; ++k) {
      const int i = r.reversed ? n - 1 - k : k;
      in.boundary.push_back(s[i]);
      in.source.emplace_back(r.curve, i);
    }
  }
  for (int f : pat.panels[p].folds) {
    in.folds.push_back(samples[f]);
    for (int i = 0; i < int(samples[f].size()); ++i) in.source.emplace_back(f, i);
  }
  return in;
}

}  // namespace

Garment sew_pattern(Pattern pat, Real h, Real gap) {
  GD_DEMAND(h > 0 && std::isfinite(h), "spacing must be positive");
  orient_panels(pat);
  check_pattern(pat);
  const int nc = int(pat.curves.size()), np = int(pat.panels.size());

  std::vector<int> mask(nc, 0), outline_uses(nc, 0);
  std::vector<std::vector<int>> users(nc);  // panels whose constraints include the curve
  bool two_layers = false;
  for (int p = 0; p < np; ++p) {
    const Panel& panel = pat.panels[p];
    const int bit = panel.layer == Layer::kFront ? kFrontBit : kBackBit;
    two_layers = two_layers || panel.layer == Layer::kBack;
    for (const CurveRef& r : panel.outline) mask[r.curve] |= bit, ++outline_uses[r.curve], users[r.curve].push_back(p);
    for (int f : panel.folds) mask[f] |= bit, users[f].push_back(p);
  }

  // Sample every curve once; mesh the panels, adding any point the mesher put on a constrained
  // segment to that curve's sampling, until no constrained segment is split.
  std::vector<std::vector<Vec2>> samples(nc);
  for (int c = 0; c < nc; ++c) samples[c] = sample_polyline(pat.curves[c].points, h);
  std::vector<PanelMesh> meshes(np);
  std::vector<char> dirty(np, 1);
  int rounds = 0, added = 0;
  for (bool again = true; again; ++rounds) {
    GD_DEMAND(rounds < kMaxRemesh, "the mesher keeps splitting seam segments");
    again = false;
    for (int p = 0; p < np; ++p) {
      if (!dirty[p]) continue;
      dirty[p] = 0;
      const PanelInput in = panel_input(pat, samples, p);
      meshes[p] = mesh_panel(in.boundary, in.folds, kMaxEdgeFactor * h);
      for (const Vec2& s : meshes[p].split_points) {
        // The constrained segment of this panel that s lies on.
        int best_c = -1, best_k = -1;
        Real best = std::numeric_limits<Real>::max();
        auto scan = [&](int c) {
          for (int k = 0; k + 1 < int(samples[c].size()); ++k) {
            const Real d = segment_distance(s, samples[c][k], samples[c][k + 1]);
            if (d < best) best = d, best_c = c, best_k = k;
          }
        };
        for (const CurveRef& r : pat.panels[p].outline) scan(r.curve);
        for (int f : pat.panels[p].folds) scan(f);
        GD_DEMAND(best < 1e-7 * (1 + h), "a mesher point on a constraint lies on no curve");
        samples[best_c].insert(samples[best_c].begin() + best_k + 1, s);
        for (int q : users[best_c]) dirty[q] = 1;
        again = true;
        ++added;
      }
    }
  }
  if (added > 0) gd::log().debug("sew_pattern({}): {} seam points added in {} meshing rounds", pat.type, added, rounds);

  // Vertices: curve end points (nodes) are shared by every curve meeting there; the heights follow
  // the layers that meet at each vertex.
  auto z_of = [&](int m) -> Real {
    if (!two_layers) return 0;
    return m == (kFrontBit | kBackBit) ? 0.5 * gap : m == kFrontBit ? gap : 0;
  };
  // A node where a curve joining both layers ends is one vertex; elsewhere the front and back
  // curves ending at the same layout point (e.g. pleat lines) keep one vertex per layer.
  std::map<NodeKey, int> node_mask;
  for (int c = 0; c < nc; ++c) {
    node_mask[node_key(samples[c].front())] |= mask[c] == (kFrontBit | kBackBit) ? 4 : 0;
    node_mask[node_key(samples[c].back())] |= mask[c] == (kFrontBit | kBackBit) ? 4 : 0;
  }
  auto node_class = [&](const Vec2& q, int c) {
    return node_mask[node_key(q)] ? (kFrontBit | kBackBit) : mask[c];
  };
  std::map<std::pair<NodeKey, int>, int> node_vertex;
  Garment g;
  g.type = pat.type;
  g.spacing = h;
  sim::Mesh& m = g.mesh;
  std::vector<std::vector<int>> cv(nc);
  for (int c = 0; c < nc; ++c) {
    const int n = int(samples[c].size());
    cv[c].resize(n);
    for (int i = 0; i < n; ++i) {
      const Vec2& q = samples[c][i];
      if (i == 0 || i == n - 1) {
        const int cls = node_class(q, c);
        const auto [it, fresh] = node_vertex.emplace(std::make_pair(node_key(q), cls), int(m.x.size()));
        if (fresh) m.x.emplace_back(q.x(), q.y(), z_of(cls));
        cv[c][i] = it->second;
      } else {
        cv[c][i] = int(m.x.size());
        m.x.emplace_back(q.x(), q.y(), z_of(mask[c]));
      }
    }
  }

  // Triangles and per-corner pattern coordinates, panel by panel.
  for (int p = 0; p < np; ++p) {
    const Panel& panel = pat.panels[p];
    const bool front = panel.layer == Layer::kFront;
    const Real z = z_of(front ? kFrontBit : kBackBit);
    g.panels.push_back({panel.name, front});
    const PanelInput in = panel_input(pat, samples, p);
    const PanelMesh& pm = meshes[p];
    GD_DEMAND(pm.split_points.empty(), "panel mesh still has split constraints");
    std::vector<int> vid(pm.points.size()), uid(pm.points.size());
    const Vec2 gr = panel.grain;
    for (size_t i = 0; i < pm.points.size(); ++i) {
      const Vec2& q = pm.points[i];
      if (pm.input_index[i] >= 0) {
        const auto [c, k] = in.source[pm.input_index[i]];
        vid[i] = cv[c][k];
      } else {
        vid[i] = int(m.x.size());
        m.x.emplace_back(q.x(), q.y(), z);
      }
      // Pattern coordinates: the grain becomes axis 0; back panels are seen from below (mirrored).
      const Real u = q.dot(gr), v = gr.x() * q.y() - gr.y() * q.x();
      uid[i] = int(m.uv.size());
      m.uv.emplace_back(u, front ? v : -v);
    }
    for (const Eigen::Vector3i& t : pm.tris) {
      if (front) {
        m.tris.emplace_back(vid[t[0]], vid[t[1]], vid[t[2]]);
        m.uv_tris.emplace_back(uid[t[0]], uid[t[1]], uid[t[2]]);
      } else {
        m.tris.emplace_back(vid[t[0]], vid[t[2]], vid[t[1]]);
        m.uv_tris.emplace_back(uid[t[0]], uid[t[2]], uid[t[1]]);
      }
      g.triangle_panel.push_back(p);
    }
  }

  for (const CurveFeature& f : pat.folds)
    for (size_t k = 0; k + 1 < cv[f.curve].size(); ++k)
      m.creases.push_back({cv[f.curve][k], cv[f.curve][k + 1], f.value});
  for (const CurveFeature& e : pat.elastic)
    for (size_t k = 0; k + 1 < cv[e.curve].size(); ++k)
      m.elastic_edges.push_back({cv[e.curve][k], cv[e.curve][k + 1], e.value});
  for (int c = 0; c < nc; ++c)
    if (outline_uses[c] == 2) g.seams.push_back({pat.curves[c].name, cv[c]});

  sim::validate_mesh(m);
  return g;
}

}  // namespace gd::garments
