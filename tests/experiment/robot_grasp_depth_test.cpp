// A generated task in robot mode sends the fingertips down to the table however high the grasp
// points lie (docs/robot.md, "Down to the table"): grasp_depth left automatic is 5 mm plus the
// highest grasp landmark's height above the table top, so the higher hand's fingertips aim exactly
// 5 mm below the table and the other's lower still (the table stops both). A skirt's waist corners
// sit 1-4 cm up on its side folds; aimed 5 mm below them the fingers closed in the air. A depth the
// user gives is kept as given.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <fstream>
#include <sstream>
#include <string>

#include "experiment/experiment.h"
#include "experiment/temp_dir.h"
#include "tasks/task_test_util.h"
#include "tasks/trajectory.h"

namespace gd::experiment {
namespace {

ExperimentConfig robot_tshirt_grasp(const std::string& out) {
  ExperimentConfig c;
  c.garment = "tshirt";
  c.task = "grasp";
  c.mode = "robot";
  c.robot.urdf = tasks::testing::piper_urdf();
  c.vertices = 500;
  c.garment_position = sim::Vec3(0.1, 0.0, 0.01);
  c.scene.dt = 0.02;
  c.scene.self_contact = false;  // the plan is under test, not the grip
  c.task_params.time_scale = 0.25;
  c.task_params.start_delay = 0.2;
  c.task_params.lift_height = 0.03;
  c.task_params.hold_duration = 0.1;
  c.settle_after = 0;
  c.plots = false;
  c.out_dir = out;
  return c;
}

/// Each arm's fingertip height (the tool point's z) where the descent ends and the fingers start
/// to close, from the run's trajectory.csv.
std::array<double, 2> fingertips_at_the_close(const std::string& dir) {
  const tasks::DualArmTrajectory t = tasks::read_trajectory(dir + "/trajectory.csv");
  std::array<double, 2> z{};
  for (tasks::Arm a : {tasks::Arm::kLeft, tasks::Arm::kRight}) {
    const auto& s = t.arm(a).samples();
    const auto closing = std::find_if(s.begin(), s.end(), [](const tasks::ArmSample& x) {
      return x.gripper < tasks::kGripperOpen - 1e-9;
    });
    EXPECT_TRUE(closing != s.begin() && closing != s.end());
    z[static_cast<int>(a)] = std::prev(closing)->position.z();
  }
  return z;
}

TEST(RobotGraspDepth, TheFingertipsGoDownToTheTableFromGraspPointsAboveIt) {
  if (tasks::testing::piper_urdf().empty()) GTEST_SKIP() << "RGBench's Piper URDF not present (GD_SHARED_DIR)";
  const testing::TempDir dir("grasp_depth_auto");
  const ExperimentConfig c = robot_tshirt_grasp(dir.str());
  const ExperimentResult r = run_experiment(c);
  ASSERT_FALSE(r.summary["failed"].get<bool>()) << r.summary["failure"];
  // The settled shoulders lie on the cloth, above the table top: the depth is more than 5 mm.
  const double depth = r.summary["task_params"]["grasp_depth"];
  EXPECT_GT(depth, 0.005);
  EXPECT_LT(depth, 0.015);  // a flat T-shirt: its shoulders within a centimetre of the table
  const std::array<double, 2> z = fingertips_at_the_close(dir.str());
  EXPECT_NEAR(std::max(z[0], z[1]), c.scene.table_height - 0.005, 1e-9);  // the higher hand: 5 mm below the table
  EXPECT_LE(std::min(z[0], z[1]), c.scene.table_height - 0.005 + 1e-9);
}

TEST(RobotGraspDepth, ADepthGivenIsKept) {
  if (tasks::testing::piper_urdf().empty()) GTEST_SKIP() << "RGBench's Piper URDF not present (GD_SHARED_DIR)";
  const testing::TempDir dir("grasp_depth_given");
  ExperimentConfig c = robot_tshirt_grasp(dir.str());
  c.task_params.grasp_depth = 0.002;
  const ExperimentResult r = run_experiment(c);
  ASSERT_FALSE(r.summary["failed"].get<bool>()) << r.summary["failure"];
  EXPECT_EQ(r.summary["task_params"]["grasp_depth"].get<double>(), 0.002);
  // 2 mm below shoulders lying on the cloth: above the table top, where the table stops nothing.
  const std::array<double, 2> z = fingertips_at_the_close(dir.str());
  EXPECT_GT(std::min(z[0], z[1]), c.scene.table_height - 0.002);
}

}  // namespace
}  // namespace gd::experiment
