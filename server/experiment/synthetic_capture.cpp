#include "experiment/synthetic_capture.h"

#include <cmath>
#include <filesystem>
#include <random>

#include "experiment/convergence.h"
#include "metrics/cloud_io.h"
#include "sim/demand.h"
#include "sim/log.h"
#include "sim/material.h"
#include "sim/scene.h"
#include "tasks/frames.h"
#include "tasks/trajectory.h"

namespace gd::experiment {
using sim::InputError;
using sim::Vec3;

Eigen::Isometry3d SyntheticCaptureOptions::default_world_to_camera() {
  // Camera frame: z along the optical axis. It sits above the cloth at (0.5, 0.1, 1.2), looks
  // down (camera z = world -z) and is rolled and tilted a little, as a real mount would be.
  const Eigen::Matrix3d down = Eigen::AngleAxisd(M_PI, Vec3::UnitX()).toRotationMatrix();
  const Eigen::Matrix3d tilt = (Eigen::AngleAxisd(0.15, Vec3::UnitY()) * Eigen::AngleAxisd(0.3, Vec3::UnitZ()))
                                   .toRotationMatrix();
  Eigen::Isometry3d camera_to_world = Eigen::Isometry3d::Identity();
  camera_to_world.linear() = tilt * down;
  camera_to_world.translation() = Vec3(0.5, 0.1, 1.2);
  return camera_to_world.inverse();
}

namespace {

/// Area-weighted surface samples of the cloth with noise, dropouts and an occluded disc.
metrics::Cloud film(const std::vector<Vec3>& x, const std::vector<Eigen::Vector3i>& tris,
                    const SyntheticCaptureOptions& o, std::mt19937& rng) {
  const std::vector<double> cum = cumulative_areas(x, tris);
  const double total = cum.empty() ? 0.0 : cum.back();
  std::uniform_real_distribution<double> u01(0, 1);
  std::normal_distribution<double> gauss(0, o.noise);
  const Vec3 hole = x[std::uniform_int_distribution<size_t>(0, x.size() - 1)(rng)];
  metrics::Cloud out;
  out.reserve(o.points_per_frame);
  const Eigen::Isometry3d& T = o.world_to_camera;
  for (int k = 0; k < o.points_per_frame; ++k) {
    const size_t t = std::lower_bound(cum.begin(), cum.end(), u01(rng) * total) - cum.begin();
    const auto& f = tris[std::min(t, tris.size() - 1)];
    double a = u01(rng), b = u01(rng);
    if (a + b > 1) a = 1 - a, b = 1 - b;
    Vec3 p = x[f[0]] + a * (x[f[1]] - x[f[0]]) + b * (x[f[2]] - x[f[0]]);
    const bool dropped = u01(rng) < o.dropout;
    if (dropped || (o.occlusion_radius > 0 && (p - hole).norm() < o.occlusion_radius)) continue;
    if (o.noise > 0) p += Vec3(gauss(rng), gauss(rng), gauss(rng));
    out.push_back((T * p).cast<float>());
  }
  return out;
}

}  // namespace

SyntheticCapture make_synthetic_capture(const ExperimentConfig& reference, const SyntheticCaptureOptions& o,
                                        const std::string& dir) {
  if (!(o.fps > 0) || o.points_per_frame < 10 || !(o.noise >= 0) || !(o.dropout >= 0 && o.dropout < 1) ||
      !(o.occlusion_radius >= 0) || !(o.camera_delay >= 0))
    throw InputError("synthetic capture: fps > 0, points_per_frame >= 10, noise >= 0, dropout in [0, 1), "
                     "occlusion_radius >= 0 and camera_delay >= 0 are required");
  const garments::Garment garment = make_experiment_garment(reference);
  Eigen::Isometry3d place = tasks::default_garment_pose();
  place.translation() = reference.garment_position;
  sim::Mesh mesh = garment.mesh;
  for (Vec3& p : mesh.x) p = place * p;
  tasks::DualArmTrajectory traj = reference.trajectory_file.empty()
                                      ? tasks::make_task(reference.task, garment, place, reference.task_params)
                                      : tasks::read_trajectory(reference.trajectory_file);
  traj.master_start_time = o.master_start_time;
  tasks::GripperOptions go = reference.grippers;
  go.mode = tasks::GraspMode::kPseudoGrasp;
  tasks::GripperController controller(traj, go);
  auto scene = sim::Scene::create(mesh, sim::MaterialLibrary::load_default().get(reference.material), reference.scene);

  std::filesystem::create_directories(dir);
  std::mt19937 rng(o.seed);
  SyntheticCapture out{dir, 0, traj.end_time()};
  const int n = static_cast<int>(std::floor(traj.end_time() * o.fps)) + 1;
  gd::log().info("synthetic capture: {} frames of {} ({} vertices, dt {}) into {}", n, garment.type,
                 scene->vertex_count(), reference.scene.dt, dir);
  for (int k = 0; k < n; ++k) {
    const double t = k / o.fps;
    if (!tasks::run_until(*scene, controller, t))
      throw InputError(fmt::format("synthetic capture: the reference simulation failed at t = {:.3f} s: {}",
                                   scene->time(), scene->failure()));
    const double ts = o.master_start_time + t - o.camera_delay;
    metrics::write_capture_frame(dir, ts, film(scene->positions(), mesh.tris, o, rng));
    ++out.frames;
  }
  tasks::write_rgbench_joints(dir + "/joints", traj);
  metrics::write_calibration(dir, (o.written_world_to_camera ? *o.written_world_to_camera : o.world_to_camera).matrix());
  metrics::Capture meta;
  meta.garment = garment.type;
  meta.action = reference.task;
  meta.sample = "01";
  meta.synthetic = fmt::format("GarmentDynamics, {} {} at {} vertices, {}, dt {} s", garment.type, reference.task,
                               scene->vertex_count(), reference.material, reference.scene.dt);
  meta.camera_delay = o.camera_delay;
  meta.has_camera_delay = true;
  meta.window = o.window;
  meta.has_window = std::isfinite(o.window.end_record_time) || o.window.start_record_time > 0 ||
                    std::isfinite(o.window.end_calculate_time) || o.window.start_calculate_time > 0;
  metrics::write_capture_json(dir, meta);
  return out;
}

}  // namespace gd::experiment
