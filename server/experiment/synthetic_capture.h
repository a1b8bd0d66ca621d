#pragma once
/// \file
/// Synthetic captures in RGBench's exact per-capture layout, for tests and demos (the real
/// dataset is not reachable from every machine): a reference simulation (its own resolution and
/// time step) is "filmed" by a virtual depth camera: at `fps` the cloth surface is sampled
/// (area-weighted points), disturbed by Gaussian noise, random dropouts and an occluded disc, put
/// in the camera frame with a known world_to_camera, and written as
/// segment_pcds/pointcloud_<ts>_segmented.pcd with ts = master_start + t - camera_delay (so that
/// RGBench's compensation t_real + camera_delay lands back on t). The arms' trajectory goes to
/// joints/{left,right}_arm_joint_states_and_end_pose.csv, the transform to
/// calibration/world_to_camera_transform.json (optionally a deliberately wrong one, to test ICP),
/// and the timing to capture.json.

#include <Eigen/Geometry>
#include <cstdint>
#include <string>

#include "experiment/experiment.h"
#include "metrics/capture.h"

namespace gd::experiment {

struct SyntheticCaptureOptions {
  double fps = 10;                     ///< frames per second of sim time
  int points_per_frame = 4000;         ///< surface samples before dropouts
  double noise = 0.001;                ///< m, standard deviation per coordinate
  double dropout = 0.1;                ///< fraction of points removed at random
  double occlusion_radius = 0.04;      ///< m, a disc of the cloth (random per frame) left unseen; 0: none
  double master_start_time = 1753696464.0;  ///< absolute Unix time of t = 0
  double camera_delay = 0.05;          ///< s
  /// The true camera: 1.2 m above the table, looking down, tilted and offset.
  Eigen::Isometry3d world_to_camera = default_world_to_camera();
  /// If set, this (wrong) transform is written to the calibration file instead of the true one.
  std::optional<Eigen::Isometry3d> written_world_to_camera;
  metrics::EvalWindow window;          ///< written to capture.json (default: everything)
  std::uint32_t seed = 7;

  static Eigen::Isometry3d default_world_to_camera();
};

/// What was written.
struct SyntheticCapture {
  std::string dir;
  int frames = 0;
  double duration = 0;  ///< s of sim time covered
};

/// Runs `reference` (its garment, material, task, scene options; pseudo mode, generated task or
/// its trajectory file) and writes the capture into `dir`. Throws InputError on bad options.
SyntheticCapture make_synthetic_capture(const ExperimentConfig& reference, const SyntheticCaptureOptions& options,
                                        const std::string& dir);

}  // namespace gd::experiment
