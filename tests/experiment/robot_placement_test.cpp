// Automatic placement in robot mode (ExperimentConfig::place_within_reach, gd run
// --place-within-reach): the garment is moved to where the arms lift it highest, the summary says
// where it lay and how far it was moved, the run starts from the garment moved there, and the flag
// is refused where it cannot apply.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>

#include "experiment/experiment.h"
#include "experiment/temp_dir.h"
#include "sim/demand.h"
#include "sim/mesh.h"
#include "tasks/task_test_util.h"

namespace gd::experiment {
namespace {

ExperimentConfig robot_towel_grasp(const std::string& out) {
  ExperimentConfig c;
  c.garment = "towel";
  c.task = "grasp";
  c.mode = "robot";
  c.robot.urdf = tasks::testing::piper_urdf();
  c.vertices = 200;
  c.scene.dt = 0.02;
  c.scene.self_contact = false;  // the placement is under test, not the grip
  c.task_params.time_scale = 0.25;
  c.task_params.start_delay = 0.1;
  c.settle_after = 0;
  c.plots = false;
  c.out_dir = out;
  return c;
}

TEST(RobotPlacement, MovesTheGarmentToWhereTheArmsLiftItHigherAndSaysWhere) {
  if (tasks::testing::piper_urdf().empty()) GTEST_SKIP() << "RGBench's Piper URDF not present (GD_SHARED_DIR)";
  const testing::TempDir plain_dir("placement_plain"), placed_dir("placement_placed");
  const ExperimentResult plain = run_experiment(robot_towel_grasp(plain_dir.str()));
  ExperimentConfig c = robot_towel_grasp(placed_dir.str());
  c.place_within_reach = true;
  const ExperimentResult placed = run_experiment(c);
  ASSERT_FALSE(placed.summary["failed"].get<bool>()) << placed.summary["failure"];

  const auto& p = placed.summary["robot"]["placement"];
  const double shift = p["shift_m"];
  EXPECT_EQ(p["given_position_m"][0].get<double>(), c.garment_position.x());
  EXPECT_EQ(placed.summary["garment_position"][0].get<double>(), c.garment_position.x() + shift);
  EXPECT_EQ(placed.summary["garment_position"][1].get<double>(), c.garment_position.y());
  EXPECT_GE(p["placements_within_reach"].get<int>(), 1);
  EXPECT_LE(p["placements_within_reach"].get<int>(), p["placements_tried"].get<int>());
  // The lift fitted where the towel was put, and taken by the run: higher than at the given place.
  const double height = p["height_m"], plain_height = plain.summary["robot"]["height_fitted"]["height_m"];
  EXPECT_EQ(placed.summary["robot"]["height_fitted"]["height_m"].get<double>(), height);
  EXPECT_EQ(placed.summary["task_params"]["lift_height"].get<double>(), height);
  EXPECT_NE(shift, 0.0);
  EXPECT_GT(height, plain_height + 0.01);
  EXPECT_LE(p["tilt_deg"].get<double>(), placed.summary["robot"]["height_fitted"]["tilt_bound_deg"].get<double>());
  // The run started from the towel moved by the shift: its first frame is the plain run's, shifted.
  const sim::Mesh a = sim::read_obj(plain_dir.str() + "/initial.obj");
  const sim::Mesh b = sim::read_obj(placed_dir.str() + "/initial.obj");
  ASSERT_EQ(a.x.size(), b.x.size());
  double worst = 0;
  for (size_t i = 0; i < a.x.size(); ++i) worst = std::max(worst, (b.x[i] - a.x[i] - sim::Vec3(shift, 0, 0)).norm());
  EXPECT_LT(worst, 1e-12);
}

TEST(RobotPlacement, IsRefusedOutsideRobotModeAndWithAGivenTrajectory) {
  const testing::TempDir tmp("placement_refused");
  ExperimentConfig c = robot_towel_grasp(tmp.str());
  c.mode = "pseudo";
  c.robot.urdf.clear();
  c.place_within_reach = true;
  try {
    c.validate();
    FAIL() << "automatic placement was accepted in pseudo mode";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("needs --mode robot"), std::string::npos) << e.what();
  }
  if (tasks::testing::piper_urdf().empty()) return;  // robot mode validates the URDF first
  c.mode = "robot";
  c.robot.urdf = tasks::testing::piper_urdf();
  c.trajectory_file = tmp.str() + "/given.csv";
  try {
    c.validate();
    FAIL() << "automatic placement was accepted with a given trajectory";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("fixes where the garment lies"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace gd::experiment
