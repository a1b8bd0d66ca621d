#include "metrics/alignment.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <random>

#include "metrics/test_util.h"

namespace gd::metrics {
namespace {

float sheet_z(float x, float y) {
  return 0.1f + 0.06f * std::sin(7 * x) * std::cos(5 * y) + 0.04f * x * y;
}

/// A draped-cloth-like sheet with bumps in both directions, so that ICP has no sliding mode.
Cloud bumpy_sheet() {
  Cloud c;
  for (int i = 0; i < 60; ++i)
    for (int j = 0; j < 60; ++j) {
      const float x = -0.35f + 0.7f * i / 59.0f, y = -0.35f + 0.7f * j / 59.0f;
      c.emplace_back(x, y, sheet_z(x, y));
    }
  return c;
}

Eigen::Matrix4d pose(const Eigen::Vector3d& axis, double angle, const Eigen::Vector3d& t) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
  T.topRightCorner<3, 1>() = t;
  return T;
}

TEST(Alignment, IcpRecoversAPerturbedCalibration) {
  const Cloud sim = bumpy_sheet();
  const Eigen::Matrix4d truth = pose({1, 0.2, 0}, 2.4, {0.05, -0.1, 1.0});
  // The camera sees the cloth densely (as a segmented capture: 20k points, 1 mm noise).
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-0.35f, 0.35f);
  std::normal_distribution<float> noise(0.0f, 0.001f);
  Cloud seen;
  for (int i = 0; i < 20000; ++i) {
    const float x = u(rng), y = u(rng);
    seen.emplace_back(x + noise(rng), y + noise(rng), sheet_z(x, y) + noise(rng));
  }
  const Cloud real_camera = transform_cloud(seen, truth);
  const double deg = std::numbers::pi / 180;
  // The calibration is off by 3 degrees about an axis through the cloth and by 2.7 cm.
  const Eigen::Matrix4d initial = truth * pose({0.3, -1, 0.5}, 3 * deg, {0.02, -0.015, 0.01});

  IcpReport rep;
  const Eigen::Matrix4d got = refine_world_to_camera(sim, real_camera, initial, {}, &rep);
  EXPECT_TRUE(rep.converged);
  EXPECT_TRUE(rep.accepted);
  EXPECT_LT(rep.fitness, 2e-5);
  EXPECT_LT(rep.fitness, 0.5 * rep.initial_fitness);
  const Eigen::Matrix4d err = got * truth.inverse();
  const double angle = Eigen::AngleAxisd(Eigen::Matrix3d(err.topLeftCorner<3, 3>())).angle();
  EXPECT_LT(std::abs(angle), 0.5 * deg);
  // Translation error measured at the cloth (camera-frame positions of world points).
  double worst = 0;
  for (const auto& p : sim) {
    const Eigen::Vector4d q(p.x(), p.y(), p.z(), 1);
    worst = std::max(worst, ((got - truth) * q).head<3>().norm());
  }
  EXPECT_LT(worst, 0.002);
}

TEST(Alignment, KeepsAnExactCalibrationOfAFlatSheet) {
  // A flat sheet: ICP can slide in its plane at no cost, so it must not move an exact calibration.
  Cloud sim;
  for (int i = 0; i < 40; ++i)
    for (int j = 0; j < 30; ++j) sim.emplace_back(0.1f + 0.6f * i / 39.0f, -0.25f + 0.5f * j / 29.0f, 0.01f);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> ux(0.1f, 0.7f), uy(-0.25f, 0.25f);
  std::normal_distribution<float> noise(0.0f, 0.002f);
  Cloud seen;
  for (int i = 0; i < 8000; ++i) seen.emplace_back(ux(rng) + noise(rng), uy(rng) + noise(rng), 0.01f + noise(rng));
  const Eigen::Matrix4d truth = pose({1, 0.3, 0}, 2.2, {0.1, 0.05, 1.2});
  for (bool p2p : {false, true}) {
    IcpOptions o;
    o.point_to_plane = p2p;
    IcpReport rep;
    const Eigen::Matrix4d got = refine_world_to_camera(sim, transform_cloud(seen, truth), truth, o, &rep);
    EXPECT_GT(rep.initial_fitness, 0);
    if (rep.accepted) {
      // Accepted only if it really fits better; then it must still be close to the truth.
      EXPECT_LE(rep.fitness, (1 - o.min_improvement) * rep.initial_fitness);
      EXPECT_LT(rep.rotation_deg, 0.5) << "point_to_plane " << p2p;
      EXPECT_LT(rep.translation, 0.005) << "point_to_plane " << p2p;
    } else {
      EXPECT_TRUE(got.isApprox(truth)) << "point_to_plane " << p2p;
    }
  }
}

TEST(Alignment, RejectsEmptyClouds) {
  testing::expect_input_error(
      [] { refine_world_to_camera({}, bumpy_sheet(), Eigen::Matrix4d::Identity()); }, "non-empty");
}

}  // namespace
}  // namespace gd::metrics
