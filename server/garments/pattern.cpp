#include "garments/pattern.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>

#include "sim/demand.h"

namespace gd::garments {
namespace {

Vec2 curve_start(const Curve& c, bool reversed) { return reversed ? c.points.back() : c.points.front(); }
Vec2 curve_end(const Curve& c, bool reversed) { return reversed ? c.points.front() : c.points.back(); }

Real cross2(const Vec2& a, const Vec2& b) { return a.x() * b.y() - a.y() * b.x(); }

/// True when segments (a, b) and (c, d) properly cross (touching at end points does not count).
bool segments_cross(const Vec2& a, const Vec2& b, const Vec2& c, const Vec2& d) {
  const Real d1 = cross2(b - a, c - a), d2 = cross2(b - a, d - a);
  const Real d3 = cross2(d - c, a - c), d4 = cross2(d - c, b - c);
  const Real eps = 1e-14;
  return ((d1 > eps && d2 < -eps) || (d1 < -eps && d2 > eps)) &&
         ((d3 > eps && d4 < -eps) || (d3 < -eps && d4 > eps));
}

bool point_in_polygon(const Vec2& p, const std::vector<Vec2>& poly) {
  bool in = false;
  for (size_t i = 0, j = poly.size() - 1; i < poly.size(); j = i++) {
    const Vec2 &a = poly[i], &b = poly[j];
    if ((a.y() > p.y()) != (b.y() > p.y()) &&
        p.x() < (b.x() - a.x()) * (p.y() - a.y()) / (b.y() - a.y()) + a.x())
      in = !in;
  }
  return in;
}

/// Pattern problems come from the sizes a caller chose, so they are input errors.
void demand(bool ok, const std::string& msg) {
  if (!ok) throw sim::InputError("invalid garment pattern: " + msg + " (check the garment sizes)");
}

}  // namespace

int Pattern::add_curve(std::string name, std::vector<Vec2> pts) {
  curves.push_back({std::move(name), std::move(pts)});
  return int(curves.size()) - 1;
}

int Pattern::add_panel(std::string name, Layer layer, std::vector<CurveRef> outline, Vec2 grain) {
  Panel p;
  p.name = std::move(name);
  p.layer = layer;
  p.outline = std::move(outline);
  p.grain = grain.normalized();
  panels.push_back(std::move(p));
  return int(panels.size()) - 1;
}

std::vector<Vec2> panel_polygon(const Pattern& pattern, int p) {
  std::vector<Vec2> poly;
  for (const CurveRef& r : pattern.panels[p].outline) {
    const std::vector<Vec2>& pts = pattern.curves[r.curve].points;
    const int n = int(pts.size());
    for (int k = 0; k + 1 < n; ++k) poly.push_back(r.reversed ? pts[n - 1 - k] : pts[k]);
  }
  return poly;
}

Real signed_area(const std::vector<Vec2>& poly) {
  Real a = 0;
  for (size_t i = 0; i < poly.size(); ++i) a += cross2(poly[i], poly[(i + 1) % poly.size()]);
  return 0.5 * a;
}

void orient_panels(Pattern& pattern) {
  for (int p = 0; p < int(pattern.panels.size()); ++p) {
    if (signed_area(panel_polygon(pattern, p)) >= 0) continue;
    std::vector<CurveRef>& o = pattern.panels[p].outline;
    std::reverse(o.begin(), o.end());
    for (CurveRef& r : o) r.reversed = !r.reversed;
  }
}

void check_pattern(const Pattern& pattern) {
  const int nc = int(pattern.curves.size());
  for (const Curve& c : pattern.curves) {
    demand(c.points.size() >= 2, fmt::format("curve {} has fewer than 2 points", c.name));
    for (size_t k = 0; k + 1 < c.points.size(); ++k)
      demand((c.points[k + 1] - c.points[k]).norm() > 1e-6,
                fmt::format("curve {} repeats a point", c.name));
  }
  std::vector<int> uses(nc, 0);
  for (int p = 0; p < int(pattern.panels.size()); ++p) {
    const Panel& panel = pattern.panels[p];
    demand(!panel.outline.empty(), fmt::format("panel {} has no outline", panel.name));
    for (size_t k = 0; k < panel.outline.size(); ++k) {
      const CurveRef& r = panel.outline[k];
      const CurveRef& next = panel.outline[(k + 1) % panel.outline.size()];
      demand(r.curve >= 0 && r.curve < nc, "outline curve index out of range");
      ++uses[r.curve];
      const Vec2 end = curve_end(pattern.curves[r.curve], r.reversed);
      const Vec2 start = curve_start(pattern.curves[next.curve], next.reversed);
      demand((end - start).norm() < 1e-9,
                fmt::format("panel {}: curve {} does not end where {} starts", panel.name,
                            pattern.curves[r.curve].name, pattern.curves[next.curve].name));
    }
    const std::vector<Vec2> poly = panel_polygon(pattern, p);
    demand(std::abs(signed_area(poly)) > 1e-6, fmt::format("panel {} has no area", panel.name));
    for (size_t i = 0; i < poly.size(); ++i)
      for (size_t j = i + 2; j < poly.size(); ++j) {
        if (i == 0 && j + 1 == poly.size()) continue;
        demand(!segments_cross(poly[i], poly[i + 1], poly[j], poly[(j + 1) % poly.size()]),
                  fmt::format("panel {} has a self-intersecting outline", panel.name));
      }
    for (int f : panel.folds) {
      demand(f >= 0 && f < nc, "fold curve index out of range");
      const std::vector<Vec2>& pts = pattern.curves[f].points;
      for (size_t k = 0; k + 1 < pts.size(); ++k)
        demand(point_in_polygon(0.5 * (pts[k] + pts[k + 1]), poly),
                  fmt::format("fold {} leaves panel {}", pattern.curves[f].name, panel.name));
    }
  }
  for (int c = 0; c < nc; ++c)
    demand(uses[c] <= 2, fmt::format("curve {} is on {} panel outlines; at most 2",
                                        pattern.curves[c].name, uses[c]));
  for (const CurveFeature& f : pattern.folds) {
    bool inside = false;
    for (const Panel& p : pattern.panels)
      inside = inside || std::find(p.folds.begin(), p.folds.end(), f.curve) != p.folds.end();
    demand(inside, "a fold feature names a curve that is no panel's fold line");
  }
  for (const CurveFeature& e : pattern.elastic)
    demand(e.curve >= 0 && e.curve < nc && uses[e.curve] > 0,
              "an elastic feature names a curve that is on no panel outline");
}

std::vector<std::string> seam_names(const Pattern& pattern) {
  std::vector<int> uses(pattern.curves.size(), 0);
  for (const Panel& p : pattern.panels)
    for (const CurveRef& r : p.outline) ++uses[r.curve];
  std::vector<std::string> names;
  for (size_t c = 0; c < pattern.curves.size(); ++c)
    if (uses[c] == 2) names.push_back(pattern.curves[c].name);
  return names;
}

}  // namespace gd::garments
