// Shared by the pinch tests: two layers of cloth hanging side by side (a fold held between
// gripper pads), and the scene options they run with.
#pragma once

#include <algorithm>

#include "sim/mesh.h"
#include "sim/scene.h"

namespace gd::sim::testing_layers {

/// A pad's pose over one step: from `from` (where it got to) to `to` (its target), linear (a
/// yielding pad's owner starts each step where the pad got to: Scene::collider_reached).
struct PadMotion {
  double t0 = 0, t1 = 0;
  Vec3 from = Vec3::Zero(), to = Vec3::Zero();
  Eigen::Isometry3d at(double t) const {
    const double u = t1 > t0 ? std::clamp((t - t0) / (t1 - t0), 0.0, 1.0) : 1.0;
    return Eigen::Isometry3d(Eigen::Translation3d((1 - u) * from + u * to));
  }
};

/// Options of the pinch scenes: 5 ms steps, self-contact on, no table, no air.
inline SceneOptions pinch_options() {
  SceneOptions o;
  o.dt = 1.0 / 200;
  o.table = false;
  o.air_density = 0;
  o.self_contact = true;
  return o;
}

/// Two copies of a W x L rectangle (4 mm edges) turned into the xz plane, hanging from
/// z = z0 + L down to z0, the first at y = +gap/2 and the second at y = -gap/2.
inline Mesh two_hanging_layers(double W, double L, double gap, double z0 = 0.5) {
  const Mesh layer = make_rect(W, L, 0.004);
  Mesh mesh = layer;
  const int n = static_cast<int>(layer.x.size());
  mesh.x.insert(mesh.x.end(), layer.x.begin(), layer.x.end());
  mesh.uv.insert(mesh.uv.end(), layer.uv.begin(), layer.uv.end());
  for (const Eigen::Vector3i& t : layer.tris) mesh.tris.push_back(t + Eigen::Vector3i::Constant(n));
  for (int i = 0; i < 2 * n; ++i) {
    const Vec3 p = mesh.x[i];
    mesh.x[i] = Vec3(p.x(), i < n ? 0.5 * gap : -0.5 * gap, z0 + p.y());
  }
  return mesh;
}

}  // namespace gd::sim::testing_layers
