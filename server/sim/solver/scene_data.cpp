#include "sim/solver/scene_data.h"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <queue>
#include <unordered_map>
#include <utility>
#include <vector>

#include "sim/demand.h"
#include "sim/log.h"

namespace gd::sim {
namespace {

/// 2D rest coordinates of a triangle's corners: pattern UVs, or the 3D triangle flattened into a
/// frame whose first axis is the world x axis projected onto the triangle (the warp direction of
/// garments laid out as RGBench lays them) or, if that degenerates, the first edge.
void rest_corners(const Mesh& m, int ti, bool use_uv, Vec2 p[3]) {
  const Eigen::Vector3i& t = m.tris[ti];
  if (use_uv) {
    for (int k = 0; k < 3; ++k) p[k] = corner_uv(m, ti, k);
    return;
  }
  const Vec3 x0 = m.x[t[0]], e1 = m.x[t[1]] - x0, e2 = m.x[t[2]] - x0;
  const Vec3 n = e1.cross(e2).normalized();
  Vec3 a1 = Vec3::UnitX() - n * n.x();
  if (a1.norm() < 1e-3) a1 = e1;
  a1.normalize();
  const Vec3 a2 = n.cross(a1);
  p[0] = Vec2::Zero();
  p[1] = Vec2(e1.dot(a1), e1.dot(a2));
  p[2] = Vec2(e2.dot(a1), e2.dot(a2));
}

/// Each vertex's distance from the nearest vertex of a gathering elastic edge (ratio < 1),
/// along the mesh's edges (the topology's) in its initial shape (Dijkstra); infinity where none
/// lies within kGatheredBandWidth (the search stops there).
std::vector<Real> distance_from_gathers(const Mesh& m, const std::vector<Eigen::Vector2i>& edges) {
  const int n = static_cast<int>(m.x.size());
  std::vector<Real> dist(n, std::numeric_limits<Real>::infinity());
  using Item = std::pair<Real, int>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> open;
  for (const ElasticEdge& e : m.elastic_edges)
    if (e.ratio < 1)
      for (const int v : {e.a, e.b}) {
        dist[v] = 0;
        open.emplace(0, v);
      }
  if (open.empty()) return dist;
  std::vector<std::vector<int>> adj(n);
  for (const Eigen::Vector2i& e : edges) adj[e[0]].push_back(e[1]), adj[e[1]].push_back(e[0]);
  while (!open.empty()) {
    const auto [d, v] = open.top();
    open.pop();
    if (d > dist[v] || d >= kGatheredBandWidth) continue;
    for (const int w : adj[v]) {
      const Real dw = d + (m.x[w] - m.x[v]).norm();
      if (dw < dist[w]) {
        dist[w] = dw;
        open.emplace(dw, w);
      }
    }
  }
  return dist;
}

/// Key of an undirected edge.
uint64_t edge_key(int a, int b) {
  const auto lo = static_cast<uint64_t>(std::min(a, b)), hi = static_cast<uint64_t>(std::max(a, b));
  return lo << 32 | hi;
}

/// Shrinks (or stretches) a triangle's rest corners along its edge (a, b) by `ratio`, leaving
/// the width across the edge unchanged: p -> p0 + (I + (ratio - 1) d d^T)(p - p0).
void scale_along_edge(const Eigen::Vector3i& tri, int a, int b, Real ratio, Vec2 p[3]) {
  int ia = -1, ib = -1;
  for (int k = 0; k < 3; ++k) {
    if (tri[k] == a) ia = k;
    if (tri[k] == b) ib = k;
  }
  if (ia < 0 || ib < 0) return;
  const Vec2 d = (p[ib] - p[ia]).normalized();
  const Mat2 M = Mat2::Identity() + (ratio - 1) * d * d.transpose();
  const Vec2 o = p[ia];
  for (int k = 0; k < 3; ++k) p[k] = o + M * (p[k] - o);
}

/// Coloring::serial: chunks in mesh order, each preceded (depth first) by the chunks of lower
/// colour it shares a vertex with that have not run yet.
std::vector<int> serial_chunk_order(const Coloring& c, const std::vector<int>& elems, int k, int vertices,
                                    const std::vector<int>& color, const std::vector<int>& slot) {
  const int nc = static_cast<int>(color.size());
  // Chunks at each vertex (CSR), to find a chunk's neighbours.
  std::vector<int> start(static_cast<size_t>(vertices) + 1, 0);
  for (int q = 0; q < nc; ++q)
    for (int e = c.first(q); e < c.last(q); ++e)
      for (int a = 0; a < k; ++a) ++start[elems[k * e + a] + 1];
  for (int v = 0; v < vertices; ++v) start[v + 1] += start[v];
  std::vector<int> at(start.back()), fill(start.begin(), start.end() - 1);
  for (int q = 0; q < nc; ++q)
    for (int e = c.first(q); e < c.last(q); ++e)
      for (int a = 0; a < k; ++a) at[fill[elems[k * e + a]]++] = q;
  std::vector<int> order;
  order.reserve(nc);
  std::vector<char> done(nc, 0);
  // Iterative depth-first walk: a chunk is emitted once every lower-colour neighbour has been.
  std::vector<int> stack;
  for (int root = 0; root < nc; ++root) {
    if (done[root]) continue;
    stack.push_back(root);
    while (!stack.empty()) {
      const int q = stack.back();
      if (done[q]) {
        stack.pop_back();
        continue;
      }
      bool ready = true;
      for (int e = c.first(q); e < c.last(q) && ready; ++e)
        for (int a = 0; a < k && ready; ++a) {
          const int v = elems[k * e + a];
          for (int j = start[v]; j < start[v + 1]; ++j) {
            const int p = at[j];
            if (color[p] < color[q] && !done[p]) {
              stack.push_back(p);  // colours strictly fall along the stack: no cycle
              ready = false;
              break;
            }
          }
        }
      if (!ready) continue;
      done[q] = 1;
      order.push_back(slot[q]);
      stack.pop_back();
    }
  }
  return order;
}

}  // namespace

Coloring color_elements(const std::vector<int>& elems, int k, int vertices, int chunk) {
  GD_DEMAND(chunk >= 1, "colouring chunks need at least one element");
  Coloring out;
  out.elements = static_cast<int>(elems.size()) / k;
  out.chunk = chunk;
  const int nc = (out.elements + chunk - 1) / chunk;
  // Colours in use at each vertex, a bit per colour; more words as colours run out (a mesh in
  // random order makes every chunk meet every other).
  int words = 1;
  std::vector<uint64_t> used(static_cast<size_t>(vertices), 0);
  std::vector<int> color(nc);
  int ncolors = 0;
  for (int q = 0; q < nc; ++q) {
    std::vector<uint64_t> mask(words, 0);
    for (int e = out.first(q); e < out.last(q); ++e)
      for (int a = 0; a < k; ++a)
        for (int w = 0; w < words; ++w) mask[w] |= used[static_cast<size_t>(elems[k * e + a]) * words + w];
    int c = 0;
    while (c < 64 * words && (mask[c / 64] >> (c % 64) & 1u)) ++c;
    if (c == 64 * words) {  // every colour taken here: widen the masks by a word
      std::vector<uint64_t> wider(static_cast<size_t>(vertices) * (words + 1), 0);
      for (size_t v = 0; v < static_cast<size_t>(vertices); ++v)
        std::copy_n(used.begin() + v * words, words, wider.begin() + v * (words + 1));
      used.swap(wider);
      ++words;
    }
    color[q] = c;
    ncolors = std::max(ncolors, c + 1);
    for (int e = out.first(q); e < out.last(q); ++e)
      for (int a = 0; a < k; ++a) used[static_cast<size_t>(elems[k * e + a]) * words + c / 64] |= uint64_t{1} << (c % 64);
  }
  out.offsets.assign(ncolors + 1, 0);
  for (int q = 0; q < nc; ++q) ++out.offsets[color[q] + 1];
  for (int c = 0; c < ncolors; ++c) out.offsets[c + 1] += out.offsets[c];
  out.chunks.resize(nc);
  std::vector<int> fill(out.offsets.begin(), out.offsets.end() - 1);
  std::vector<int> slot(nc);
  for (int q = 0; q < nc; ++q) {
    slot[q] = fill[color[q]];
    out.chunks[fill[color[q]]++] = q;
  }
  out.serial = serial_chunk_order(out, elems, k, vertices, color, slot);
  return out;
}

SceneData build_scene_data(const Mesh& mesh, const Material& mat, const SceneOptions& opt) {
  SceneData d;
  d.n = static_cast<int>(mesh.x.size());
  d.thickness = mat.thickness;
  d.friction = mat.friction;
  d.stiffness_ref = std::max(mat.stretch_warp, mat.stretch_weft);
  d.x.resize(3 * d.n);
  d.v.assign(3 * d.n, 0.0);
  for (int i = 0; i < d.n; ++i)
    for (int c = 0; c < 3; ++c) d.x[3 * i + c] = mesh.x[i][c];

  const bool use_uv = opt.rest_from_uv && has_uv(mesh);
  std::unordered_map<uint64_t, Real> elastic;  // edge -> rest-length ratio
  for (const ElasticEdge& e : mesh.elastic_edges) elastic[edge_key(e.a, e.b)] = e.ratio;
  const int nt = static_cast<int>(mesh.tris.size());
  const Topology topo = build_topology(mesh);
  // The gathered band (kGatheredCompressionRatio, kGatheredBandWidth): each vertex's distance
  // from the gathering elastic edges.
  const std::vector<Real> gather_distance = distance_from_gathers(mesh, topo.edges);
  d.mass.assign(d.n, 0.0);
  d.tris.resize(3 * nt);
  d.tri_rest.resize(nt);
  std::vector<std::array<Vec2, 3>> corners(nt);
  for (int t = 0; t < nt; ++t) {
    const auto& tri = mesh.tris[t];
    Vec2 p[3];
    rest_corners(mesh, t, use_uv, p);
    for (int k = 0; k < 3 && !elastic.empty(); ++k) {
      const auto it = elastic.find(edge_key(tri[k], tri[(k + 1) % 3]));
      if (it != elastic.end()) scale_along_edge(tri, tri[k], tri[(k + 1) % 3], it->second, p);
    }
    corners[t] = {p[0], p[1], p[2]};
    Mat2 Dm;
    Dm.col(0) = p[1] - p[0];
    Dm.col(1) = p[2] - p[0];
    const Real area = 0.5 * std::abs(Dm.determinant());
    GD_DEMAND(area > 0, "degenerate rest triangle passed mesh validation");
    StretchShearRest& r = d.tri_rest[t];
    r.Dm_inv = Dm.inverse();
    r.area = area;
    r.k_warp = mat.stretch_warp;
    r.k_weft = mat.stretch_weft;
    r.k_shear = mat.shear;
    const Real g0 = gather_distance[tri[0]], g1 = gather_distance[tri[1]], g2 = gather_distance[tri[2]];
    const bool gathered = std::min({g0, g1, g2}) == 0 || (g0 + g1 + g2) / 3 < kGatheredBandWidth;
    r.compression_ratio = gathered ? std::min(opt.compression_ratio, kGatheredCompressionRatio) : opt.compression_ratio;
    for (int k = 0; k < 3; ++k) {
      d.tris[3 * t + k] = tri[k];
      d.mass[tri[k]] += mat.density * area / 3.0;
    }
    d.area += area;
  }

  std::unordered_map<uint64_t, Real> creases;  // edge -> bending scale
  for (const Crease& c : mesh.creases) creases[edge_key(c.a, c.b)] = c.bend_scale;
  const int nh = static_cast<int>(topo.hinges.size());
  d.hinges.resize(4 * nh);
  d.hinge_rest.resize(nh);
  d.hinge_wing_area.resize(2 * static_cast<size_t>(nh));
  for (int h = 0; h < nh; ++h) {
    const Eigen::Vector4i& hv = topo.hinges[h];
    for (int k = 0; k < 4; ++k) d.hinges[4 * h + k] = hv[k];
    const int ta = topo.hinge_tris[h][0];
    // Edge direction in pattern space of triangle ta: bending about an edge along the weft
    // curves the warp, so its rigidity is the warp one.
    Vec2 e2d;
    {
      const auto& tri = mesh.tris[ta];
      int i0 = -1, i1 = -1;
      for (int k = 0; k < 3; ++k) {
        if (tri[k] == hv[0]) i0 = k;
        if (tri[k] == hv[1]) i1 = k;
      }
      GD_DEMAND(i0 >= 0 && i1 >= 0, "hinge edge not in its triangle");
      e2d = (corners[ta][i1] - corners[ta][i0]);
    }
    const Vec2 eh = e2d.normalized();
    HingeRest& r = d.hinge_rest[h];
    r.stiffness = mat.bend_warp * eh.y() * eh.y() + mat.bend_weft * eh.x() * eh.x();
    r.friction_moment = mat.bend_friction_warp * eh.y() * eh.y() + mat.bend_friction_weft * eh.x() * eh.x();
    if (!creases.empty()) {
      const auto it = creases.find(edge_key(hv[0], hv[1]));
      if (it != creases.end()) r.stiffness *= it->second, r.friction_moment *= it->second;
    }
    r.friction_stiffness = r.friction_moment > 0 ? r.friction_moment / mat.bend_slip_curvature : 0.0;
    // Curvature scale and area of the hinge from its rest shape (docs/physics.md); with uvs
    // the two wings may come from different panels (a seam), so each wing uses its own corners.
    if (use_uv) {
      const int tb = topo.hinge_tris[h][1];
      const auto area2 = [](const std::array<Vec2, 3>& c) {
        Mat2 D;
        D.col(0) = c[1] - c[0];
        D.col(1) = c[2] - c[0];
        return 0.5 * std::abs(D.determinant());
      };
      d.hinge_wing_area[2 * h] = area2(corners[ta]);
      d.hinge_wing_area[2 * h + 1] = area2(corners[tb]);
      r.coef = hinge_rest_coef(e2d.norm(), d.hinge_wing_area[2 * h], d.hinge_wing_area[2 * h + 1], &r.area);
    } else {
      const Vec3 &X0 = mesh.x[hv[0]], &X1 = mesh.x[hv[1]], &X2 = mesh.x[hv[2]], &X3 = mesh.x[hv[3]];
      d.hinge_wing_area[2 * h] = 0.5 * (X1 - X0).cross(X2 - X0).norm();
      d.hinge_wing_area[2 * h + 1] = 0.5 * (X0 - X1).cross(X3 - X1).norm();
      r.coef = hinge_rest_coef((X1 - X0).norm(), d.hinge_wing_area[2 * h], d.hinge_wing_area[2 * h + 1], &r.area);
    }
    r.kappa_n = mat.bend_kappa_n;
    r.theta0 = use_uv ? 0.0
                      : dihedral_angle(mesh.x[hv[0]], mesh.x[hv[1]], mesh.x[hv[2]], mesh.x[hv[3]]);
  }

  // Block pattern: a vertex couples with every vertex it shares a triangle or hinge with.
  std::vector<std::vector<int>> nbr(d.n);
  auto couple = [&](const int* v, int k) {
    for (int a = 0; a < k; ++a)
      for (int b = 0; b < k; ++b) nbr[v[a]].push_back(v[b]);
  };
  for (int t = 0; t < nt; ++t) couple(&d.tris[3 * t], 3);
  for (int h = 0; h < nh; ++h) couple(&d.hinges[4 * h], 4);
  d.row_ptr.assign(d.n + 1, 0);
  for (int i = 0; i < d.n; ++i) {
    nbr[i].push_back(i);
    std::sort(nbr[i].begin(), nbr[i].end());
    nbr[i].erase(std::unique(nbr[i].begin(), nbr[i].end()), nbr[i].end());
    d.row_ptr[i + 1] = d.row_ptr[i] + static_cast<int>(nbr[i].size());
  }
  d.cols.reserve(d.row_ptr.back());
  for (int i = 0; i < d.n; ++i) d.cols.insert(d.cols.end(), nbr[i].begin(), nbr[i].end());
  auto slot = [&](int i, int j) {
    const auto b = d.cols.begin() + d.row_ptr[i], e = d.cols.begin() + d.row_ptr[i + 1];
    const auto it = std::lower_bound(b, e, j);
    GD_DEMAND(it != e && *it == j, "block missing from the Hessian pattern");
    return static_cast<int>(it - d.cols.begin());
  };
  d.diag.resize(d.n);
  for (int i = 0; i < d.n; ++i) d.diag[i] = slot(i, i);
  d.tri_slots.resize(9 * nt);
  for (int t = 0; t < nt; ++t)
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) d.tri_slots[9 * t + 3 * a + b] = slot(d.tris[3 * t + a], d.tris[3 * t + b]);
  d.hinge_slots.resize(16 * nh);
  for (int h = 0; h < nh; ++h)
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b) d.hinge_slots[16 * h + 4 * a + b] = slot(d.hinges[4 * h + a], d.hinges[4 * h + b]);

  d.tri_colors = color_elements(d.tris, 3, d.n);
  d.hinge_colors = color_elements(d.hinges, 4, d.n);
  gd::log().debug("scene data: {} vertices, {} triangles, {} hinges, {} blocks, {}+{} colours", d.n, nt, nh,
                  d.blocks(), d.tri_colors.colors(), d.hinge_colors.colors());
  return d;
}

}  // namespace gd::sim
