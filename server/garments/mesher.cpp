#include "garments/mesher.h"

#include <CGAL/Constrained_Delaunay_triangulation_2.h>
#include <CGAL/Delaunay_mesh_face_base_2.h>
#include <CGAL/Delaunay_mesh_size_criteria_2.h>
#include <CGAL/Delaunay_mesh_vertex_base_2.h>
#include <CGAL/Delaunay_mesher_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>
#include <tuple>
#include <map>
#include <numbers>
#include <utility>

#include "sim/demand.h"
#include "sim/types.h"

namespace gd::garments {
namespace {

using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Vb = CGAL::Delaunay_mesh_vertex_base_2<K>;
using Fb = CGAL::Delaunay_mesh_face_base_2<K>;
using Tds = CGAL::Triangulation_data_structure_2<Vb, Fb>;
using CDT = CGAL::Constrained_Delaunay_triangulation_2<K, Tds, CGAL::Exact_predicates_tag>;
using Criteria = CGAL::Delaunay_mesh_size_criteria_2<CDT>;
using Point = K::Point_2;

using Key = std::pair<double, double>;

}  // namespace

PanelMesh mesh_panel(const std::vector<Vec2>& boundary, const std::vector<std::vector<Vec2>>& folds,
                     Real max_edge) {
  GD_DEMAND(boundary.size() >= 3, "a panel outline needs at least 3 points");
  GD_DEMAND(max_edge > 0 && std::isfinite(max_edge), "max_edge must be positive");
  CDT cdt;
  std::map<Key, int> input;  // exact input coordinates -> input index
  int next = 0;
  auto insert = [&](const Vec2& p) {
    input.emplace(Key(p.x(), p.y()), next++);
    return cdt.insert(Point(p.x(), p.y()));
  };
  std::vector<CDT::Vertex_handle> ring;
  ring.reserve(boundary.size());
  for (const Vec2& p : boundary) ring.push_back(insert(p));
  for (size_t i = 0; i < ring.size(); ++i) {
    GD_DEMAND(ring[i] != ring[(i + 1) % ring.size()],
              fmt::format("panel outline repeats point ({}, {})", boundary[i].x(), boundary[i].y()));
    cdt.insert_constraint(ring[i], ring[(i + 1) % ring.size()]);
  }
  for (const std::vector<Vec2>& f : folds) {
    CDT::Vertex_handle prev;
    for (size_t k = 0; k < f.size(); ++k) {
      CDT::Vertex_handle v = insert(f[k]);
      GD_DEMAND(k == 0 || v != prev, "fold line repeats a point");
      if (k > 0) cdt.insert_constraint(prev, v);
      prev = v;
    }
  }
  // CGAL's refinement (what refine_Delaunay_mesh_2 runs), a point at a time under a budget: a
  // panel whose sizes are far apart in scale (a 1e9 m towel at 200 vertices) would take billions
  // of points to meet the angle bound, for minutes and gigabytes.
  const long budget = mesher_point_budget(boundary, max_edge);
  CGAL::Delaunay_mesher_2<CDT, Criteria> mesher(cdt, Criteria(kMesherAspectBound, max_edge));
  mesher.init();
  long steps = 0;
  while (!mesher.is_refinement_done()) {
    mesher.step_by_step_refine_mesh();
    if (++steps % kMesherCancelCheckPoints == 0) MeshingCancellation::check();
    if (static_cast<long>(cdt.number_of_vertices()) > budget)
      throw sim::InputError(fmt::format(
          "a garment panel needs more than {} mesh points at a spacing of {:.3g} m: its sizes are too far apart in "
          "scale (e.g. a very long, very narrow panel); give sizes of similar magnitude or more vertices",
          budget, max_edge));
  }

  PanelMesh out;
  std::map<CDT::Vertex_handle, int> index;
  auto id = [&](CDT::Vertex_handle v) {
    const auto [it, added] = index.emplace(v, int(out.points.size()));
    if (added) {
      const Vec2 p(v->point().x(), v->point().y());
      out.points.push_back(p);
      const auto in = input.find(Key(p.x(), p.y()));
      out.input_index.push_back(in == input.end() ? -1 : in->second);
    }
    return it->second;
  };
  for (auto f = cdt.finite_faces_begin(); f != cdt.finite_faces_end(); ++f) {
    if (!f->is_in_domain()) continue;
    out.tris.emplace_back(id(f->vertex(0)), id(f->vertex(1)), id(f->vertex(2)));
  }
  for (auto e = cdt.finite_edges_begin(); e != cdt.finite_edges_end(); ++e) {
    if (!cdt.is_constrained(*e)) continue;
    for (int k : {1, 2}) {
      const Point& p = e->first->vertex((e->second + k) % 3)->point();
      if (!input.count(Key(p.x(), p.y()))) out.split_points.emplace_back(p.x(), p.y());
    }
  }
  // A point splitting a constraint ends two constrained edges: report it once.
  std::sort(out.split_points.begin(), out.split_points.end(),
            [](const Vec2& a, const Vec2& b) { return std::tie(a.x(), a.y()) < std::tie(b.x(), b.y()); });
  out.split_points.erase(std::unique(out.split_points.begin(), out.split_points.end()), out.split_points.end());
  return out;
}

namespace {
thread_local MeshingCancellation* innermost_cancellation = nullptr;
}

MeshingCancellation::MeshingCancellation(std::function<bool()> cancelled)
    : cancelled_(std::move(cancelled)), outer_(innermost_cancellation) {
  innermost_cancellation = this;
}

MeshingCancellation::~MeshingCancellation() { innermost_cancellation = outer_; }

void MeshingCancellation::check() {
  const MeshingCancellation* c = innermost_cancellation;
  if (c && c->cancelled_ && c->cancelled_()) throw MeshingCancelled();
}

long mesher_point_budget(const std::vector<Vec2>& boundary, Real max_edge) {
  Real area = 0;  // shoelace
  for (size_t i = 0; i < boundary.size(); ++i) {
    const Vec2& a = boundary[i];
    const Vec2& b = boundary[(i + 1) % boundary.size()];
    area += a.x() * b.y() - a.y() * b.x();
  }
  const Real equilateral = std::abs(0.5 * area) / (max_edge * max_edge * std::sqrt(3.0) / 4);
  return static_cast<long>(std::min<Real>(1e9, kMesherBudgetFactor * equilateral + boundary.size() + kMesherBudgetFloor));
}

std::vector<Vec2> sample_polyline(const std::vector<Vec2>& pts, Real h) {
  GD_DEMAND(pts.size() >= 2 && h > 0, "sample_polyline needs 2 points and h > 0");
  const Real kKeepCos = std::cos(20.0 * std::numbers::pi / 180.0);
  std::vector<size_t> keep = {0};
  for (size_t k = 1; k + 1 < pts.size(); ++k) {
    const Vec2 a = (pts[k] - pts[k - 1]).normalized(), b = (pts[k + 1] - pts[k]).normalized();
    if (a.dot(b) < kKeepCos) keep.push_back(k);
  }
  keep.push_back(pts.size() - 1);
  std::vector<Vec2> out = {pts.front()};
  for (size_t s = 0; s + 1 < keep.size(); ++s) {
    const size_t i0 = keep[s], i1 = keep[s + 1];
    std::vector<Real> arc = {0};
    for (size_t k = i0; k < i1; ++k) arc.push_back(arc.back() + (pts[k + 1] - pts[k]).norm());
    const int n = std::max(1, int(std::lround(arc.back() / h)));
    size_t seg = 0;
    for (int j = 1; j < n; ++j) {
      const Real t = arc.back() * j / n;
      while (seg + 1 < arc.size() - 1 && arc[seg + 1] < t) ++seg;
      const Real w = (t - arc[seg]) / std::max(arc[seg + 1] - arc[seg], Real(1e-300));
      out.push_back((1 - w) * pts[i0 + seg] + w * pts[i0 + seg + 1]);
    }
    out.push_back(pts[i1]);
  }
  return out;
}

Real spacing_for_vertices(Real area, int vertices) {
  GD_DEMAND(area > 0 && vertices > 0, "spacing_for_vertices needs a positive area and count");
  return std::sqrt(2 * area / (std::sqrt(3.0) * vertices));
}

}  // namespace gd::garments
