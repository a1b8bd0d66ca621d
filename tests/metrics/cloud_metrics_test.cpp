#include "metrics/cloud_metrics.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>

#include "metrics/test_util.h"
#include "sim/backend/cpu/omp_threads.h"
#include "sim/log.h"

namespace gd::metrics {
namespace {

using testing::random_cloud;

/// The definitions of RGBench's compute_cost, by brute force in double.
Metrics brute_force(const Cloud& sim, const Cloud& real) {
  auto directed = [](const Cloud& a, const Cloud& b, bool l1, double& mean, double& mx) {
    double sum = 0;
    mx = 0;
    for (const auto& p : a) {
      double best = INFINITY;
      for (const auto& q : b) {
        const Eigen::Vector3d d = p.cast<double>() - q.cast<double>();
        best = std::min(best, l1 ? d.cwiseAbs().sum() : d.norm());
      }
      sum += best;
      mx = std::max(mx, best);
    }
    mean = sum / double(a.size());
  };
  Metrics m;
  double unused;
  directed(sim, real, true, m.cd_l1_s2r, unused);
  directed(real, sim, true, m.cd_l1_r2s, unused);
  directed(sim, real, false, m.cd_l2_s2r, m.hd_s2r);
  double mean_r2s;
  directed(real, sim, false, mean_r2s, m.hd_r2s);
  double zs = 0, zr = 0;
  for (const auto& p : sim) zs += p.z();
  for (const auto& p : real) zr += p.z();
  m.z_err = std::abs(zs / double(sim.size()) - zr / double(real.size()));
  double st = 0;
  for (size_t i = 1; i + 1 < sim.size(); ++i) {
    const Eigen::Vector3d a = sim[i - 1].cast<double>(), b = sim[i].cast<double>(),
                          c = sim[i + 1].cast<double>();
    st += ((a + b + c) / 3.0 - b).norm();
  }
  m.sim_stab = sim.size() < 3 ? 0 : st / double(sim.size());
  return m;
}

void expect_metrics_near(const Metrics& a, const Metrics& b, double rel) {
  for (const MetricName& n : kMetricNames) {
    const double x = a.*n.field, y = b.*n.field;
    EXPECT_NEAR(x, y, rel * std::max(std::abs(y), 1e-9)) << n.key;
  }
}

/// A regular grid with spacing h, nx x ny x nz points.
Cloud grid(int nx, int ny, int nz, float h) {
  Cloud c;
  for (int i = 0; i < nx; ++i)
    for (int j = 0; j < ny; ++j)
      for (int k = 0; k < nz; ++k) c.emplace_back(i * h, j * h, k * h);
  return c;
}

TEST(CloudMetrics, MatchesBruteForceOnRandomClouds) {
  for (auto [ns, nr, seed] : {std::tuple{2000, 3000, 1u}, std::tuple{3000, 2000, 2u},
                              std::tuple{1, 500, 3u}, std::tuple{700, 1, 4u}}) {
    const Cloud sim = random_cloud(size_t(ns), seed);
    Cloud real = random_cloud(size_t(nr), seed + 100, 0.8f);
    for (auto& p : real) p += Eigen::Vector3f(0.1f, -0.05f, 0.2f);
    expect_metrics_near(compute_metrics(sim, real), brute_force(sim, real), 1e-6);
  }
}

TEST(CloudMetrics, AnisotropicCloudsMatchBruteForce) {
  // Flat, cloth-like clouds where L1 and L2 neighbours often differ.
  Cloud sim = random_cloud(2500, 7), real = random_cloud(2500, 8);
  for (auto& p : sim) p.z() *= 0.02f;
  for (auto& p : real) p = Eigen::Vector3f(p.x() * 0.9f, p.y() * 1.1f, 0.05f + 0.03f * p.z());
  expect_metrics_near(compute_metrics(sim, real), brute_force(sim, real), 1e-6);
}

TEST(CloudMetrics, IdenticalCloudsGiveZeroDistances) {
  const Cloud c = random_cloud(4000, 11);
  const Metrics m = compute_metrics(c, c);
  EXPECT_EQ(m.cd_l1_s2r, 0);
  EXPECT_EQ(m.cd_l1_r2s, 0);
  EXPECT_EQ(m.cd_l2_s2r, 0);
  EXPECT_EQ(m.hd_s2r, 0);
  EXPECT_EQ(m.hd_r2s, 0);
  EXPECT_EQ(m.z_err, 0);
  EXPECT_GT(m.sim_stab, 0);  // random order: not smooth
}

TEST(CloudMetrics, KnownShiftGivesKnownValues) {
  const Cloud sim = grid(10, 10, 4, 0.1f);
  for (const Eigen::Vector3f shift : {Eigen::Vector3f(0.01f, 0.02f, 0.0f),
                                      Eigen::Vector3f(0.01f, 0.02f, 0.005f)}) {
    Cloud real = sim;
    for (auto& p : real) p += shift;
    const Metrics m = compute_metrics(sim, real);
    const double l1 = 0.01 + 0.02 + shift.z(), l2 = std::sqrt(0.0001 + 0.0004 + double(shift.z()) * shift.z());
    EXPECT_NEAR(m.cd_l1_s2r, l1, 1e-6);
    EXPECT_NEAR(m.cd_l1_r2s, l1, 1e-6);
    EXPECT_NEAR(m.cd_l2_s2r, l2, 1e-6);
    EXPECT_NEAR(m.hd_s2r, l2, 1e-6);
    EXPECT_NEAR(m.hd_r2s, l2, 1e-6);
    EXPECT_NEAR(m.z_err, shift.z(), 1e-6);
  }
  EXPECT_NEAR(compute_metrics(sim, sim).cd_l2_s2r, 0, 0);
}

TEST(CloudMetrics, HausdorffIsOneSidedMaximum) {
  // One real outlier far from the sim cloud: HD_r2s sees it, HD_s2r does not.
  Cloud sim = grid(5, 5, 1, 0.1f), real = sim;
  real.emplace_back(0.2f, 0.2f, 1.0f);
  const Metrics m = compute_metrics(sim, real);
  EXPECT_NEAR(m.hd_s2r, 0, 1e-9);
  EXPECT_NEAR(m.hd_r2s, 1.0, 1e-6);
  EXPECT_NEAR(m.cd_l1_r2s, 1.0 / 26.0, 1e-6);
  EXPECT_NEAR(m.z_err, 1.0 / 26.0, 1e-6);
}

TEST(CloudMetrics, SimStabilityOfLineAndZigZag) {
  Cloud line;
  for (int i = 0; i < 50; ++i) line.emplace_back(i / 128.0f, 0.0f, 0.25f);  // exact in float
  EXPECT_EQ(sim_stability(line), 0);
  // v_i = (i h, (i mod 2) a, 0): every interior vertex is 2a/3 from its neighbourhood mean.
  const int n = 41;
  const double a = 0.012;
  Cloud zz;
  for (int i = 0; i < n; ++i) zz.emplace_back(i / 128.0f, (i % 2) * float(a), 0.0f);
  EXPECT_NEAR(sim_stability(zz), (n - 2) * (2 * double(float(a)) / 3) / n, 1e-12);
  EXPECT_NEAR(compute_metrics(zz, line).sim_stab, sim_stability(zz), 0);
  EXPECT_EQ(sim_stability(Cloud(2, Eigen::Vector3f::Ones())), 0);
}

TEST(CloudMetrics, RejectsEmptyAndNonFiniteClouds) {
  const Cloud c = random_cloud(10, 1);
  testing::expect_input_error([&] { compute_metrics({}, c); }, "sim cloud is empty");
  testing::expect_input_error([&] { compute_metrics(c, {}); }, "real cloud is empty");
  Cloud bad = c;
  bad[3].y() = NAN;
  testing::expect_input_error([&] { compute_metrics(c, bad); }, "index 3");
}

TEST(CloudMetrics, JsonHasTheSevenKeys) {
  Metrics m{0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7};
  const auto j = to_json(m);
  EXPECT_EQ(j.size(), 7u);
  EXPECT_DOUBLE_EQ(j["cd_l1_s2r"].get<double>(), 0.1);
  EXPECT_DOUBLE_EQ(j["cd_l1_r2s"].get<double>(), 0.2);
  EXPECT_DOUBLE_EQ(j["cd_l2_s2r"].get<double>(), 0.3);
  EXPECT_DOUBLE_EQ(j["hd_s2r"].get<double>(), 0.4);
  EXPECT_DOUBLE_EQ(j["hd_r2s"].get<double>(), 0.5);
  EXPECT_DOUBLE_EQ(j["z_err"].get<double>(), 0.6);
  EXPECT_DOUBLE_EQ(j["sim_stab"].get<double>(), 0.7);
  const Metrics back = metrics_from_json(j);
  for (const MetricName& n : kMetricNames) EXPECT_EQ(back.*n.field, m.*n.field) << n.key;
  testing::expect_input_error([] { metrics_from_json(nlohmann::json{{"cd_l1_s2r", 1}}); }, "cd_l2_s2r");
}

TEST(CloudMetrics, Bench40kBy40k) {
  // Timing only (logged, not asserted): two 40k clouds shaped like draped cloth.
  Cloud sim = random_cloud(40000, 21), real = random_cloud(40000, 22);
  for (auto& p : sim) p.z() = 0.1f + 0.05f * std::sin(6 * p.x()) * std::cos(4 * p.y()) + 0.003f * p.z();
  for (auto& p : real) p.z() = 0.11f + 0.05f * std::sin(6 * p.x() + 0.2f) * std::cos(4 * p.y()) + 0.003f * p.z();
  compute_metrics(Cloud(sim.begin(), sim.begin() + 1000), real);  // warm up the thread pool
  const auto t0 = std::chrono::steady_clock::now();
  const Metrics m = compute_metrics(sim, real);
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  gd::log().info("bench: compute_metrics 40k x 40k: {:.3f} s on {} threads (cd_l1_r2s {:.5f})", s,
                 omp_threads(), m.cd_l1_r2s);
  std::printf("[ bench    ] compute_metrics 40k x 40k: %.3f s on %d threads\n", s, omp_threads());
  EXPECT_GT(m.cd_l1_r2s, 0);
}

}  // namespace
}  // namespace gd::metrics
