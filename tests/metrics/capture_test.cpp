#include "metrics/capture.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "metrics/test_util.h"

namespace gd::metrics {
namespace {

namespace fs = std::filesystem;
using testing::expect_input_error;
using testing::random_cloud;
using testing::temp_dir;

Eigen::Matrix4d camera_pose() {
  // A camera 1.2 m in front of and above the table, looking back down at it.
  Eigen::Matrix4d w2c = Eigen::Matrix4d::Identity();
  w2c.topLeftCorner<3, 3>() = (Eigen::AngleAxisd(2.3, Eigen::Vector3d::UnitX()) *
                               Eigen::AngleAxisd(-1.4, Eigen::Vector3d::UnitZ()))
                                  .toRotationMatrix();
  w2c.topRightCorner<3, 1>() = Eigen::Vector3d(0.05, -0.2, 1.1);
  return w2c;
}

TEST(Capture, FrameNamesFormatAndParseLikeRgbench) {
  EXPECT_EQ(frame_file_name(1753696464.817768), "pointcloud_1753696464.817768_segmented.pcd");
  EXPECT_EQ(frame_file_name(1753696465.0), "pointcloud_1753696465.000000_segmented.pcd");
  EXPECT_DOUBLE_EQ(*parse_frame_timestamp("pointcloud_1753696464.817768_segmented.pcd"),
                   1753696464.817768);
  EXPECT_FALSE(parse_frame_timestamp("pointcloud_1753696464.817768.pcd"));
  EXPECT_FALSE(parse_frame_timestamp("pointcloud_abc_segmented.pcd"));
}

TEST(Capture, LoadsSyntheticCaptureSortedAndInWorldFrame) {
  const std::string dir = temp_dir("cap");
  const Eigen::Matrix4d w2c = camera_pose();
  const std::vector<double> ts = {1753696465.25, 1753696464.817768, 1753696465.9, 1753696465.031};
  std::vector<Cloud> world;
  for (size_t k = 0; k < ts.size(); ++k) {
    world.push_back(random_cloud(200 + 10 * k, unsigned(k) + 1, 0.3f));
    write_capture_frame(dir, ts[k], transform_cloud(world.back(), w2c));
  }
  write_calibration(dir, w2c);
  std::ofstream(dir + "/segment_pcds/pointcloud_1753696464.9.pcd");  // not "_segmented": ignored
  fs::create_directories(dir + "/joints");
  std::ofstream(dir + "/joints/left_arm_joint_states_and_end_pose.csv") << "time\n";

  const Capture c = load_capture(dir);
  ASSERT_EQ(c.frames.size(), 4u);
  EXPECT_TRUE(c.has_calibration);
  EXPECT_TRUE(c.has_left_joints);
  EXPECT_FALSE(c.has_right_joints);
  EXPECT_LE((c.world_to_camera - w2c).norm(), 1e-12);
  EXPECT_LE((c.camera_to_world * w2c - Eigen::Matrix4d::Identity()).norm(), 1e-12);
  const std::vector<size_t> order = {1, 3, 0, 2};
  for (size_t i = 0; i < 4; ++i) {
    EXPECT_NEAR(c.frames[i].timestamp, ts[order[i]], 1e-6);
    const Cloud w = frame_in_world(c, i);
    ASSERT_EQ(w.size(), world[order[i]].size());
    for (size_t p = 0; p < w.size(); ++p) EXPECT_LE((w[p] - world[order[i]][p]).norm(), 2e-6f);
  }
  EXPECT_FALSE(c.has_camera_delay);
  EXPECT_FALSE(c.has_window);
}

TEST(Capture, MissingCalibrationIsIdentityAndBadOnesAreErrors) {
  const std::string dir = temp_dir("nocal");
  write_capture_frame(dir, 100.5, random_cloud(10, 1));
  const Capture c = load_capture(dir);
  EXPECT_FALSE(c.has_calibration);
  EXPECT_EQ(c.world_to_camera, Eigen::Matrix4d::Identity());
  EXPECT_EQ(c.camera_to_world, Eigen::Matrix4d::Identity());

  fs::create_directories(dir + "/calibration");
  std::ofstream(dir + "/calibration/world_to_camera_transform.json") << "[[1,0,0],[0,1,0]]";
  expect_input_error([&] { load_capture(dir); }, "4x4");
  expect_input_error([&] { load_capture(dir + "/nope"); }, "does not exist");
  const std::string empty = temp_dir("empty");
  fs::create_directories(empty + "/segment_pcds");
  expect_input_error([&] { load_capture(empty); }, "no pointcloud_<unix_ts>_segmented.pcd");
}

TEST(Capture, CaptureJsonAndOptionsGiveTiming) {
  const std::string dir = temp_dir("json");
  write_capture_frame(dir, 10.0, random_cloud(10, 1));
  Capture meta;
  meta.garment = "green_tshirt";
  meta.action = "fold";
  meta.sample = "02";
  meta.camera_delay = 0.05;
  meta.has_camera_delay = true;
  meta.window = {0.5, 6.0, 1.0, 5.0};
  meta.has_window = true;
  write_capture_json(dir, meta);
  Capture c = load_capture(dir);
  EXPECT_EQ(c.garment, "green_tshirt");
  EXPECT_EQ(c.action, "fold");
  EXPECT_EQ(c.sample, "02");
  EXPECT_DOUBLE_EQ(c.camera_delay, 0.05);
  EXPECT_DOUBLE_EQ(c.window.end_calculate_time, 5.0);
  EXPECT_DOUBLE_EQ(c.window.start_record_time, 0.5);
  EXPECT_TRUE(c.synthetic.empty());  // a capture that does not say otherwise is real
  meta.synthetic = "GarmentDynamics, tshirt fold at 680 vertices";
  write_capture_json(dir, meta);
  EXPECT_EQ(load_capture(dir).synthetic, meta.synthetic);

  CaptureOptions o;
  o.camera_delay = 0.04;
  o.window = EvalWindow{0, 2, 0, 1};
  c = load_capture(dir, o);
  EXPECT_DOUBLE_EQ(c.camera_delay, 0.04);
  EXPECT_DOUBLE_EQ(c.window.end_record_time, 2);

  std::ofstream(dir + "/capture.json") << R"({"camera_delay": "fast"})";
  expect_input_error([&] { load_capture(dir); }, "camera_delay");
}

TEST(Capture, ExperimentLibraryLookupOnTheRealFile) {
  const std::string data = testing::rgbench_data_dir();
  if (data.empty()) GTEST_SKIP() << "GD_SHARED_DIR/data/rgbench not available";
  const std::string lib = data + "/experiment_library.yaml";
  const auto all = load_experiment_library(lib);
  EXPECT_GE(all.size(), 90u);
  const auto e = find_experiment(lib, "blue_dress", "fling", "1");
  ASSERT_TRUE(e);
  EXPECT_DOUBLE_EQ(e->camera_delay, 0.059880);
  EXPECT_EQ(e->data_subfolder, "blue_dress/blue_dress_fling_2025-07-27-21-35-28");
  EXPECT_DOUBLE_EQ(e->window.end_record_time, 4.0);
  EXPECT_DOUBLE_EQ(e->window.end_calculate_time, 3.14);
  const auto by_dir = find_experiment_by_subfolder(lib, "blue_dress_fling_2025-07-27-21-35-44");
  ASSERT_TRUE(by_dir);
  EXPECT_EQ(by_dir->sample, "02");
  EXPECT_FALSE(find_experiment(lib, "blue_dress", "fling", "99"));

  // A capture directory named like the dataset's picks its entry up by name.
  const std::string dir = temp_dir("lib") + "/blue_dress_fling_2025-07-27-21-35-59";
  write_capture_frame(dir, 5.0, random_cloud(5, 1));
  CaptureOptions o;
  o.experiment_library = lib;
  const Capture c = load_capture(dir, o);
  EXPECT_TRUE(c.has_camera_delay);
  EXPECT_DOUBLE_EQ(c.camera_delay, 0.0609756);
  EXPECT_DOUBLE_EQ(c.window.end_calculate_time, 2.6);
  EXPECT_EQ(c.garment, "blue_dress");
  EXPECT_EQ(c.action, "fling");
  expect_input_error([&] { load_experiment_library(data + "/nope.yaml"); }, "nope.yaml");
}

TEST(Capture, EvaluationLoopFollowsRgbenchTiming) {
  // Frames every 0.1 s from master_start - 0.2 s; a sim with dt = 0.002 whose vertices are the
  // world cloud translated by 1 cm per second of sim time.
  const std::string dir = temp_dir("eval");
  const double master = 1000.0, dt = 0.002;
  const Cloud base = random_cloud(300, 5, 0.3f);
  for (int k = 0; k < 12; ++k) write_capture_frame(dir, master - 0.2 + 0.1 * k, base);  // identity calib
  Capture meta;
  meta.camera_delay = 0.05;
  meta.has_camera_delay = true;
  meta.window = {0.0, 0.62, 0.2, 0.5};
  meta.has_window = true;
  write_capture_json(dir, meta);
  const Capture c = load_capture(dir);

  for (const std::string action : {"fold", "fling"}) {
    const double prep = sim_prepare_time(action);
    double sim_t = 0;
    std::vector<double> asked;
    EvalOptions o;
    o.master_start_time = master;
    o.prepare_time = prep;
    o.keep_frames = 3;
    const EvalResult r = run_evaluation(c, o, [&](double target) {
      asked.push_back(target);
      while (sim_t < target) sim_t += dt;  // RGBench's step_to_time: may overshoot by < dt
      Cloud v = base;
      for (auto& p : v) p.x() += 0.01f * float(sim_t - prep);
      return SimSample{v, sim_t};
    });
    // Frames at t = 0.0 .. 0.9 (the two before master start are dropped).
    ASSERT_EQ(asked.size(), 10u);
    for (size_t k = 0; k < asked.size(); ++k) EXPECT_NEAR(asked[k], 0.1 * k + 0.05 + prep, 1e-6);
    // sim_time = t + 0.05 (+ < dt) must be <= 0.62: t = 0.0 .. 0.5 -> 6 rows.
    ASSERT_EQ(r.rows.size(), 6u) << action;
    for (size_t k = 0; k < r.rows.size(); ++k) {
      EXPECT_NEAR(r.rows[k].target_time, 0.1 * k, 1e-6);
      EXPECT_GE(r.rows[k].sim_time, r.rows[k].target_time + 0.05 - 1e-9);
      EXPECT_LT(r.rows[k].sim_time, r.rows[k].target_time + 0.05 + dt + 1e-9);
      EXPECT_NEAR(r.rows[k].m.cd_l1_s2r, 0.01 * r.rows[k].sim_time, 1e-5);
      EXPECT_EQ(r.rows[k].frame, k + 2);
    }
    ASSERT_EQ(r.kept.size(), 3u);
    EXPECT_EQ(r.kept.front().row, 0u);
    EXPECT_EQ(r.kept.back().row, 5u);
    EXPECT_EQ(r.kept[1].real.size(), base.size());
  }
  EXPECT_EQ(sim_prepare_time("fling"), 10.0);
  EXPECT_EQ(sim_prepare_time("grasp"), 0.0);
}

}  // namespace
}  // namespace gd::metrics
