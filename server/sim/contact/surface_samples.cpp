#include "sim/contact/surface_samples.h"

#include <algorithm>
#include <cmath>
#include <unordered_set>

#include <fmt/format.h>

#include "sim/demand.h"

namespace gd::sim {

namespace {
Vec3 at(const std::vector<double>& x, int i) { return Vec3(x[3 * i], x[3 * i + 1], x[3 * i + 2]); }

/// Parts an edge of length len is cut into so its parts are at most `spacing` long.
int parts(double len, double spacing) {
  return std::clamp(static_cast<int>(std::ceil(len / spacing - 1e-9)), 1, kMaxSampleDivisions);
}
}  // namespace

SurfaceSamples sample_surface(const std::vector<double>& x, const std::vector<int>& tris,
                              const std::vector<double>& vertex_mass, double spacing, double wider_than) {
  if (!(spacing > 0) || !std::isfinite(spacing))
    throw InputError(fmt::format("sample spacing must be a positive finite length in m, got {}", spacing));
  if (!(wider_than >= 0) || !std::isfinite(wider_than))
    throw InputError(fmt::format("the width of the triangles to sample must be a finite length >= 0 m, got {}", wider_than));
  const int n = static_cast<int>(x.size() / 3), nt = static_cast<int>(tris.size() / 3);
  if (vertex_mass.size() != static_cast<size_t>(n))
    throw InputError(fmt::format("{} vertex masses for {} vertices", vertex_mass.size(), n));
  for (const double m : vertex_mass)
    if (!(m > 0) || !std::isfinite(m)) throw InputError(fmt::format("a vertex mass must be positive and finite, got {}", m));
  for (const int v : tris)
    if (v < 0 || v >= n) throw InputError(fmt::format("triangle index {} out of range (0..{})", v, n - 1));
  SurfaceSamples s;
  s.spacing = spacing;
  s.tri_ptr.assign(nt + 1, 0);
  std::unordered_set<long long> owned;  // edges whose samples a triangle already took
  auto add = [&](int t, double w0, double w1, double w2, double m) {
    s.tri.push_back(t);
    s.w.insert(s.w.end(), {w0, w1, w2});
    s.mass.push_back(m);
  };
  for (int t = 0; t < nt; ++t) {
    const int* v = tris.data() + 3 * t;
    const Vec3 a = at(x, v[0]), b = at(x, v[1]), c = at(x, v[2]);
    const double len[3] = {(b - a).norm(), (c - b).norm(), (a - c).norm()};
    if (!(std::max({len[0], len[1], len[2]}) > wider_than)) {
      s.tri_ptr[t + 1] = s.size();
      continue;
    }
    const int k = parts(std::max({len[0], len[1], len[2]}), spacing);
    const double m = (vertex_mass[v[0]] + vertex_mass[v[1]] + vertex_mass[v[2]]) / 3;
    for (int i = 1; i < k; ++i)
      for (int j = 1; i + j < k; ++j) add(t, double(k - i - j) / k, double(i) / k, double(j) / k, m);
    for (int e = 0; e < 3; ++e) {  // edge e from v[e] to v[(e + 1) % 3]
      const int p = v[e], q = v[(e + 1) % 3];
      const long long key = static_cast<long long>(std::min(p, q)) * n + std::max(p, q);
      if (!owned.insert(key).second) continue;
      const int ke = parts(len[e], spacing);
      for (int j = 1; j < ke; ++j) {
        double w[3] = {0, 0, 0};
        w[e] = double(ke - j) / ke;
        w[(e + 1) % 3] = double(j) / ke;
        add(t, w[0], w[1], w[2], m);
      }
    }
    s.tri_ptr[t + 1] = s.size();
  }
  return s;
}

}  // namespace gd::sim
