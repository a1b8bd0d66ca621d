#pragma once
/// \file
/// Refinement of a capture's camera calibration by ICP (PCL's IterativeClosestPoint): the real
/// cloud, put in the world frame with the initial calibration, is registered rigidly onto the
/// simulated cloud of the same instant, and the correction is folded into world_to_camera.

#include <Eigen/Core>

#include "metrics/cloud_io.h"

namespace gd::metrics {

struct IcpOptions {
  double max_correspondence_distance = 0.05;  ///< m; pairs farther apart are ignored
  int max_iterations = 100;
  double transformation_epsilon = 1e-10;  ///< stop when the update's squared change is below
  double euclidean_fitness_epsilon = 1e-12;  ///< relative change of the mean squared error
  /// Point-to-plane (PCL IterativeClosestPointWithNormals, normals of the denser cloud from its
  /// `normal_neighbours` nearest points) instead of point-to-point, which slides slowly along
  /// smooth cloth and stops millimetres short.
  bool point_to_plane = true;
  int normal_neighbours = 16;
  /// Largest accepted correction (rotation deg / translation m); a larger one is rejected (the
  /// initial transform is returned and a warning logged) since it usually means a wrong match.
  double max_rotation_deg = 20;
  double max_translation = 0.2;
  /// A correction is kept only if it lowers the fitness (mean squared distance of matched
  /// pairs) by at least this fraction of the initial transform's fitness. A flat sheet lets
  /// ICP slide in its plane at almost no cost; an exact calibration must stay as it is.
  double min_improvement = 0.05;
};

struct IcpReport {
  bool converged = false;
  bool accepted = false;       ///< false: the initial transform was returned
  double fitness = 0;          ///< after: mean squared distance from each source point to its nearest
                               ///< target point, over pairs closer than max_correspondence_distance, m²
  double initial_fitness = 0;  ///< the same score for the initial transform
  double rotation_deg = 0;     ///< size of the correction
  double translation = 0;      ///< m
};

/// Refines `initial_world_to_camera` so that inv(result) * real_camera best matches sim_world.
/// The sparser of the two clouds is registered onto the denser one (PCL ICP, rigid).
/// Logs the fitness; fills `report` when given. Throws InputError for an empty cloud.
Eigen::Matrix4d refine_world_to_camera(const Cloud& sim_world, const Cloud& real_camera,
                                       const Eigen::Matrix4d& initial_world_to_camera,
                                       const IcpOptions& options = {}, IcpReport* report = nullptr);

}  // namespace gd::metrics
