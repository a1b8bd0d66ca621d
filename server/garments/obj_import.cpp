#include "garments/obj_import.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "sim/demand.h"
#include "sim/log.h"

namespace gd::garments {
namespace {

using sim::InputError;

/// Best uniform scale of the uvs onto the 3D edge lengths and the RMS relative mismatch after it.
std::pair<Real, Real> uv_fit(const sim::Mesh& m) {
  Real num = 0, den = 0;
  std::vector<std::pair<Real, Real>> lens;
  lens.reserve(3 * m.tris.size());
  for (int t = 0; t < int(m.tris.size()); ++t)
    for (int k = 0; k < 3; ++k) {
      const Real l3 = (m.x[m.tris[t][k]] - m.x[m.tris[t][(k + 1) % 3]]).norm();
      const Real l2 = (sim::corner_uv(m, t, k) - sim::corner_uv(m, t, (k + 1) % 3)).norm();
      num += l2 * l3, den += l2 * l2;
      lens.emplace_back(l2, l3);
    }
  if (!(den > 0)) return {0, 1e30};
  const Real s = num / den;
  Real e = 0;
  for (const auto& [l2, l3] : lens) e += std::pow(s * l2 / std::max(l3, Real(1e-300)) - 1, 2);
  return {s, std::sqrt(e / lens.size())};
}

const char* mode_name(UvMode m) {
  switch (m) {
    case UvMode::kAuto: return "auto";
    case UvMode::kKeep: return "kept as metres";
    case UvMode::kRescale: return "rescaled";
    case UvMode::kDrop: return "dropped";
  }
  return "?";
}

}  // namespace

Garment load_garment_obj(const std::string& path, const ObjImportOptions& opt, UvReport* report) {
  Garment g;
  g.type = "mesh";
  sim::Mesh& m = g.mesh;
  m = sim::read_obj(path);
  const int nv = int(m.x.size());
  if (m.tris.empty()) {
    throw InputError(fmt::format("OBJ file '{}' has no faces ({} vertices); a garment needs triangles or polygons (f lines)",
                                 path, nv));
  }
  std::vector<char> used(nv, 0);
  for (const Eigen::Vector3i& f : m.tris)
    for (int k = 0; k < 3; ++k) used[f[k]] = 1;
  const auto unused = std::find(used.begin(), used.end(), 0);
  if (unused != used.end())
    throw InputError(fmt::format("OBJ file '{}': vertex {} (1-based) is used by no face; remove unused vertices",
                                 path, unused - used.begin() + 1));

  UvReport rep;
  rep.present = sim::has_uv(m);
  // Validate the geometry first (without uvs), so a broken mesh is reported as such.
  {
    sim::Mesh geo;
    geo.x = m.x;
    geo.tris = m.tris;
    try {
      sim::validate_mesh(geo);
    } catch (const InputError& e) {
      throw InputError(fmt::format("OBJ file '{}': {}", path, e.what()));
    }
  }
  if (rep.present) {
    std::tie(rep.scale, rep.distortion) = uv_fit(m);
    UvMode use = opt.uv_mode;
    if (use == UvMode::kAuto) {
      use = rep.distortion > opt.max_uv_distortion        ? UvMode::kDrop
            : std::abs(rep.scale - 1) <= opt.keep_scale_tolerance ? UvMode::kKeep
                                                                  : UvMode::kRescale;
    }
    if (use == UvMode::kRescale)
      for (Vec2& u : m.uv) u *= rep.scale;
    if (use == UvMode::kDrop) m.uv.clear(), m.uv_tris.clear();
    if (use != UvMode::kDrop) {
      try {
        sim::validate_mesh(m);
      } catch (const InputError& e) {
        throw InputError(fmt::format("OBJ file '{}': {} (load with UvMode::kDrop to ignore its uvs)", path, e.what()));
      }
    }
    rep.used = use;
    gd::log().info("OBJ '{}': uvs {} (best scale {:.4g}, edge-length mismatch {:.3g} after scaling)", path,
                   mode_name(use), rep.scale, rep.distortion);
  } else {
    m.uv.clear();
    gd::log().info("OBJ '{}': no uvs on every face corner; the rest shape is the 3D shape", path);
  }
  if (report) *report = rep;

  // Orientation consistency (the simulator copes, but say so).
  std::map<std::pair<int, int>, int> directed;
  int flipped = 0;
  for (const Eigen::Vector3i& f : m.tris)
    for (int k = 0; k < 3; ++k)
      if (++directed[{f[k], f[(k + 1) % 3]}] > 1) ++flipped;
  if (flipped) gd::log().warn("OBJ '{}': {} edges have inconsistently oriented triangles", path, flipped);

  // Frame-derived quantities and landmarks.
  Vec3 lo = m.x[0], hi = m.x[0];
  for (const Vec3& p : m.x) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  g.length = hi.x() - lo.x();
  g.width = hi.y() - lo.y();
  g.spacing = sim::mean_edge_length(m);
  const Real ymid = 0.5 * (lo.y() + hi.y());
  auto nearest = [&](const Vec3& q) {
    int best = 0;
    for (int i = 1; i < nv; ++i)
      if ((m.x[i] - q).squaredNorm() < (m.x[best] - q).squaredNorm()) best = i;
    return best;
  };
  Landmarks& lm = g.landmarks;
  const Real xs = lo.x() + 0.05 * g.length;
  lm.left_shoulder_vertex = nearest(Vec3(xs, ymid + 0.25 * g.width, hi.z()));
  lm.right_shoulder_vertex = nearest(Vec3(xs, ymid - 0.25 * g.width, hi.z()));
  lm.left_shoulder = m.x[lm.left_shoulder_vertex];
  lm.right_shoulder = m.x[lm.right_shoulder_vertex];
  int lh = -1, rh = -1;
  for (int i = 0; i < nv; ++i) {
    if (m.x[i].x() < hi.x() - 0.05 * g.length) continue;
    if (lh < 0 || m.x[i].y() > m.x[lh].y()) lh = i;
    if (rh < 0 || m.x[i].y() < m.x[rh].y()) rh = i;
  }
  lm.left_hem = m.x[lh];
  lm.right_hem = m.x[rh];
  return g;
}

}  // namespace gd::garments
