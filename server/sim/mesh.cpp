#include "sim/mesh.h"

#include <spdlog/fmt/fmt.h>
#include <tiny_obj_loader.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <string_view>
#include <tuple>

#include "sim/demand.h"
#include "sim/log.h"

namespace gd::sim {
namespace {

/// One triangle side, keyed by its sorted vertex pair so that sorting groups shared edges.
struct HalfEdge {
  int lo, hi;  // sorted endpoints (the key)
  int a, b;    // direction in the triangle's winding
  int tri, opp;
  auto key() const { return std::tie(lo, hi, tri); }
};

std::vector<HalfEdge> sorted_half_edges(const Mesh& m) {
  std::vector<HalfEdge> h;
  h.reserve(3 * m.tris.size());
  for (int t = 0; t < int(m.tris.size()); ++t) {
    for (int k = 0; k < 3; ++k) {
      const int a = m.tris[t][k], b = m.tris[t][(k + 1) % 3], opp = m.tris[t][(k + 2) % 3];
      h.push_back({std::min(a, b), std::max(a, b), a, b, t, opp});
    }
  }
  std::sort(h.begin(), h.end(),
            [](const HalfEdge& p, const HalfEdge& q) { return p.key() < q.key(); });
  return h;
}

/// Calls f(first, last) for each run of half-edges sharing one undirected edge.
template <class F>
void for_each_edge(const std::vector<HalfEdge>& h, F&& f) {
  for (size_t i = 0; i < h.size();) {
    size_t j = i + 1;
    while (j < h.size() && h[j].lo == h[i].lo && h[j].hi == h[i].hi) ++j;
    f(i, j);
    i = j;
  }
}

template <class V>
Real tri_area(const V& a, const V& b, const V& c) {
  if constexpr (V::RowsAtCompileTime == 2) {
    const V u = b - a, v = c - a;
    return 0.5 * std::abs(u.x() * v.y() - u.y() * v.x());
  } else {
    return 0.5 * (b - a).cross(c - a).norm();
  }
}

void throw_if_non_manifold(const std::vector<HalfEdge>& h) {
  for_each_edge(h, [&](size_t i, size_t j) {
    if (j - i <= 2) return;
    std::string tris;
    for (size_t k = i; k < j; ++k) tris += fmt::format("{}{}", k > i ? ", " : "", h[k].tri);
    throw InputError(fmt::format(
        "non-manifold edge between vertices {} and {}: shared by {} triangles ({}); an edge may "
        "belong to at most 2",
        h[i].lo, h[i].hi, j - i, tris));
  });
}

/// Triangulates the strip between two vertex rows, adding at each step the shorter of the two
/// candidate diagonals. Seen from +z (or the front), `lo` runs left to right with `up` on its
/// left-hand side, so every triangle comes out counter-clockwise. `closed` rows wrap around.
void zip_rows(const std::vector<Vec3>& x, const std::vector<int>& lo, const std::vector<int>& up,
              bool closed, std::vector<Eigen::Vector3i>& tris) {
  const size_t nl = closed ? lo.size() : lo.size() - 1, nu = closed ? up.size() : up.size() - 1;
  auto L = [&](size_t i) { return lo[i % lo.size()]; };
  auto U = [&](size_t k) { return up[k % up.size()]; };
  size_t i = 0, k = 0;
  while (i < nl || k < nu) {
    const bool advance_lo = k == nu || (i < nl && (x[L(i + 1)] - x[U(k)]).squaredNorm() <=
                                                      (x[L(i)] - x[U(k + 1)]).squaredNorm());
    if (advance_lo) {
      tris.emplace_back(L(i), L(i + 1), U(k));
      ++i;
    } else {
      tris.emplace_back(L(i), U(k + 1), U(k));
      ++k;
    }
  }
}

void set_planar_uv(Mesh& m) {
  m.uv.resize(m.x.size());
  for (size_t i = 0; i < m.x.size(); ++i) m.uv[i] = m.x[i].head<2>();
}

void require_positive(Real v, const char* what, const char* fn) {
  if (!(std::isfinite(v) && v > 0))
    throw InputError(fmt::format("{}: {} must be positive and finite (got {})", fn, what, v));
}

}  // namespace

void validate_mesh(const Mesh& m) {
  const int nv = int(m.x.size());
  if (m.x.empty()) throw InputError("mesh has no vertices");
  if (m.tris.empty()) throw InputError("mesh has no triangles");
  for (int i = 0; i < nv; ++i) {
    if (!m.x[i].allFinite())
      throw InputError(fmt::format("vertex {} has a non-finite position ({}, {}, {})", i,
                                   m.x[i].x(), m.x[i].y(), m.x[i].z()));
  }
  const bool has_uv = !m.uv.empty();
  const bool indexed_uv = !m.uv_tris.empty();
  if (indexed_uv && !has_uv) throw InputError("mesh has uv_tris but no uvs; give both or neither");
  if (has_uv && !indexed_uv && int(m.uv.size()) != nv)
    throw InputError(fmt::format(
        "mesh has {} uvs but {} vertices; give one uv per vertex, uv indices per triangle, or none",
        m.uv.size(), nv));
  if (indexed_uv && m.uv_tris.size() != m.tris.size())
    throw InputError(fmt::format("mesh has {} uv triangles but {} triangles; give one per triangle",
                                 m.uv_tris.size(), m.tris.size()));
  for (size_t t = 0; t < m.uv_tris.size(); ++t)
    for (int k = 0; k < 3; ++k)
      if (m.uv_tris[t][k] < 0 || m.uv_tris[t][k] >= int(m.uv.size()))
        throw InputError(fmt::format("uv triangle {} references uv {}, but the mesh has {} uvs", t,
                                     m.uv_tris[t][k], m.uv.size()));
  for (size_t i = 0; i < m.uv.size(); ++i) {
    if (!m.uv[i].allFinite())
      throw InputError(
          fmt::format("uv {} is non-finite ({}, {})", i, m.uv[i].x(), m.uv[i].y()));
  }
  for (size_t t = 0; t < m.tris.size(); ++t) {
    const Eigen::Vector3i& f = m.tris[t];
    for (int k = 0; k < 3; ++k) {
      if (f[k] < 0 || f[k] >= nv)
        throw InputError(fmt::format(
            "triangle {} references vertex {}, but the mesh has {} vertices (indices are 0-based)",
            t, f[k], nv));
    }
    if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2])
      throw InputError(fmt::format("triangle {} ({}, {}, {}) is degenerate: it repeats a vertex", t,
                                   f[0], f[1], f[2]));
  }

  // Scale.
  Vec3 lo = m.x[0], hi = m.x[0];
  for (const Vec3& p : m.x) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  const Real diag = (hi - lo).norm();
  if (diag > 100)
    throw InputError(fmt::format(
        "mesh bounding-box diagonal is {:.4g} m (> 100 m); positions must be in metres (is the "
        "mesh in millimetres or centimetres?)",
        diag));
  const std::vector<HalfEdge> h = sorted_half_edges(m);
  Real len3 = 0, len2 = 0;
  int n_edges = 0;
  for_each_edge(h, [&](size_t i, size_t) {
    len3 += (m.x[h[i].lo] - m.x[h[i].hi]).norm();
    ++n_edges;
  });
  if (has_uv) {
    for (size_t t = 0; t < m.tris.size(); ++t)
      for (int k = 0; k < 3; ++k)
        len2 += (corner_uv(m, int(t), k) - corner_uv(m, int(t), (k + 1) % 3)).norm();
    len2 *= Real(n_edges) / (3.0 * m.tris.size());
  }
  const Real mean3 = len3 / n_edges, mean2 = len2 / n_edges;
  if (mean3 < 1e-5)
    throw InputError(fmt::format(
        "mean edge length is {:.4g} m (< 1e-5 m); positions must be in metres (is the mesh in "
        "kilometres, or collapsed?)",
        mean3));

  // Degenerate triangles.
  constexpr Real kAbsArea = 1e-12, kRelArea = 1e-6;
  const Real min3 = std::max(kAbsArea, kRelArea * mean3 * mean3);
  const Real min2 = std::max(kAbsArea, kRelArea * mean2 * mean2);
  for (size_t t = 0; t < m.tris.size(); ++t) {
    const Eigen::Vector3i& f = m.tris[t];
    const Real a3 = tri_area(m.x[f[0]], m.x[f[1]], m.x[f[2]]);
    if (a3 < min3)
      throw InputError(fmt::format(
          "triangle {} ({}, {}, {}) is degenerate: 3D area {:.3g} m² is below {:.3g} m²", t, f[0],
          f[1], f[2], a3, min3));
    if (!has_uv) continue;
    const Real a2 = tri_area(corner_uv(m, int(t), 0), corner_uv(m, int(t), 1), corner_uv(m, int(t), 2));
    if (a2 < min2)
      throw InputError(fmt::format(
          "triangle {} ({}, {}, {}) is degenerate in uv: uv area {:.3g} m² is below {:.3g} m²", t,
          f[0], f[1], f[2], a2, min2));
  }

  // Duplicate triangles (same vertex set, any order or orientation).
  std::vector<std::pair<Eigen::Vector3i, int>> sorted(m.tris.size());
  for (size_t t = 0; t < m.tris.size(); ++t) {
    Eigen::Vector3i f = m.tris[t];
    std::sort(f.data(), f.data() + 3);
    sorted[t] = {f, int(t)};
  }
  auto as_tuple = [](const std::pair<Eigen::Vector3i, int>& p) {
    return std::tie(p.first[0], p.first[1], p.first[2], p.second);
  };
  std::sort(sorted.begin(), sorted.end(),
            [&](const auto& p, const auto& q) { return as_tuple(p) < as_tuple(q); });
  for (size_t i = 1; i < sorted.size(); ++i) {
    if (sorted[i].first == sorted[i - 1].first)
      throw InputError(fmt::format("triangles {} and {} use the same vertices ({}, {}, {})",
                                   sorted[i - 1].second, sorted[i].second, sorted[i].first[0],
                                   sorted[i].first[1], sorted[i].first[2]));
  }

  throw_if_non_manifold(h);

  // Feature edges must be edges of the mesh.
  auto is_edge = [&](int a, int b) {
    const int lo = std::min(a, b), hi = std::max(a, b);
    const auto it = std::lower_bound(h.begin(), h.end(), std::make_pair(lo, hi), [](const HalfEdge& e, const std::pair<int, int>& k) {
      return std::make_pair(e.lo, e.hi) < k;
    });
    return it != h.end() && it->lo == lo && it->hi == hi;
  };
  for (size_t i = 0; i < m.creases.size(); ++i) {
    const Crease& c = m.creases[i];
    if (c.a < 0 || c.b < 0 || c.a >= nv || c.b >= nv || !is_edge(c.a, c.b))
      throw InputError(fmt::format("crease {} ({}, {}) is not an edge of the mesh", i, c.a, c.b));
    if (!(std::isfinite(c.bend_scale) && c.bend_scale >= 0 && c.bend_scale <= 100))
      throw InputError(fmt::format("crease {} has bend_scale {}; use a value in [0, 100]", i, c.bend_scale));
  }
  for (size_t i = 0; i < m.elastic_edges.size(); ++i) {
    const ElasticEdge& e = m.elastic_edges[i];
    if (e.a < 0 || e.b < 0 || e.a >= nv || e.b >= nv || !is_edge(e.a, e.b))
      throw InputError(fmt::format("elastic edge {} ({}, {}) is not an edge of the mesh", i, e.a, e.b));
    if (!(std::isfinite(e.ratio) && e.ratio > 0.1 && e.ratio <= 2))
      throw InputError(fmt::format("elastic edge {} has rest-length ratio {}; use a value in (0.1, 2]", i, e.ratio));
  }
}

Topology build_topology(const Mesh& m) {
  const std::vector<HalfEdge> h = sorted_half_edges(m);
  throw_if_non_manifold(h);
  Topology top;
  std::vector<int> boundary;
  int inconsistent = 0;
  for_each_edge(h, [&](size_t i, size_t j) {
    top.edges.emplace_back(h[i].lo, h[i].hi);
    if (j - i == 1) {
      boundary.push_back(h[i].lo);
      boundary.push_back(h[i].hi);
      return;
    }
    const HalfEdge &e = h[i], &f = h[i + 1];  // e has the lower triangle index
    if (e.a == f.a) ++inconsistent;
    top.hinges.emplace_back(e.a, e.b, e.opp, f.opp);
    top.hinge_tris.emplace_back(e.tri, f.tri);
  });
  if (inconsistent > 0)
    gd::log().warn(
        "build_topology: {} interior edge(s) join inconsistently oriented triangles; fix the "
        "winding (hinges follow the lower-numbered triangle)",
        inconsistent);
  std::sort(boundary.begin(), boundary.end());
  boundary.erase(std::unique(boundary.begin(), boundary.end()), boundary.end());
  top.boundary_vertices = std::move(boundary);
  return top;
}

Mesh make_rect(Real size_x, Real size_y, Real spacing) {
  require_positive(size_x, "size_x", "make_rect");
  require_positive(size_y, "size_y", "make_rect");
  require_positive(spacing, "spacing", "make_rect");
  const int nx = std::max(1L, std::lround(size_x / spacing));
  const Real dx = size_x / nx;
  // Rows ideally dx·√3/2 apart. The boundary triangles are right triangles with legs dx and dy,
  // so their smallest angle is atan(min(r, 1/r)), r = dy/dx; if rounding the row count pushes
  // that below 40°, take the other neighbouring count when it is better.
  const Real n_rows = size_y / (dx * std::numbers::sqrt3 / 2);
  auto quality = [&](long n) {
    const Real r = size_y / n / dx;
    return std::min(r, 1 / r);
  };
  long ny = std::max(1L, std::lround(n_rows));
  const long other = std::max(1L, ny > n_rows ? ny - 1 : ny + 1);
  if (quality(ny) < std::tan(40 * std::numbers::pi / 180) && quality(other) > quality(ny))
    ny = other;
  const Real dy = size_y / ny;

  Mesh m;
  std::vector<std::vector<int>> rows(ny + 1);
  auto add = [&](std::vector<int>& row, Real x, Real y) {
    row.push_back(int(m.x.size()));
    m.x.emplace_back(x, y, 0);
  };
  for (int j = 0; j <= ny; ++j) {
    const Real y = j == ny ? size_y : j * dy;
    add(rows[j], 0, y);
    if (j % 2 == 0) {
      for (int i = 1; i < nx; ++i) add(rows[j], i * dx, y);
    } else {  // shifted by half a spacing; the half-cells at both ends are snapped to the edges
      for (int i = 1; i + 1 < nx; ++i) add(rows[j], (i + 0.5) * dx, y);
    }
    add(rows[j], size_x, y);
  }
  for (int j = 0; j < ny; ++j) zip_rows(m.x, rows[j], rows[j + 1], false, m.tris);
  set_planar_uv(m);
  return m;
}

Mesh make_disc(Real radius, Real spacing) {
  require_positive(radius, "radius", "make_disc");
  require_positive(spacing, "spacing", "make_disc");
  const int n_rings = std::max(1L, std::lround(radius / spacing));
  const Real dr = radius / n_rings;
  Mesh m;
  m.x.emplace_back(0, 0, 0);
  std::vector<int> inner = {0}, outer;
  for (int k = 1; k <= n_rings; ++k) {
    const Real r = k == n_rings ? radius : k * dr;
    outer.clear();
    for (int j = 0; j < 6 * k; ++j) {
      const Real phi = 2 * std::numbers::pi * j / (6 * k);
      outer.push_back(int(m.x.size()));
      m.x.emplace_back(r * std::cos(phi), r * std::sin(phi), 0);
    }
    if (k == 1) {
      for (int j = 0; j < 6; ++j) m.tris.emplace_back(0, outer[j], outer[(j + 1) % 6]);
    } else {
      zip_rows(m.x, outer, inner, true, m.tris);  // outer ring runs counter-clockwise
    }
    std::swap(inner, outer);
  }
  set_planar_uv(m);
  return m;
}

int nearest_vertex(const Mesh& m, const Vec3& p) {
  GD_DEMAND(!m.x.empty(), "nearest_vertex on an empty mesh");
  int best = 0;
  for (int i = 1; i < int(m.x.size()); ++i) {
    if ((m.x[i] - p).squaredNorm() < (m.x[best] - p).squaredNorm()) best = i;
  }
  return best;
}

std::vector<int> vertices_where(const Mesh& m, const std::function<bool(const Vec3&)>& pred) {
  std::vector<int> out;
  for (int i = 0; i < int(m.x.size()); ++i) {
    if (pred(m.x[i])) out.push_back(i);
  }
  return out;
}

Real mesh_area(const Mesh& m) {
  Real a = 0;
  for (const auto& f : m.tris) a += tri_area(m.x[f[0]], m.x[f[1]], m.x[f[2]]);
  return a;
}

Real mean_edge_length(const Mesh& m) {
  const std::vector<HalfEdge> h = sorted_half_edges(m);
  Real len = 0;
  int n = 0;
  for_each_edge(h, [&](size_t i, size_t) {
    len += (m.x[h[i].lo] - m.x[h[i].hi]).norm();
    ++n;
  });
  return n > 0 ? len / n : 0;
}

void write_obj(const Mesh& m, const std::vector<Vec3>& positions, const std::string& path) {
  const std::vector<Vec3>& x = positions.empty() ? m.x : positions;
  if (x.size() != m.x.size())
    throw InputError(fmt::format("write_obj: {} positions given for a mesh of {} vertices",
                                 x.size(), m.x.size()));
  std::ofstream out(path);
  if (!out) throw InputError(fmt::format("cannot open '{}' for writing", path));
  const bool uv = !m.uv.empty();
  for (const Vec3& p : x) out << fmt::format("v {} {} {}\n", p.x(), p.y(), p.z());
  for (const Vec2& t : m.uv) out << fmt::format("vt {} {}\n", t.x(), t.y());
  for (size_t t = 0; t < m.tris.size(); ++t) {
    const auto& f = m.tris[t];
    if (uv) {
      const Eigen::Vector3i u = m.uv_tris.empty() ? f : m.uv_tris[t];
      out << fmt::format("f {}/{} {}/{} {}/{}\n", f[0] + 1, u[0] + 1, f[1] + 1, u[1] + 1, f[2] + 1, u[2] + 1);
    } else
      out << fmt::format("f {} {} {}\n", f[0] + 1, f[1] + 1, f[2] + 1);
  }
  out.close();
  if (!out) throw InputError(fmt::format("failed to write '{}' (disk full?)", path));
}

namespace {

/// tinyobjloader reads a number it cannot parse ("nan", "inf", "abc") as 0 and a missing
/// coordinate as 0: checks every `v` and `vt` line first, so that such a file is refused with
/// the line, instead of becoming a mesh with vertices at the origin.
void check_obj_numbers(const std::string& path, const std::string& text) {
  size_t line_no = 0, pos = 0;
  while (pos < text.size()) {
    const size_t end = std::min(text.find('\n', pos), text.size());
    std::string_view line(text.data() + pos, end - pos);
    pos = end + 1;
    ++line_no;
    size_t k = 0;
    auto next_token = [&]() -> std::string_view {
      while (k < line.size() && (line[k] == ' ' || line[k] == '\t' || line[k] == '\r')) ++k;
      const size_t b = k;
      while (k < line.size() && line[k] != ' ' && line[k] != '\t' && line[k] != '\r') ++k;
      return line.substr(b, k - b);
    };
    const std::string_view key = next_token();
    const int need = key == "v" ? 3 : key == "vt" ? 2 : 0;  // positions; pattern uvs
    if (need == 0) continue;
    int count = 0;
    for (std::string_view tok = next_token(); !tok.empty() && tok[0] != '#'; tok = next_token()) {
      const std::string t(tok);
      char* stop = nullptr;
      const double value = std::strtod(t.c_str(), &stop);
      if (stop != t.c_str() + t.size() || !std::isfinite(value))
        throw InputError(fmt::format("OBJ file '{}': line {}: '{}' in a '{}' line is not a finite number", path, line_no,
                                     t, key));
      ++count;
    }
    if (count < need)
      throw InputError(fmt::format("OBJ file '{}': line {}: a '{}' line needs {} numbers, it has {}", path, line_no, key,
                                   need, count));
  }
}

}  // namespace

Mesh read_obj(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw InputError(fmt::format("OBJ file '{}' does not exist", path));
  if (!std::filesystem::is_regular_file(path, ec))
    throw InputError(fmt::format("OBJ file '{}' is not a regular file", path));
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("OBJ file '{}' cannot be opened", path));
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  check_obj_numbers(path, text);
  tinyobj::ObjReaderConfig cfg;
  cfg.triangulate = false;  // fanned below, so triangles keep the file's corner order
  cfg.vertex_color = false;
  tinyobj::ObjReader reader;
  // Parsed from memory with an empty material text: an `mtllib` line opens no file (the
  // simulator uses no materials; a server must not follow a path a request names).
  if (!reader.ParseFromString(text, std::string(), cfg)) {
    std::string why = reader.Error();
    while (!why.empty() && (why.back() == '\n' || why.back() == '\r')) why.pop_back();
    throw InputError(fmt::format("OBJ file '{}' could not be parsed: {}", path, why.empty() ? "unknown error" : why));
  }
  if (!reader.Warning().empty()) gd::log().debug("OBJ '{}': {}", path, reader.Warning());
  const tinyobj::attrib_t& at = reader.GetAttrib();
  Mesh m;
  const int nv = int(at.vertices.size() / 3), nvt = int(at.texcoords.size() / 2);
  m.x.reserve(nv);
  for (int i = 0; i < nv; ++i) m.x.emplace_back(at.vertices[3 * i], at.vertices[3 * i + 1], at.vertices[3 * i + 2]);
  std::vector<Eigen::Vector3i> uv_tris;
  std::vector<int> vt_of(nv, -1);  // per vertex: the vt its corners use, -1 if none seen yet
  bool every_corner_uv = true, seams = false;
  int face_no = 0;
  for (const tinyobj::shape_t& sh : reader.GetShapes()) {
    size_t off = 0;
    for (const unsigned n : sh.mesh.num_face_vertices) {
      ++face_no;
      if (n < 3) {  // tinyobjloader drops these itself; skip them too should a version keep them
        off += n;
        continue;
      }
      std::vector<int> v(n), vt(n);
      for (unsigned k = 0; k < n; ++k) {
        const tinyobj::index_t& idx = sh.mesh.indices[off + k];
        // (tinyobjloader has already turned a negative index, which counts back from the vertices
        // read so far, into an absolute one: the file's own number is not known here.)
        if (idx.vertex_index < 0)
          throw InputError(fmt::format("OBJ file '{}': face {} uses a vertex before the first one (a negative index "
                                       "counts back from the vertices above its line; the file has {} vertices)",
                                       path, face_no, nv));
        if (idx.vertex_index >= nv)
          throw InputError(fmt::format("OBJ file '{}': face {} uses vertex {}, out of range (the file has {} vertices)",
                                       path, face_no, idx.vertex_index + 1, nv));
        v[k] = idx.vertex_index;
        vt[k] = idx.texcoord_index;
        if (vt[k] < 0 || vt[k] >= nvt) {
          every_corner_uv = false;
          continue;
        }
        int& seen = vt_of[v[k]];
        if (seen < 0)
          seen = vt[k];
        else if (seen != vt[k] && (at.texcoords[2 * seen] != at.texcoords[2 * vt[k]] ||
                                   at.texcoords[2 * seen + 1] != at.texcoords[2 * vt[k] + 1]))
          seams = true;  // this vertex has two different uvs: keep uvs per corner
      }
      off += n;
      for (unsigned k = 1; k + 1 < n; ++k) {
        m.tris.emplace_back(v[0], v[k], v[k + 1]);
        uv_tris.emplace_back(vt[0], vt[k], vt[k + 1]);
      }
    }
  }
  if (!every_corner_uv || m.tris.empty()) return m;
  auto vt_uv = [&](int t) { return Vec2(at.texcoords[2 * t], at.texcoords[2 * t + 1]); };
  if (seams) {
    for (int t = 0; t < nvt; ++t) m.uv.push_back(vt_uv(t));
    m.uv_tris = std::move(uv_tris);
  } else if (std::none_of(vt_of.begin(), vt_of.end(), [](int t) { return t < 0; })) {
    for (int i = 0; i < nv; ++i) m.uv.push_back(vt_uv(vt_of[i]));
  }
  return m;
}

}  // namespace gd::sim
