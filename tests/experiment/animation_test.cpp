// Every run writes OUT/animation.npy: the garment's positions at the recorded frames (float32,
// (frames, N, 3)), their times in summary.json; scripts/plot_animation.py draws the GIF from it.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "experiment/experiment.h"
#include "experiment/temp_dir.h"
#include "sim/mesh.h"

namespace gd::experiment {
namespace {

TEST(Animation, TheRecordedFramesAreWrittenAsANpyArrayWithTheirTimes) {
  const testing::TempDir tmp("animation");
  ExperimentConfig c;
  c.garment = "towel";
  c.task = "grasp";
  c.vertices = 200;
  c.scene.dt = 0.01;
  c.scene.self_contact = false;
  c.task_params.time_scale = 0.1;
  c.settle_after = 0;
  c.plots = false;
  c.out_dir = tmp.str();
  const ExperimentResult r = run_experiment(c);
  const auto& a = r.summary.at("animation");
  const size_t frames = a.at("frames").get<size_t>();
  const std::vector<double> times = a.at("times").get<std::vector<double>>();
  const int n = r.summary.at("vertices").get<int>();
  ASSERT_EQ(times.size(), frames);
  EXPECT_GE(frames, 10u);
  EXPECT_LE(frames, 160u);
  EXPECT_DOUBLE_EQ(times.front(), 0.0);
  for (size_t k = 1; k < times.size(); ++k) EXPECT_GT(times[k], times[k - 1]);
  // The .npy: magic, version 1.0, a header naming float32 and the shape, then the data.
  std::ifstream f(tmp.str() + "/animation.npy", std::ios::binary);
  std::vector<char> bytes((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  ASSERT_GT(bytes.size(), 10u);
  EXPECT_EQ(std::string(bytes.data(), 6), "\x93NUMPY");
  uint16_t len = 0;
  std::memcpy(&len, bytes.data() + 8, 2);
  EXPECT_EQ((10 + len) % 64, 0);
  const std::string header(bytes.data() + 10, len);
  EXPECT_NE(header.find("'<f4'"), std::string::npos) << header;
  EXPECT_NE(header.find("(" + std::to_string(frames) + ", " + std::to_string(n) + ", 3)"), std::string::npos) << header;
  ASSERT_EQ(bytes.size(), 10 + len + frames * n * 3 * sizeof(float));
  // The first frame is the initial garment, the last the final one (float32 of the OBJs' doubles).
  const sim::Mesh initial = sim::read_obj(tmp.str() + "/initial.obj");
  const float* data = reinterpret_cast<const float*>(bytes.data() + 10 + len);
  for (int i = 0; i < n; i += 37)
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(data[3 * i + k], initial.x[i][k], 1e-6);
  EXPECT_LE(times.back(), r.summary.at("sim_seconds").get<double>() + 1e-9);
  // The run's speed counts its steps only: set-up (meshing, settling, files) is reported apart.
  const double wall = r.summary.at("wall_seconds"), stepping = r.summary.at("stepping_seconds");
  EXPECT_GT(stepping, 0.0);
  EXPECT_LT(stepping, wall);
  EXPECT_NEAR(r.summary.at("setup_seconds").get<double>(), wall - stepping, 1e-9);
  EXPECT_NEAR(r.summary.at("ms_per_step").get<double>(), 1e3 * stepping / r.summary.at("steps").get<int>(), 1e-9);
  EXPECT_EQ(r.summary.at("settle_steps").get<int>(), 100);  // the garment settles 1 s at dt 10 ms before planning
}

}  // namespace
}  // namespace gd::experiment
