// A generated fold in robot mode (docs/robot.md, "The fold within reach"): pseudo mode turns the
// flap over on a half circle about the fold line, which for a T-shirt rises some 30 cm above the
// table midway and takes the Piper's hands out of reach. Robot mode keeps a half circle within
// reach; else it puts the shoulders down farther short of the hem (a wider fold_margin: a shorter
// stroke, its half circle smaller and nearer the bases) where that brings it within reach; else it
// lowers the turn to the highest the arms follow. It says so in the summary, and keeps a page turn
// the user gave as given.
#include <gtest/gtest.h>

#include <string>

#include "experiment/experiment.h"
#include "experiment/temp_dir.h"
#include "garments/generator.h"
#include "sim/demand.h"
#include "tasks/generators.h"
#include "tasks/task_test_util.h"

namespace gd::experiment {
namespace {

/// The generated T-shirt's fold, its shoulders on the bases' line (x = 0): the one place along x
/// where the Piper reaches both ends of the stroke (docs/robot.md, "Placed within reach").
ExperimentConfig robot_tshirt_fold(const std::string& out) {
  ExperimentConfig c;
  c.garment = "tshirt";
  c.task = "fold";
  c.mode = "robot";
  c.robot.urdf = tasks::testing::piper_urdf();
  c.vertices = 500;
  c.garment_position = sim::Vec3(0.0, 0.0, 0.01);
  c.scene.dt = 0.02;
  c.scene.self_contact = false;  // the reach is under test, not the grip
  c.task_params.time_scale = 0.25;
  c.task_params.start_delay = 0.1;
  c.task_params.settle_duration = 0.1;
  c.settle_after = 0;
  c.plots = false;
  c.out_dir = out;
  return c;
}

// On the bases' line no margin up to a quarter of the length helps (the half circle climbs steeply
// beside the bases): the turn is lowered.
TEST(RobotFoldReach, ThePageTurnIsLoweredToTheHighestTheArmsFollow) {
  if (tasks::testing::piper_urdf().empty()) GTEST_SKIP() << "RGBench's Piper URDF not present (GD_SHARED_DIR)";
  const testing::TempDir dir("fold_reach");
  const ExperimentConfig c = robot_tshirt_fold(dir.str());
  const ExperimentResult r = run_experiment(c);
  ASSERT_FALSE(r.summary["failed"].get<bool>()) << r.summary["failure"];
  const auto& fit = r.summary["robot"]["height_fitted"];
  EXPECT_EQ(fit["task_param"].get<std::string>(), "fold_arc");
  EXPECT_TRUE(fit["lowered"].get<bool>());
  // Pseudo mode's half circle: half the shoulders-to-hem chord, some 30 cm for this T-shirt.
  const garments::Garment g = garments::make_garment("tshirt", c.vertices);
  const double wanted = tasks::fold_page_rise(g, Eigen::Isometry3d::Identity(), c.task_params);
  EXPECT_GT(wanted, 0.25);
  EXPECT_NEAR(fit["wanted_m"].get<double>(), wanted, 1e-4);  // the run's: the garment settled first
  // Lowered, still a turn (not the level translation), and what the run took.
  const double height = fit["height_m"];
  EXPECT_GT(height, 0.05);
  EXPECT_LT(height, wanted - 0.05);
  EXPECT_EQ(r.summary["task_params"]["fold_arc"].get<double>(), height);
  EXPECT_LE(fit["tilt_deg"].get<double>(), fit["tilt_bound_deg"].get<double>());

  // The half circle itself is refused, naming the arm (the fit's bisection is tests/tasks/robot_reach_test.cpp's).
  const testing::TempDir refused_dir("fold_reach_given");
  ExperimentConfig given = robot_tshirt_fold(refused_dir.str());
  given.task_params.fold_arc = wanted;
  try {
    run_experiment(given);
    ADD_FAILURE() << "the half-circle page turn was within the Piper's reach";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot reach its pose"), std::string::npos) << e.what();
  }
}

// With its shoulders 10 cm in front of the bases (the default placement) the T-shirt's half circle
// comes down 0.76 m out and 0.2 m up, out of the Piper's reach; put down some 10 cm short of the hem
// instead of 3 its half circle is within reach, and the flap stays taut.
TEST(RobotFoldReach, TheMarginWidensToTheNarrowestThatBringsTheHalfCircleWithinReach) {
  if (tasks::testing::piper_urdf().empty()) GTEST_SKIP() << "RGBench's Piper URDF not present (GD_SHARED_DIR)";
  const testing::TempDir dir("fold_reach_margin");
  ExperimentConfig c = robot_tshirt_fold(dir.str());
  c.garment_position = sim::Vec3(0.1, 0.0, 0.01);
  const ExperimentResult r = run_experiment(c);
  ASSERT_FALSE(r.summary["failed"].get<bool>()) << r.summary["failure"];
  const auto& fit = r.summary["robot"]["height_fitted"];
  EXPECT_EQ(fit["task_param"].get<std::string>(), "fold_margin");
  EXPECT_FALSE(fit["lowered"].get<bool>());
  EXPECT_EQ(fit["wanted_m"].get<double>(), tasks::TaskParams{}.fold_margin);
  const double margin = fit["height_m"];
  const garments::Garment g = garments::make_garment("tshirt", c.vertices);
  EXPECT_GT(margin, 0.05);
  EXPECT_LE(margin, 0.25 * r.summary["garment_length"].get<double>() + 1e-12);  // still on the bottom half
  EXPECT_EQ(r.summary["task_params"]["fold_margin"].get<double>(), margin);
  EXPECT_EQ(r.summary["task_params"]["fold_arc"].get<double>(), -1.0);  // the half circle
  EXPECT_LE(fit["tilt_deg"].get<double>(), fit["tilt_bound_deg"].get<double>());

  // A margin 1.5 cm narrower (beyond the fit's 1 cm resolution) with its own half circle is refused.
  const testing::TempDir refused_dir("fold_reach_margin_given");
  ExperimentConfig given = robot_tshirt_fold(refused_dir.str());
  given.garment_position = c.garment_position;
  given.task_params.fold_margin = margin - 0.015;
  given.task_params.fold_arc = tasks::fold_page_rise(g, Eigen::Isometry3d::Identity(), given.task_params);
  try {
    run_experiment(given);
    ADD_FAILURE() << "the half circle with a " << given.task_params.fold_margin << " m margin was within reach";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot reach its pose"), std::string::npos) << e.what();
  }
}

// The skirt's half circle is within reach (its hands tilt up to some 40 degrees, more than a
// lift's 30): a fold's turn is lowered only where the arms cannot follow it at all, since a lower
// turn leaves the flap slack.
TEST(RobotFoldReach, AHalfCircleWithinReachIsKept) {
  if (tasks::testing::piper_urdf().empty()) GTEST_SKIP() << "RGBench's Piper URDF not present (GD_SHARED_DIR)";
  const testing::TempDir dir("fold_reach_skirt");
  ExperimentConfig c = robot_tshirt_fold(dir.str());
  c.garment = "skirt";
  c.garment_position = sim::Vec3(0.05, 0.0, 0.01);
  const ExperimentResult r = run_experiment(c);
  ASSERT_FALSE(r.summary["failed"].get<bool>()) << r.summary["failure"];
  const auto& fit = r.summary["robot"]["height_fitted"];
  EXPECT_FALSE(fit["lowered"].get<bool>());
  EXPECT_EQ(fit["height_m"].get<double>(), fit["wanted_m"].get<double>());
  EXPECT_GT(fit["tilt_deg"].get<double>(), 30.0);
  EXPECT_EQ(r.summary["task_params"]["fold_arc"].get<double>(), fit["wanted_m"].get<double>());
}

TEST(RobotFoldReach, APageTurnGivenIsTakenAsGiven) {
  if (tasks::testing::piper_urdf().empty()) GTEST_SKIP() << "RGBench's Piper URDF not present (GD_SHARED_DIR)";
  const testing::TempDir dir("fold_reach_kept");
  ExperimentConfig c = robot_tshirt_fold(dir.str());
  c.task_params.fold_arc = 0.1;
  const ExperimentResult r = run_experiment(c);
  ASSERT_FALSE(r.summary["failed"].get<bool>()) << r.summary["failure"];
  EXPECT_FALSE(r.summary["robot"].contains("height_fitted"));
  EXPECT_EQ(r.summary["task_params"]["fold_arc"].get<double>(), 0.1);
}

}  // namespace
}  // namespace gd::experiment
