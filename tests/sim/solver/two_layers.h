// Shared by the pinch tests: two layers of cloth hanging side by side (a fold held between
// gripper pads), and the scene options they run with.
#pragma once

#include "sim/mesh.h"
#include "sim/scene.h"

namespace gd::sim::testing_layers {

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
