#pragma once
// Small garments and scenes for the tasks tests (the garment generator is not used here).

#include <algorithm>
#include <memory>

#include "garments/garment.h"
#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/scene.h"
#include "tasks/frames.h"

namespace gd::tasks::testing {

/// A flat length x width rectangle in the garment frame (x in [0, length], y centred), with the
/// shoulder landmarks at the small-x corners and the hem landmarks at the far corners.
inline garments::Garment rect_garment(double length, double width, double spacing) {
  garments::Garment g;
  g.type = "towel";
  g.mesh = sim::make_rect(length, width, spacing);
  for (sim::Vec3& p : g.mesh.x) p.y() -= 0.5 * width;
  g.length = length;
  g.width = width;
  auto& lm = g.landmarks;
  lm.left_shoulder = sim::Vec3(0, 0.5 * width, 0);
  lm.right_shoulder = sim::Vec3(0, -0.5 * width, 0);
  lm.left_hem = sim::Vec3(length, 0.5 * width, 0);
  lm.right_hem = sim::Vec3(length, -0.5 * width, 0);
  lm.left_shoulder_vertex = sim::nearest_vertex(g.mesh, lm.left_shoulder);
  lm.right_shoulder_vertex = sim::nearest_vertex(g.mesh, lm.right_shoulder);
  return g;
}

/// The garment's mesh moved to the world by `pose`.
inline sim::Mesh placed(const garments::Garment& g, const Eigen::Isometry3d& pose = default_garment_pose()) {
  sim::Mesh m = g.mesh;
  for (sim::Vec3& p : m.x) p = pose * p;
  return m;
}

inline sim::SceneOptions task_options() {
  sim::SceneOptions o;
  o.dt = 0.01;
  o.self_contact = false;
  o.threads = 1;
  return o;
}

inline std::unique_ptr<sim::Scene> make_scene(const sim::Mesh& m, const sim::SceneOptions& o = task_options()) {
  return sim::Scene::create(m, sim::MaterialLibrary::load_default().get("cotton"), o);
}

inline double min_z(const std::vector<sim::Vec3>& x) {
  double z = 1e9;
  for (const auto& p : x) z = std::min(z, p.z());
  return z;
}
inline double max_z(const std::vector<sim::Vec3>& x) {
  double z = -1e9;
  for (const auto& p : x) z = std::max(z, p.z());
  return z;
}
/// Extent of the points along axis c.
inline double extent(const std::vector<sim::Vec3>& x, int c) {
  double lo = 1e9, hi = -1e9;
  for (const auto& p : x) lo = std::min(lo, p[c]), hi = std::max(hi, p[c]);
  return hi - lo;
}

}  // namespace gd::tasks::testing
