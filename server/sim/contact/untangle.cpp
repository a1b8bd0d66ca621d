#include "sim/contact/untangle.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>

#include "sim/contact/distance.h"
#include "sim/contact/tri_tri_intersect.h"
#include "sim/demand.h"

namespace gd::sim {
namespace {

Vec3 vtx(const std::vector<double>& x, int i) { return Vec3(x[3 * i], x[3 * i + 1], x[3 * i + 2]); }

/// Smallest of the 15 primitive distances (6 point-triangle, 9 edge-edge) between two triangles, m.
double min_primitive_distance(const Vec3 (&a)[3], const Vec3 (&b)[3]) {
  double d2 = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    d2 = std::min(d2, point_triangle_distance2(a[k], b[0], b[1], b[2], nullptr, nullptr));
    d2 = std::min(d2, point_triangle_distance2(b[k], a[0], a[1], a[2], nullptr, nullptr));
    for (int j = 0; j < 3; ++j)
      d2 = std::min(d2, edge_edge_distance2(a[k], a[(k + 1) % 3], b[j], b[(j + 1) % 3], nullptr, nullptr));
  }
  return std::sqrt(std::max(d2, 0.0));
}

bool share_vertex(const int* a, const int* b) {
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j)
      if (a[i] == b[j]) return true;
  return false;
}

void check_mesh(const std::vector<double>& x, const std::vector<int>& tris) {
  GD_DEMAND(x.size() % 3 == 0, "positions must hold 3 coordinates per vertex");
  GD_DEMAND(tris.size() % 3 == 0, "triangles must hold 3 indices each");
  const int nv = static_cast<int>(x.size() / 3);
  for (int v : tris) GD_DEMAND(v >= 0 && v < nv, "triangle index out of range");
}

/// Unique undirected edges with, per triangle side k (vertices k, k+1), the edge id, and a CSR
/// vertex -> (neighbour, edge) adjacency.
struct EdgeTable {
  std::vector<Eigen::Vector2i> edges;
  std::vector<Eigen::Vector2i> edge_tris;  // first two triangles of each edge, -1 when absent
  std::vector<int> edge_sides;             // number of triangle sides on the edge (1: boundary)
  std::vector<int> tri_edge;               // 3 per triangle
  std::vector<int> adj_start, adj_vertex, adj_edge;
  bool boundary(int e) const { return edge_sides[e] == 1; }
  /// The triangle across edge e from triangle t (-1 for none).
  int across(int e, int t) const {
    if (edge_sides[e] != 2) return -1;
    return edge_tris[e][0] == t ? edge_tris[e][1] : edge_tris[e][0];
  }
};

EdgeTable build_edges(const std::vector<int>& tris, int nv) {
  const int nt = static_cast<int>(tris.size() / 3);
  std::vector<std::tuple<int, int, int>> sides;  // (lo, hi, 3 t + k)
  sides.reserve(tris.size());
  for (int t = 0; t < nt; ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = tris[3 * t + k], b = tris[3 * t + (k + 1) % 3];
      sides.emplace_back(std::min(a, b), std::max(a, b), 3 * t + k);
    }
  std::sort(sides.begin(), sides.end());
  EdgeTable et;
  et.tri_edge.assign(tris.size(), -1);
  for (size_t i = 0; i < sides.size(); ++i) {
    const auto [lo, hi, side] = sides[i];
    if (i == 0 || std::get<0>(sides[i - 1]) != lo || std::get<1>(sides[i - 1]) != hi) {
      et.edges.emplace_back(lo, hi);
      et.edge_tris.emplace_back(-1, -1);
      et.edge_sides.push_back(0);
    }
    const int e = static_cast<int>(et.edges.size()) - 1;
    et.tri_edge[side] = e;
    if (et.edge_sides[e] < 2) et.edge_tris[e][et.edge_sides[e]] = side / 3;
    ++et.edge_sides[e];
  }
  et.adj_start.assign(nv + 1, 0);
  for (const auto& e : et.edges) {
    ++et.adj_start[e[0] + 1];
    ++et.adj_start[e[1] + 1];
  }
  for (int v = 0; v < nv; ++v) et.adj_start[v + 1] += et.adj_start[v];
  et.adj_vertex.resize(2 * et.edges.size());
  et.adj_edge.resize(2 * et.edges.size());
  std::vector<int> fill(et.adj_start.begin(), et.adj_start.end() - 1);
  for (int e = 0; e < static_cast<int>(et.edges.size()); ++e) {
    const int a = et.edges[e][0], b = et.edges[e][1];
    et.adj_vertex[fill[a]] = b;
    et.adj_edge[fill[a]++] = e;
    et.adj_vertex[fill[b]] = a;
    et.adj_edge[fill[b]++] = e;
  }
  return et;
}

/// Edge `edge` (a side of triangle `own`, which gives the crossing its sheet colour) passes
/// through triangle `tri`.
struct Crossing {
  int edge, tri, own;
};

/// Unit normal and a point of triangle t (normal zero for a degenerate triangle).
void plane_of(const std::vector<double>& x, const std::vector<int>& tris, int t, Vec3* n, Vec3* p) {
  const Vec3 t0 = vtx(x, tris[3 * t]), t1 = vtx(x, tris[3 * t + 1]), t2 = vtx(x, tris[3 * t + 2]);
  *n = (t1 - t0).cross(t2 - t0);
  const double nn = n->norm();
  if (nn > 0.0 && std::isfinite(nn))
    *n /= nn;
  else
    n->setZero();
  *p = t0;
}

/// One displacement pass (steps 1-6 of the file comment of untangle.h). Returns the number of
/// vertices moved.
int untangle_pass(std::vector<double>* xp, const std::vector<int>& tris, const std::vector<int>& fixed,
                  const EdgeTable& et, const std::vector<Eigen::Vector2i>& pairs, double gap, int mode) {
  std::vector<double>& x = *xp;
  const int nv = static_cast<int>(x.size() / 3);
  const int nt = static_cast<int>(tris.size() / 3);
  const int ne = static_cast<int>(et.edges.size());
  auto is_fixed = [&](int v) { return !fixed.empty() && fixed[v] != 0; };

  // 1. Crossings, unique per (edge, triangle).
  std::vector<Crossing> cr;
  for (const auto& p : pairs) {
    for (int side = 0; side < 2; ++side) {
      const int own = p[side], other = p[1 - side];
      const Vec3 t0 = vtx(x, tris[3 * other]), t1 = vtx(x, tris[3 * other + 1]), t2 = vtx(x, tris[3 * other + 2]);
      for (int k = 0; k < 3; ++k) {
        const int e = et.tri_edge[3 * own + k];
        if (segment_triangle_intersect(vtx(x, et.edges[e][0]), vtx(x, et.edges[e][1]), t0, t1, t2, nullptr))
          cr.push_back({e, other, own});
      }
    }
  }
  std::sort(cr.begin(), cr.end(),
            [](const Crossing& a, const Crossing& b) { return std::tie(a.edge, a.tri) < std::tie(b.edge, b.tri); });
  cr.erase(std::unique(cr.begin(), cr.end(),
                       [](const Crossing& a, const Crossing& b) { return a.edge == b.edge && a.tri == b.tri; }),
           cr.end());
  if (cr.empty()) return 0;
  std::vector<Vec3> cr_n(cr.size()), cr_p(cr.size());
  for (size_t i = 0; i < cr.size(); ++i) plane_of(x, tris, cr[i].tri, &cr_n[i], &cr_p[i]);

  // 2. Cuts: the crossing edges, plus, where a contour ends inside a surface (a boundary edge
  //    crosses triangle T), the edges along the shortest dual path from T to the boundary.
  std::vector<char> cut(ne, 0);
  for (const auto& c : cr) cut[c.edge] = 1;
  {
    std::vector<int> via(nt, -2);  // edge reached through (-1: a source), -2 unvisited
    std::vector<int> exit_edge(nt, -1);
    std::vector<int> queue;
    for (int t = 0; t < nt; ++t)
      for (int k = 0; k < 3; ++k) {
        const int e = et.tri_edge[3 * t + k];
        if (et.boundary(e) && !cut[e] && via[t] == -2) {
          via[t] = -1;
          exit_edge[t] = e;
          queue.push_back(t);
        }
      }
    for (size_t q = 0; q < queue.size(); ++q) {
      const int t = queue[q];
      for (int k = 0; k < 3; ++k) {
        const int e = et.tri_edge[3 * t + k];
        const int u = et.across(e, t);
        if (u < 0 || cut[e] || via[u] != -2) continue;
        via[u] = e;
        queue.push_back(u);
      }
    }
    std::vector<char> extra(ne, 0);
    for (const auto& c : cr) {
      if (!et.boundary(c.edge) || via[c.tri] == -2) continue;
      int t = c.tri;
      while (via[t] >= 0) {
        extra[via[t]] = 1;
        t = et.across(via[t], t);
      }
      extra[exit_edge[t]] = 1;
    }
    for (int e = 0; e < ne; ++e) cut[e] |= extra[e];
  }

  // 3. Regions: components of the graph of uncut edges, with their penetration volume
  //    sum(vertex area * (depth + gap)), depth measured from the plane of the nearest crossing
  //    (breadth-first from the crossing edges' endpoints), and whether they hold a fixed vertex.
  std::vector<double> vertex_area(nv, 0.0);
  for (int t = 0; t < nt; ++t) {
    const Vec3 a = vtx(x, tris[3 * t]), b = vtx(x, tris[3 * t + 1]), c = vtx(x, tris[3 * t + 2]);
    const double A = 0.5 * (b - a).cross(c - a).norm();
    for (int k = 0; k < 3; ++k) vertex_area[tris[3 * t + k]] += A / 3.0;
  }
  std::vector<int> comp(nv, -1);
  std::vector<char> comp_fixed;
  std::vector<int> stack;
  int ncomp = 0;
  for (int s0 = 0; s0 < nv; ++s0) {
    if (comp[s0] >= 0) continue;
    comp_fixed.push_back(0);
    comp[s0] = ncomp;
    stack.assign(1, s0);
    while (!stack.empty()) {
      const int v = stack.back();
      stack.pop_back();
      if (is_fixed(v)) comp_fixed[ncomp] = 1;
      for (int j = et.adj_start[v]; j < et.adj_start[v + 1]; ++j) {
        const int w = et.adj_vertex[j];
        if (cut[et.adj_edge[j]] || comp[w] >= 0) continue;
        comp[w] = ncomp;
        stack.push_back(w);
      }
    }
    ++ncomp;
  }
  std::vector<double> comp_volume(ncomp, 0.0);
  {
    std::vector<int> plane(nv, -1);  // index of the crossing whose plane measures the depth
    std::vector<int> queue;
    for (size_t i = 0; i < cr.size(); ++i)
      for (int k = 0; k < 2; ++k) {
        const int v = et.edges[cr[i].edge][k];
        if (plane[v] < 0) {
          plane[v] = static_cast<int>(i);
          queue.push_back(v);
        }
      }
    for (size_t q = 0; q < queue.size(); ++q) {
      const int v = queue[q];
      for (int j = et.adj_start[v]; j < et.adj_start[v + 1]; ++j) {
        const int w = et.adj_vertex[j];
        if (cut[et.adj_edge[j]] || plane[w] >= 0) continue;
        plane[w] = plane[v];
        queue.push_back(w);
      }
    }
    for (int v = 0; v < nv; ++v) {
      const double depth = plane[v] >= 0 ? std::abs(cr_n[plane[v]].dot(vtx(x, v) - cr_p[plane[v]])) : 0.0;
      comp_volume[comp[v]] += vertex_area[v] * (depth + gap);
    }
  }

  // Contour groups and sheet colours: graph search over the triangles linked by intersecting pairs.
  std::vector<int> tri_group(nt, -1), tri_color(nt, 0);
  int ngroups = 0;
  {
    std::vector<int> deg_start(nt + 1, 0);
    for (const auto& p : pairs) {
      ++deg_start[p[0] + 1];
      ++deg_start[p[1] + 1];
    }
    for (int t = 0; t < nt; ++t) deg_start[t + 1] += deg_start[t];
    std::vector<int> nbr(deg_start[nt]);
    std::vector<int> fill(deg_start.begin(), deg_start.end() - 1);
    for (const auto& p : pairs) {
      nbr[fill[p[0]]++] = p[1];
      nbr[fill[p[1]]++] = p[0];
    }
    for (const auto& p : pairs) {
      if (tri_group[p[0]] >= 0) continue;
      tri_group[p[0]] = ngroups;
      stack.assign(1, p[0]);
      while (!stack.empty()) {
        const int t = stack.back();
        stack.pop_back();
        for (int j = deg_start[t]; j < deg_start[t + 1]; ++j) {
          const int u = nbr[j];
          if (tri_group[u] >= 0) continue;  // an odd cycle (triple intersection) keeps the first colour
          tri_group[u] = ngroups;
          tri_color[u] = 1 - tri_color[t];
          stack.push_back(u);
        }
      }
      ++ngroups;
    }
  }

  // 4. Mover per crossing. The penetrating endpoint is the one in the region of smaller volume
  //    (separating crossing) or with the smaller move (non-separating).
  struct Move {
    int group = -1, color = 0;
    int vertex = -1;  // chosen mover, -1 when none
    Vec3 d = Vec3::Zero();
    int region = -1;  // region moved when the crossing separates
    bool separating = false;
    int fb_vertex[3] = {-1, -1, -1};  // fallback movers (see step 6)
    Vec3 fb_d = Vec3::Zero();
  };
  std::vector<Move> moves(cr.size());
  for (size_t i = 0; i < cr.size(); ++i) {
    const Crossing& c = cr[i];
    Move& m = moves[i];
    m.group = tri_group[c.own];
    m.color = tri_color[c.own];
    const Vec3& n = cr_n[i];
    if (n.squaredNorm() == 0.0) continue;  // degenerate triangle: no direction
    const int ev[2] = {et.edges[c.edge][0], et.edges[c.edge][1]};
    const double h[2] = {n.dot(vtx(x, ev[0]) - cr_p[i]), n.dot(vtx(x, ev[1]) - cr_p[i])};
    Vec3 d[2];
    for (int k = 0; k < 2; ++k) {
      const double s = h[1 - k] < h[k] ? -1.0 : 1.0;  // towards the other endpoint's side
      d[k] = (s * gap - h[k]) * n;
    }
    const int c0 = comp[ev[0]], c1 = comp[ev[1]];
    m.separating = c0 != c1;
    const int pen = m.separating ? (comp_volume[c1] < comp_volume[c0] ? 1 : 0) : (d[1].norm() < d[0].norm() ? 1 : 0);
    if (m.separating) {
      int best = -1;
      for (int k : {pen, 1 - pen})
        if (!comp_fixed[comp[ev[k]]]) {
          best = k;
          break;
        }
      if (best >= 0) {
        m.vertex = ev[best];
        m.d = d[best];
        m.region = comp[ev[best]];
      }
    } else {
      for (int k : {pen, 1 - pen})
        if (!is_fixed(ev[k])) {
          m.vertex = ev[k];
          m.d = d[k];
          break;
        }
    }
    // Fallback: the penetrating endpoint if free, else the pierced triangle's vertices the other
    // way, else the other endpoint.
    if (!is_fixed(ev[pen])) {
      m.fb_vertex[0] = ev[pen];
      m.fb_d = d[pen];
    } else {
      int j = 0;
      for (int k = 0; k < 3; ++k)
        if (!is_fixed(tris[3 * c.tri + k])) m.fb_vertex[j++] = tris[3 * c.tri + k];
      m.fb_d = -d[pen];
      if (j == 0 && !is_fixed(ev[1 - pen])) {
        m.fb_vertex[0] = ev[1 - pen];
        m.fb_d = d[1 - pen];
      }
    }
  }

  // 5. One colour per group, compared by (non-separating crossings, volume of the distinct
  //    regions moved); a colour without crossings, or with a crossing that has no mover, is
  //    infeasible. mode 0: the cheaper feasible colour; 1: the dearer one when both are feasible;
  //    2: no colour (fallback moves everywhere).
  struct Cost {
    bool infeasible = false;
    int nonsep = 0;
    double volume = 0.0;
    int count = 0;
  };
  std::vector<Cost> cost(2 * ngroups);
  std::vector<std::tuple<int, int, int>> regions;  // (group, colour, region), each summed once
  for (const auto& m : moves) {
    if (m.group < 0) continue;
    Cost& c = cost[2 * m.group + m.color];
    ++c.count;
    if (m.vertex < 0)
      c.infeasible = true;
    else if (m.separating)
      regions.emplace_back(m.group, m.color, m.region);
    else
      ++c.nonsep;
  }
  std::sort(regions.begin(), regions.end());
  regions.erase(std::unique(regions.begin(), regions.end()), regions.end());
  for (const auto& [g, col, r] : regions) cost[2 * g + col].volume += comp_volume[r];
  std::vector<int> chosen(ngroups, -1);  // colour, or -1 for the fallback (both colours)
  for (int g = 0; g < ngroups; ++g) {
    if (mode == 2) continue;  // fallback for every group
    const Cost& c0 = cost[2 * g];
    const Cost& c1 = cost[2 * g + 1];
    const bool ok0 = c0.count > 0 && !c0.infeasible, ok1 = c1.count > 0 && !c1.infeasible;
    if (ok0 && ok1)  // mode 1 takes the dearer colour
      chosen[g] = (std::tie(c0.nonsep, c0.volume) <= std::tie(c1.nonsep, c1.volume)) == (mode == 0) ? 0 : 1;
    else if (ok0 || ok1)
      chosen[g] = ok0 ? 0 : 1;
  }

  // 6. Average the displacements per vertex and apply them to free vertices.
  std::vector<Vec3> sum(nv, Vec3::Zero());
  std::vector<int> n_moves(nv, 0);
  for (const auto& m : moves) {
    if (m.group < 0) continue;
    const int ch = chosen[m.group];
    if (ch < 0) {
      for (int v : m.fb_vertex)
        if (v >= 0) {
          sum[v] += m.fb_d;
          ++n_moves[v];
        }
      continue;
    }
    if (m.color != ch || m.vertex < 0) continue;
    sum[m.vertex] += m.d;
    ++n_moves[m.vertex];
  }
  int moved = 0;
  for (int v = 0; v < nv; ++v) {
    if (n_moves[v] == 0) continue;
    const Vec3 d = sum[v] / n_moves[v];
    if (!d.allFinite() || d.squaredNorm() == 0.0) continue;
    for (int k = 0; k < 3; ++k) x[3 * v + k] += d[k];
    ++moved;
  }
  return moved;
}

}  // namespace

std::vector<Eigen::Vector2i> intersecting_pairs(const std::vector<double>& x, const std::vector<int>& tris,
                                                const std::vector<Eigen::Vector2i>& candidates) {
  check_mesh(x, tris);
  const int nt = static_cast<int>(tris.size() / 3);
  // Candidates in parallel, each thread collecting its own; sorted below, so the answer does not
  // depend on the thread count.
  std::vector<Eigen::Vector2i> out;
  const int count = static_cast<int>(candidates.size());
#pragma omp parallel if (count >= 4096)
  {
    std::vector<Eigen::Vector2i> found;
#pragma omp for schedule(static) nowait
    for (int k = 0; k < count; ++k) {
      const auto& c = candidates[k];
      const int a = std::min(c[0], c[1]), b = std::max(c[0], c[1]);
      GD_DEMAND(a >= 0 && b < nt, "candidate triangle index out of range");
      if (a == b) continue;
      const int* ta = &tris[3 * a];
      const int* tb = &tris[3 * b];
      if (share_vertex(ta, tb)) continue;
      const Vec3 a0 = vtx(x, ta[0]), a1 = vtx(x, ta[1]), a2 = vtx(x, ta[2]);
      const Vec3 b0 = vtx(x, tb[0]), b1 = vtx(x, tb[1]), b2 = vtx(x, tb[2]);
      // Cheap box rejection, conservative with respect to the test's tolerance (1e-12 of the extent).
      const Vec3 alo = a0.cwiseMin(a1).cwiseMin(a2), ahi = a0.cwiseMax(a1).cwiseMax(a2);
      const Vec3 blo = b0.cwiseMin(b1).cwiseMin(b2), bhi = b0.cwiseMax(b1).cwiseMax(b2);
      const double slack = 1e-9 * (ahi.cwiseMax(bhi) - alo.cwiseMin(blo)).maxCoeff();
      if (((alo.array() - slack) > bhi.array()).any() || ((blo.array() - slack) > ahi.array()).any()) continue;
      if (!triangles_intersect(a0, a1, a2, b0, b1, b2)) continue;
      // Touching within rounding is contact, not a crossing: a crossing formed by continuous
      // motion has no primitive pair at (numerically) zero distance, since it passes through
      // contact first.
      const Vec3 ta3[3] = {a0, a1, a2}, tb3[3] = {b0, b1, b2};
      if (min_primitive_distance(ta3, tb3) < kTouchDistance) continue;
      found.emplace_back(a, b);
    }
#pragma omp critical(gd_intersecting_pairs)
    out.insert(out.end(), found.begin(), found.end());
  }
  std::sort(out.begin(), out.end(),
            [](const Eigen::Vector2i& p, const Eigen::Vector2i& q) { return std::tie(p[0], p[1]) < std::tie(q[0], q[1]); });
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

UntangleResult untangle(std::vector<double>* x, const std::vector<int>& tris, const std::vector<int>& fixed,
                        const std::function<std::vector<Eigen::Vector2i>(const std::vector<double>&)>& candidates,
                        double gap, int max_iters) {
  GD_DEMAND(x != nullptr, "untangle needs positions");
  check_mesh(*x, tris);
  const int nv = static_cast<int>(x->size() / 3);
  GD_DEMAND(fixed.empty() || static_cast<int>(fixed.size()) == nv, "fixed must be empty or one flag per vertex");
  GD_DEMAND(std::isfinite(gap) && gap >= 0.0, "gap must be finite and non-negative");
  UntangleResult r;
  std::vector<Eigen::Vector2i> pairs = intersecting_pairs(*x, tris, candidates(*x));
  r.intersecting_before = static_cast<int>(pairs.size());
  if (pairs.empty()) return r;
  const EdgeTable et = build_edges(tris, nv);
  // Stall handling: after two passes without a new lowest pair count, two passes that move the
  // other colour, then two fallback passes (both colours), then normal again, and so on.
  size_t best = pairs.size();
  std::vector<double> best_x = *x;  // the state with the fewest pairs so far (the input first)
  int stall = 0, idle = 0;
  while (!pairs.empty() && r.iterations < max_iters) {
    const int mode = (stall / 2) % 3;
    const int moved = untangle_pass(x, tris, fixed, et, pairs, gap, mode);
    ++r.iterations;
    if (moved == 0) {
      if (++idle == 3) break;  // nothing can move in any mode: stuck
      stall = 2 * ((mode + 1) % 3);
      --r.iterations;
      continue;
    }
    idle = 0;
    pairs = intersecting_pairs(*x, tris, candidates(*x));
    if (pairs.size() < best) {
      best = pairs.size();
      best_x = *x;
      stall = 0;
    } else {
      ++stall;
    }
  }
  if (pairs.size() > best) {  // never hand back more crossings than the best state seen
    *x = std::move(best_x);
    pairs = intersecting_pairs(*x, tris, candidates(*x));
  }
  r.intersecting_after = static_cast<int>(pairs.size());
  return r;
}

std::vector<Eigen::Vector2i> all_triangle_pairs(const std::vector<int>& tris, int vertex_count) {
  GD_DEMAND(tris.size() % 3 == 0, "triangles must hold 3 indices each");
  for (int v : tris) GD_DEMAND(v >= 0 && v < vertex_count, "triangle index out of range");
  const int nt = static_cast<int>(tris.size() / 3);
  std::vector<Eigen::Vector2i> out;
  for (int a = 0; a < nt; ++a)
    for (int b = a + 1; b < nt; ++b)
      if (!share_vertex(&tris[3 * a], &tris[3 * b])) out.emplace_back(a, b);
  return out;
}

}  // namespace gd::sim
