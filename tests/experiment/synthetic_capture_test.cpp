// Synthetic RGBench captures from a finer reference run are ingested, time-aligned and (with ICP)
// re-registered by the experiment runner: what was put in comes back out.
#include "experiment/synthetic_capture.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "experiment/experiment.h"
#include "experiment/temp_dir.h"
#include "metrics/capture.h"
#include "sim/demand.h"

namespace gd::experiment {
namespace {
namespace fs = std::filesystem;

using testing::TempDir;

/// A towel grasp: the reference at ~500 vertices and dt 5 ms, the runs at ~250 vertices and 10 ms.
ExperimentConfig towel_grasp(int vertices, double dt) {
  ExperimentConfig c;
  c.garment = "towel";
  c.task = "grasp";
  c.vertices = vertices;
  c.scene.dt = dt;
  c.scene.self_contact = false;  // a single layer lifted by two corners: no self-contact needed
  c.task_params.time_scale = 0.3;
  c.plots = false;
  c.keep_frames = 2;
  return c;
}

/// The reference capture of a test (ctest runs each test in its own process, in parallel, so
/// every test writes its own).
std::string reference_capture(const TempDir& tmp) {
  return [&] {
    const std::string d = tmp / "capture";
    ExperimentConfig ref = towel_grasp(500, 0.005);
    ref.out_dir = d + "_ref";
    SyntheticCaptureOptions o;
    o.fps = 8;
    o.camera_delay = 0.06;
    make_synthetic_capture(ref, o, d);
    return d;
  }();
}

double mean_cd(const ExperimentResult& r) { return r.summary["cd_l1_r2s"].get<double>(); }

TEST(SyntheticCapture, WritesRgbenchLayout) {
  const TempDir tmp("WritesRgbenchLayout");
  const std::string dir = reference_capture(tmp);
  EXPECT_TRUE(fs::exists(dir + "/calibration/world_to_camera_transform.json"));
  EXPECT_TRUE(fs::exists(dir + "/joints/left_arm_joint_states_and_end_pose.csv"));
  EXPECT_TRUE(fs::exists(dir + "/joints/right_arm_joint_states_and_end_pose.csv"));
  const metrics::Capture c = metrics::load_capture(dir);
  ASSERT_GT(c.frames.size(), 20u);
  EXPECT_NEAR(c.camera_delay, 0.06, 1e-12);
  EXPECT_TRUE(c.has_calibration);
  // It says what made it, so that reports never pass it off as a real capture.
  EXPECT_NE(c.synthetic.find("GarmentDynamics"), std::string::npos) << c.synthetic;
  EXPECT_NE(c.synthetic.find("vertices"), std::string::npos) << c.synthetic;
  // Frame k was filmed at sim time k / fps and stamped master_start + k / fps - delay.
  const SyntheticCaptureOptions o;
  EXPECT_NEAR(c.frames[1].timestamp - c.frames[0].timestamp, 1.0 / 8, 1e-5);
  EXPECT_NEAR(c.frames[0].timestamp, o.master_start_time - 0.06, 1e-5);
}

TEST(SyntheticCapture, RunnerRecoversTheReferenceWithTimeAlignment) {
  const TempDir tmp("RunnerRecoversTheReferenceWithTimeAlignment");
  ExperimentConfig run = towel_grasp(250, 0.01);
  run.capture_dir = reference_capture(tmp);
  run.out_dir = tmp / "run";
  const ExperimentResult r = run_experiment(run);
  ASSERT_FALSE(r.summary["failed"].get<bool>()) << r.summary["failure"];

  // RGBench's loop drops frames stamped before the joints' master start (t_real < 0: frame 0,
  // stamped at -delay) and evaluates every other frame.
  const metrics::Capture c = metrics::load_capture(run.capture_dir);
  ASSERT_EQ(r.rows.size(), c.frames.size() - 1);
  for (size_t k = 0; k < r.rows.size(); ++k) {
    const double t_real = (k + 1) / 8.0 - 0.06;
    EXPECT_NEAR(r.rows[k].target_time, t_real, 1e-5);
    // The sim was stepped to t_real + delay and overshoots by less than one step.
    EXPECT_GE(r.rows[k].sim_time, t_real + 0.06 - 1e-9);
    EXPECT_LT(r.rows[k].sim_time, t_real + 0.06 + 0.01 + 1e-9);
  }
  // A coarser, differently stepped simulation of the same motion matches the filmed reference
  // (noise 1 mm per coordinate, 10% dropouts, an occluded disc): its vertices lie within
  // millimetres of the filmed surface (sim-to-real), while real-to-sim is bounded by the sim's
  // vertex spacing (~4 cm here: a dense real point is ~2 cm in L1 from the nearest vertex).
  EXPECT_LT(r.summary["cd_l2_s2r"].get<double>(), 0.01);
  EXPECT_LT(mean_cd(r), 0.03);
  EXPECT_TRUE(fs::exists(run.out_dir + "/metrics.csv"));
  EXPECT_EQ(r.summary["capture_kind"], "synthetic");
  EXPECT_NE(r.summary["capture_synthetic"].get<std::string>().find("GarmentDynamics"), std::string::npos);
  // The report's animation of both clouds: (frames, 2, points, 3) float32, the simulation then
  // the capture, at evaluated frames from the record window's start to its end.
  const auto& anim = r.summary.at("capture_animation");
  const size_t frames = anim.at("frames").get<size_t>(), points = anim.at("points").get<size_t>();
  EXPECT_EQ(frames, std::min<size_t>(60, r.rows.size()));
  const auto times = anim.at("times").get<std::vector<double>>();
  ASSERT_EQ(times.size(), frames);
  EXPECT_DOUBLE_EQ(times.front(), r.rows.front().sim_time);
  EXPECT_DOUBLE_EQ(times.back(), r.rows.back().sim_time);
  const size_t data = frames * 2 * points * 3 * sizeof(float);
  const size_t bytes = fs::file_size(run.out_dir + "/capture_animation.npy");
  ASSERT_GT(bytes, data);
  EXPECT_EQ((bytes - data) % 64, 0u);  // the .npy header, padded to 64 bytes
  EXPECT_LE(bytes - data, 256u);
  EXPECT_TRUE(fs::exists(run.out_dir + "/frames/sim_0.ply"));

  // The same capture claiming a camera delay 0.5 s too long compares the wrong instants.
  const std::string shifted = tmp / "shifted";
  fs::copy(run.capture_dir, shifted, fs::copy_options::recursive);
  nlohmann::json j;
  std::ifstream(shifted + "/capture.json") >> j;
  j["camera_delay"] = 0.56;
  std::ofstream(shifted + "/capture.json") << j.dump();
  ExperimentConfig late = run;
  late.capture_dir = shifted;
  late.out_dir = tmp / "late";
  const ExperimentResult r2 = run_experiment(late);
  EXPECT_GT(mean_cd(r2), 1.5 * mean_cd(r));
}

TEST(SyntheticCapture, IcpRepairsAMiscalibratedCamera) {
  const TempDir tmp("IcpRepairsAMiscalibratedCamera");
  // The clouds were filmed with the true camera; the calibration file of this copy holds one that
  // is 2 degrees and 2 cm off.
  const std::string dir = tmp / "miscalibrated";
  fs::copy(reference_capture(tmp), dir, fs::copy_options::recursive);
  const SyntheticCaptureOptions o;
  Eigen::Isometry3d wrong = o.world_to_camera;
  wrong.prerotate(Eigen::AngleAxisd(2.0 * M_PI / 180, Eigen::Vector3d(0.3, 1, 0.2).normalized()));
  wrong.pretranslate(Eigen::Vector3d(0.012, -0.01, 0.012));
  metrics::write_calibration(dir, wrong.matrix());

  ExperimentConfig run = towel_grasp(250, 0.01);
  run.capture_dir = dir;
  run.out_dir = tmp / "noicp";
  const double cd_wrong = run_experiment(run).summary["cd_l2_s2r"].get<double>();
  run.icp = true;
  run.out_dir = tmp / "icp";
  const ExperimentResult fixed = run_experiment(run);
  ASSERT_TRUE(fixed.summary.contains("icp"));
  EXPECT_TRUE(fixed.summary["icp"]["accepted"].get<bool>());
  // The correction found is about the error put in (2 degrees).
  EXPECT_NEAR(fixed.summary["icp"]["rotation_deg"].get<double>(), 2.0, 0.5);
  const double cd_fixed = fixed.summary["cd_l2_s2r"].get<double>();
  EXPECT_LT(cd_fixed, 0.8 * cd_wrong);
  EXPECT_LT(cd_fixed, 0.01);
  // The translation found is about the error put in too (1.9 cm at the camera; measured at the
  // cloth it differs by the rotation's lever arm, so only roughly).
  EXPECT_GT(fixed.summary["icp"]["translation"].get<double>(), 0.005);

  // With the true calibration, ICP (registering the first frame against the simulation at that
  // frame's instant) must not make things worse.
  run.capture_dir = reference_capture(tmp);
  run.out_dir = tmp / "exact_icp";
  const ExperimentResult exact = run_experiment(run);
  const auto& icp = exact.summary["icp"];
  EXPECT_GT(icp["sim_time"].get<double>(), 0);
  if (icp["accepted"].get<bool>()) {
    EXPECT_LT(icp["rotation_deg"].get<double>(), 0.5);
    EXPECT_LT(icp["translation"].get<double>(), 0.005);
  }
  EXPECT_LT(exact.summary["cd_l2_s2r"].get<double>(), 1.1 * cd_fixed);
}

TEST(SyntheticCapture, RejectsBadOptions) {
  const TempDir tmp("RejectsBadOptions");
  SyntheticCaptureOptions o;
  o.fps = 0;
  ExperimentConfig ref = towel_grasp(300, 0.01);
  EXPECT_THROW(make_synthetic_capture(ref, o, tmp / "bad"), sim::InputError);
}

}  // namespace
}  // namespace gd::experiment
