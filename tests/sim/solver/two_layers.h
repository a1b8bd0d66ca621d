// Shared by the pinch tests: two layers of cloth hanging side by side (a fold held between
// gripper pads), and the scene options they run with.
#pragma once

#include <algorithm>
#include <memory>
#include <utility>
#include <vector>

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
  /// The coming step, from `now` to now + dt: from where the last one got to (the fraction
  /// `reached` of its motion: Scene::collider_reached) to `target`.
  void next(double reached, double now, double dt, const Vec3& target) {
    from = at(t0 + reached * (t1 - t0)).translation();
    t0 = now;
    t1 = now + dt;
    to = target;
  }
};

/// Box pads of half extents `half` at `at` (one per entry), moved by PadMotion: each step from
/// where it got to (Scene::collider_reached) towards its target. `group`: one yield group (a hand).
struct Pads {
  std::vector<int> ids;
  std::vector<std::shared_ptr<PadMotion>> motion;
  Pads(Scene& scene, const std::vector<Vec3>& at, const Vec3& half, bool yielding, bool group, double friction) {
    for (const Vec3& p : at) {
      auto m = std::make_shared<PadMotion>();
      m->from = m->to = p;
      Collider pad = Collider::box(half);
      pad.set_pose([m](double t) { return m->at(t); });
      pad.set_yielding(yielding);
      if (group) pad.set_yield_group(0);
      pad.set_friction(friction);
      pad.set_stiffness_scale(20);  // a squeeze of ~20 times the weight under a pad, as robot mode sets it
      ids.push_back(scene.add_collider(pad));
      motion.push_back(m);
    }
  }
  /// Sets up the coming step: pad k from where it got to towards target(k, t1), a Vec3 (declare a
  /// lambda's `-> Vec3`: an Eigen sum returned as auto refers to temporaries that are gone).
  template <class Target>
  void advance(const Scene& scene, double dt, Target target) {
    const std::vector<double> reached = scene.collider_reached(ids);
    for (size_t k = 0; k < ids.size(); ++k) motion[k]->next(reached[k], scene.time(), dt, target(k, scene.time() + dt));
  }
};

/// The squeeze scenes' pads (yielding_collider_test, pads_in_solve_test): two boxes of half extents
/// (W, thick, grip/2) across the layers at height z, the -y one still centred at
/// y = -y_start, the +y one moved by `moving`; added in that order. `still_yields`: the still pad
/// yields too; `group`: both are one hand (a yield group). Returns {still id, moving id}.
inline std::pair<int, int> add_squeeze_pads(Scene& scene, const std::shared_ptr<PadMotion>& moving, double W,
                                            double thick, double grip, double y_start, double z, bool moving_yields,
                                            bool still_yields, bool group, double friction) {
  std::pair<int, int> ids{-1, -1};
  for (const double side : {-1.0, 1.0}) {
    Collider pad = Collider::box(Vec3(W, thick, 0.5 * grip));
    if (side > 0) {
      pad.set_pose([moving](double t) { return moving->at(t); });
      pad.set_yielding(moving_yields);
    } else {
      pad.set_pose([=](double) { return Eigen::Isometry3d(Eigen::Translation3d(0.5 * W, -y_start, z)); });
      pad.set_yielding(still_yields);
    }
    if (group) pad.set_yield_group(0);
    pad.set_friction(friction);
    pad.set_stiffness_scale(20);
    (side > 0 ? ids.second : ids.first) = scene.add_collider(pad);
  }
  return ids;
}

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
