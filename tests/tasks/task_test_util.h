#pragma once
// Small garments and scenes for the tasks tests (the garment generator is not used here).

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "garments/garment.h"
#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/scene.h"
#include "tasks/frames.h"
#include "tasks/trajectory.h"

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

/// RGBench's Piper URDF under $GD_SHARED_DIR, or "" where it is absent (robot tests skip).
inline std::string piper_urdf() {
  std::filesystem::path shared;
  if (const char* s = std::getenv("GD_SHARED_DIR"); s && *s) shared = s;
  const auto p = shared / "data" / "rgbench" / "piper_with_gripper.urdf";
  return !shared.empty() && std::filesystem::exists(p) ? p.string() : "";
}

/// Both arms' trajectories at these times: the left hand top down at left_at(t) with opening
/// left_gripper(t); the right hand top down and open at `right_at`, waiting out of the way.
template <class At, class Gripper>
DualArmTrajectory two_arms(const std::vector<double>& times, At left_at, Gripper left_gripper,
                           const sim::Vec3& right_at = sim::Vec3(0.2, -0.25, 0.3)) {
  std::vector<ArmSample> left, right;
  for (const double t : times) {
    ArmSample s;
    s.t = t;
    s.orientation = top_down_orientation();
    s.gripper = left_gripper(t);
    s.position = left_at(t);
    left.push_back(s);
    s.gripper = kGripperOpen;
    s.position = right_at;
    right.push_back(s);
  }
  DualArmTrajectory traj;
  traj.left = ArmTrajectory(left, "left");
  traj.right = ArmTrajectory(right, "right");
  return traj;
}

}  // namespace gd::tasks::testing
