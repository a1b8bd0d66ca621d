#include "metrics/alignment.h"

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/features/normal_3d_omp.h>
#include <pcl/registration/icp.h>
#include <pcl/search/kdtree.h>
#include <spdlog/fmt/fmt.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <vector>

#include "sim/demand.h"
#include "sim/log.h"

namespace gd::metrics {
namespace {

pcl::PointCloud<pcl::PointXYZ>::Ptr to_pcl(const Cloud& c) {
  auto pc = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  pc->reserve(c.size());
  for (const auto& p : c)
    if (p.allFinite()) pc->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
  pc->width = uint32_t(pc->size());
  pc->height = 1;
  pc->is_dense = true;
  return pc;
}

pcl::PointCloud<pcl::PointNormal>::Ptr to_pcl_normals(const Cloud& c) {
  auto pc = std::make_shared<pcl::PointCloud<pcl::PointNormal>>();
  pc->reserve(c.size());
  for (const auto& p : c) {
    if (!p.allFinite()) continue;
    pcl::PointNormal q;
    q.x = p.x();
    q.y = p.y();
    q.z = p.z();
    q.normal_x = q.normal_y = q.normal_z = 0;
    q.curvature = 0;
    pc->push_back(q);
  }
  pc->width = uint32_t(pc->size());
  pc->height = 1;
  pc->is_dense = true;
  return pc;
}

/// PCL's fitness score of `src` against `dst` as they are: the mean squared distance from each
/// source point to its nearest target point, over the pairs closer than max_distance.
double fitness_as_is(const Cloud& src, const Cloud& dst, double max_distance) {
  pcl::search::KdTree<pcl::PointXYZ> tree;
  tree.setInputCloud(to_pcl(dst));
  std::vector<int> idx(1);
  std::vector<float> d2(1);
  double sum = 0;
  long n = 0;
  for (const auto& p : src) {
    if (!p.allFinite()) continue;
    if (tree.nearestKSearch(pcl::PointXYZ(p.x(), p.y(), p.z()), 1, idx, d2) == 1 &&
        d2[0] <= max_distance * max_distance) {
      sum += d2[0];
      ++n;
    }
  }
  return n ? sum / double(n) : std::numeric_limits<double>::max();
}

/// Runs a configured PCL ICP of `source` onto `target`; returns the rigid motion found (which
/// maps the source onto the target) and whether it converged.
template <class Icp, class CloudPtr>
Eigen::Matrix4d run_icp(Icp& icp, const CloudPtr& source, const CloudPtr& target, const IcpOptions& o,
                        bool* converged) {
  icp.setInputSource(source);
  icp.setInputTarget(target);
  icp.setMaxCorrespondenceDistance(o.max_correspondence_distance);
  icp.setMaximumIterations(o.max_iterations);
  icp.setTransformationEpsilon(o.transformation_epsilon);
  icp.setEuclideanFitnessEpsilon(o.euclidean_fitness_epsilon);
  typename CloudPtr::element_type aligned;
  icp.align(aligned);
  *converged = icp.hasConverged();
  return icp.getFinalTransformation();
}

}  // namespace

Eigen::Matrix4d refine_world_to_camera(const Cloud& sim_world, const Cloud& real_camera,
                                       const Eigen::Matrix4d& initial, const IcpOptions& o,
                                       IcpReport* report) {
  if (sim_world.empty() || real_camera.empty())
    throw sim::InputError("ICP needs a non-empty sim cloud and real cloud");
  if (!(o.min_improvement >= 0 && o.min_improvement < 1))
    throw sim::InputError(fmt::format("ICP options: min_improvement ({}) must be in [0, 1)", o.min_improvement));
  if (!(o.max_correspondence_distance > 0) || o.max_iterations < 1)
    throw sim::InputError(fmt::format(
        "ICP options: max_correspondence_distance ({}) must be > 0 and max_iterations ({}) >= 1",
        o.max_correspondence_distance, o.max_iterations));
  // Point-to-point ICP converges best from the sparser cloud onto the denser one (a simulated
  // mesh has ~1 cm vertex spacing, a segmented capture a few mm), so the sparser one is the
  // source. D maps the source onto the target, both in the (initial) world frame.
  const Eigen::Matrix4d cam_to_world0 = initial.inverse();
  const bool sim_is_source = sim_world.size() <= real_camera.size();
  const Cloud real_world0 = transform_cloud(real_camera, cam_to_world0);
  const Cloud& src = sim_is_source ? sim_world : real_world0;
  const Cloud& dst = sim_is_source ? real_world0 : sim_world;

  Eigen::Matrix4d D;
  bool converged = false;
  if (o.point_to_plane) {
    // Point-to-plane: target normals from the k nearest neighbours; no sliding along the cloth.
    auto target = to_pcl_normals(dst);
    pcl::NormalEstimationOMP<pcl::PointNormal, pcl::PointNormal> ne;
    ne.setInputCloud(target);
    ne.setSearchMethod(std::make_shared<pcl::search::KdTree<pcl::PointNormal>>());
    ne.setKSearch(std::max(3, o.normal_neighbours));
    ne.compute(*target);  // fills normal_x/y/z and curvature, keeps the points
    // Points without a usable normal (isolated) would poison the linear solve.
    target->erase(std::remove_if(target->begin(), target->end(),
                                 [](const pcl::PointNormal& p) {
                                   return !std::isfinite(p.normal_x) || !std::isfinite(p.normal_y) ||
                                          !std::isfinite(p.normal_z);
                                 }),
                  target->end());
    target->width = uint32_t(target->size());
    target->height = 1;
    if (target->empty()) throw sim::InputError("ICP: no target normal could be estimated");
    pcl::IterativeClosestPointWithNormals<pcl::PointNormal, pcl::PointNormal, double> icp;
    D = run_icp(icp, to_pcl_normals(src), target, o, &converged);
  } else {
    pcl::IterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ, double> icp;
    D = run_icp(icp, to_pcl(src), to_pcl(dst), o, &converged);
  }

  // Both fitnesses by the same measure, so that the acceptance compares like with like.
  IcpReport r;
  r.converged = converged;
  r.fitness = fitness_as_is(transform_cloud(src, D), dst, o.max_correspondence_distance);
  r.initial_fitness = fitness_as_is(src, dst, o.max_correspondence_distance);
  const bool better = r.fitness <= (1.0 - o.min_improvement) * r.initial_fitness;
  const Eigen::AngleAxisd aa(Eigen::Matrix3d(D.topLeftCorner<3, 3>()));
  r.rotation_deg = std::abs(aa.angle()) * 180.0 / std::numbers::pi;
  r.translation = D.topRightCorner<3, 1>().norm();
  r.accepted = r.converged && better && r.rotation_deg <= o.max_rotation_deg && r.translation <= o.max_translation;
  Eigen::Matrix4d out = initial;
  if (r.accepted) {
    // sim_world = C * real_camera with C the corrected camera-to-world: C = D^-1 C0 when the sim
    // cloud was moved onto the real one, C = D C0 otherwise.
    out = sim_is_source ? Eigen::Matrix4d(initial * D) : Eigen::Matrix4d(initial * D.inverse());
    gd::log().info("ICP: fitness {:.3e} m² (as calibrated {:.3e}), correction {:.3f} deg / {:.4f} m ({} source, {} target points)",
                   r.fitness, r.initial_fitness, r.rotation_deg, r.translation, src.size(), dst.size());
  } else {
    gd::log().warn("ICP: correction rejected (converged {}, {:.3f} deg / {:.4f} m, fitness {:.3e} m² vs "
                   "{:.3e} m² as calibrated); keeping the initial world_to_camera",
                   r.converged, r.rotation_deg, r.translation, r.fitness, r.initial_fitness);
  }
  if (report) *report = r;
  return out;
}

}  // namespace gd::metrics
