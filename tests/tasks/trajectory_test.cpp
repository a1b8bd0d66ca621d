// Trajectories: interpolation, validation, our CSV/JSON formats and RGBench's joints CSVs.
#include "tasks/trajectory.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <unistd.h>

#include "sim/demand.h"

namespace gd::tasks {
namespace {

using sim::InputError;
namespace fs = std::filesystem;


Eigen::Quaterniond about_z(double angle) { return Eigen::Quaterniond(Eigen::AngleAxisd(angle, Vec3::UnitZ())); }

/// A fresh scratch directory per test.
fs::path scratch(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("gd_tasks_test_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

void write(const fs::path& p, const std::string& text) {
  std::ofstream out(p);
  out << text;
}

/// The InputError message of f(), or "" if it does not throw one.
template <class F>
std::string error_of(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

#define EXPECT_INPUT_ERROR_MENTIONS(expr, text)                                                      \
  do {                                                                                                \
    const std::string msg_ = error_of([&] { (void)(expr); });                                         \
    EXPECT_NE(msg_, "") << #expr << " did not throw InputError";                                     \
    EXPECT_NE(msg_.find(text), std::string::npos) << "message '" << msg_ << "' lacks '" << (text) << "'"; \
  } while (0)

DualArmTrajectory sample_trajectory() {
  DualArmTrajectory t;
  t.master_start_time = 1753696464.817768;
  t.left = ArmTrajectory({{0.0, Vec3(0.1, 0.2, 0.3), about_z(0.1), 0.035},
                          {0.5, Vec3(0.15, 0.25, 0.35), about_z(0.4), 0.02},
                          {1.25, Vec3(0.2, 0.3, 0.1), Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Vec3(1, 1, 0).normalized())), 0.0}});
  t.right = ArmTrajectory({{0.1, Vec3(0.3, -0.2, 0.1), about_z(-0.2), 0.0},
                           {0.9, Vec3(0.35, -0.25, 0.2), about_z(-0.1), 0.035}});
  return t;
}

void expect_same(const DualArmTrajectory& a, const DualArmTrajectory& b, double tol) {
  EXPECT_NEAR(a.master_start_time, b.master_start_time, 1e-6);
  for (Arm arm : {Arm::kLeft, Arm::kRight}) {
    const auto& sa = a.arm(arm).samples();
    const auto& sb = b.arm(arm).samples();
    ASSERT_EQ(sa.size(), sb.size()) << arm_name(arm);
    for (size_t k = 0; k < sa.size(); ++k) {
      EXPECT_NEAR(sa[k].t, sb[k].t, tol);
      EXPECT_LT((sa[k].position - sb[k].position).norm(), tol);
      EXPECT_LT(sa[k].orientation.angularDistance(sb[k].orientation), tol);
      EXPECT_NEAR(sa[k].gripper, sb[k].gripper, tol);
    }
  }
}

// --- interpolation ---------------------------------------------------------------------------

TEST(ArmTrajectory, InterpolatesLinearlyWithSlerpAndClampsOutsideTheRange) {
  const ArmTrajectory t({{1.0, Vec3(0, 0, 0), about_z(0), 0.035}, {3.0, Vec3(2, 4, -2), about_z(std::numbers::pi / 2), 0.0}});
  const ArmSample m = t.sample(1.5);
  EXPECT_DOUBLE_EQ(m.t, 1.5);
  EXPECT_LT((m.position - Vec3(0.5, 1, -0.5)).norm(), 1e-12);
  EXPECT_NEAR(m.orientation.angularDistance(about_z(std::numbers::pi / 8)), 0, 1e-12);  // SLERP: constant angular rate
  EXPECT_NEAR(m.gripper, 0.035 * 0.75, 1e-12);
  const ArmSample before = t.sample(-5), after = t.sample(10);
  EXPECT_LT(before.position.norm(), 1e-12);
  EXPECT_DOUBLE_EQ(before.gripper, 0.035);
  EXPECT_LT((after.position - Vec3(2, 4, -2)).norm(), 1e-12);
  EXPECT_NEAR(after.orientation.angularDistance(about_z(std::numbers::pi / 2)), 0, 1e-12);
  EXPECT_DOUBLE_EQ(after.gripper, 0.0);
  // Exactly on a sample.
  EXPECT_LT((t.sample(3.0).position - Vec3(2, 4, -2)).norm(), 1e-12);
  const Eigen::Isometry3d p = t.pose(2.0);
  EXPECT_LT((p.translation() - Vec3(1, 2, -1)).norm(), 1e-12);
  EXPECT_LT((p.linear() - about_z(std::numbers::pi / 4).toRotationMatrix()).norm(), 1e-12);
}

TEST(ArmTrajectory, SlerpTakesTheShortArcWhateverTheQuaternionSign) {
  Eigen::Quaterniond q1 = about_z(0.2);
  q1.coeffs() *= -1;  // same rotation, opposite hemisphere
  const ArmTrajectory t({{0, Vec3::Zero(), about_z(0), 0.0}, {1, Vec3::Zero(), q1, 0.0}});
  EXPECT_NEAR(t.sample(0.5).orientation.angularDistance(about_z(0.1)), 0, 1e-12);
}

TEST(ArmTrajectory, RejectsBadSamplesNamingThem) {
  const ArmSample ok{0, Vec3::Zero(), Eigen::Quaterniond::Identity(), 0.0};
  ArmSample b = ok;
  b.t = 0;  // not after sample 0
  EXPECT_INPUT_ERROR_MENTIONS(ArmTrajectory({ok, b}), "sample 1");
  b.t = -1;
  EXPECT_INPUT_ERROR_MENTIONS(ArmTrajectory({ok, b}), "increase");
  b = ok;
  b.t = 1;
  b.position.x() = NAN;
  EXPECT_INPUT_ERROR_MENTIONS(ArmTrajectory({ok, b}), "position");
  b = ok;
  b.t = 1;
  b.orientation = Eigen::Quaterniond(1, 0.2, 0, 0);
  EXPECT_INPUT_ERROR_MENTIONS(ArmTrajectory({ok, b}), "norm");
  b.orientation = Eigen::Quaterniond::Identity();
  b.gripper = INFINITY;
  EXPECT_INPUT_ERROR_MENTIONS(ArmTrajectory({ok, b}), "gripper");
  b.gripper = -0.01;
  EXPECT_INPUT_ERROR_MENTIONS(ArmTrajectory({ok, b}), "negative");
  EXPECT_THROW(ArmTrajectory().sample(0), InputError);
  EXPECT_THROW(ArmTrajectory({ok}).sample(NAN), InputError);
}

TEST(ArmTrajectory, NormalisesNearlyUnitQuaternions) {
  const ArmTrajectory t({{0, Vec3::Zero(), Eigen::Quaterniond(1.0004, 0, 0, 0), 0.0}});
  EXPECT_NEAR(t.samples()[0].orientation.norm(), 1.0, 1e-15);
}

// --- our CSV and JSON ----------------------------------------------------------------------

TEST(TrajectoryCsv, RoundTripsThroughTextAndFiles) {
  const DualArmTrajectory t = sample_trajectory();
  const std::string text = format_trajectory_csv(t);
  EXPECT_EQ(text.find("time,arm,x,y,z,qw,qx,qy,qz,gripper"), text.find('\n') + 1);
  expect_same(t, parse_trajectory_csv(text), 1e-12);
  const fs::path d = scratch("csv");
  write_trajectory_csv((d / "t.csv").string(), t);
  expect_same(t, read_trajectory_csv((d / "t.csv").string()), 1e-12);
  expect_same(t, read_trajectory((d / "t.csv").string()), 1e-12);
  fs::remove_all(d);
}

TEST(TrajectoryCsv, AcceptsAnyColumnOrderInterleavedArmsCommentsAndCrlf) {
  const std::string text =
      "# a comment\r\n"
      "arm,time,gripper,x,y,z,qw,qx,qy,qz\r\n"
      "right, 0.0, 0.035, 0.3, -0.2, 0.1, 1, 0, 0, 0\r\n"
      "left, 0.0, 0.0, 0.1, 0.2, 0.3, 0, 1, 0, 0\r\n"
      "\r\n"
      "right, 1.0, 0.0, 0.4, -0.2, 0.1, 1, 0, 0, 0\r\n"
      "# master_start_time = 12.5\r\n";
  const DualArmTrajectory t = parse_trajectory_csv(text);
  EXPECT_DOUBLE_EQ(t.master_start_time, 12.5);
  ASSERT_EQ(t.left.size(), 1u);
  ASSERT_EQ(t.right.size(), 2u);
  EXPECT_DOUBLE_EQ(t.left.samples()[0].orientation.x(), 1.0);  // w-first: (0, 1, 0, 0)
  EXPECT_DOUBLE_EQ(t.left.samples()[0].orientation.w(), 0.0);
  EXPECT_DOUBLE_EQ(t.right.sample(0.5).position.x(), 0.35);
  EXPECT_DOUBLE_EQ(t.end_time(), 1.0);
}

TEST(TrajectoryCsv, MalformedInputIsAnInputErrorNamingTheLine) {
  const std::string header = "time,arm,x,y,z,qw,qx,qy,qz,gripper\n";
  EXPECT_INPUT_ERROR_MENTIONS(parse_trajectory_csv("time,arm,x,y,z,qw,qx,qy,gripper\n"), "qz");  // missing column
  EXPECT_INPUT_ERROR_MENTIONS(parse_trajectory_csv(header + "0,middle,0,0,0,1,0,0,0,0\n"), "csv:2");
  EXPECT_INPUT_ERROR_MENTIONS(parse_trajectory_csv(header + "0,left,0,nan,0,1,0,0,0,0\n"), "position");
  EXPECT_INPUT_ERROR_MENTIONS(parse_trajectory_csv(header + "0,left,0,abc,0,1,0,0,0,0\n"), "'y' is not a number");
  EXPECT_INPUT_ERROR_MENTIONS(parse_trajectory_csv(header + "0,left,0,,0,1,0,0,0,0\n"), "empty");
  EXPECT_INPUT_ERROR_MENTIONS(parse_trajectory_csv(header + "0,left,0,0,0,1,0,0,0\n"), "expected 10 fields");
  EXPECT_INPUT_ERROR_MENTIONS(parse_trajectory_csv(header + "0,left,0,0,0,2,0,0,0,0\n"), "norm");
  EXPECT_INPUT_ERROR_MENTIONS(
      parse_trajectory_csv(header + "1,left,0,0,0,1,0,0,0,0\n0,right,0,0,0,1,0,0,0,0\n0.5,left,0,0,0,1,0,0,0,0\n"),
      "csv:4");
  EXPECT_INPUT_ERROR_MENTIONS(parse_trajectory_csv("time,arm,x,y,z,qw,qx,qy,qz,gripper,speed\n"), "unknown column 'speed'");
  EXPECT_INPUT_ERROR_MENTIONS(parse_trajectory_csv(header), "no samples");
  EXPECT_INPUT_ERROR_MENTIONS(parse_trajectory_csv("# only a comment\n"), "no header");
  EXPECT_INPUT_ERROR_MENTIONS(read_trajectory_csv("/nonexistent/t.csv"), "cannot open");
  EXPECT_INPUT_ERROR_MENTIONS(read_trajectory("t.yaml"), "extension");
}

TEST(TrajectoryJson, RoundTripsAndRejectsMalformedInput) {
  const DualArmTrajectory t = sample_trajectory();
  const nlohmann::json j = trajectory_to_json(t);
  EXPECT_EQ(j["format"], "gd-trajectory");
  EXPECT_EQ(j["left"][0]["quat_wxyz"][0].get<double>(), t.left.samples()[0].orientation.w());
  expect_same(t, trajectory_from_json(j), 1e-12);
  const fs::path d = scratch("json");
  write_trajectory_json((d / "t.json").string(), t);
  expect_same(t, read_trajectory((d / "t.json").string()), 1e-12);

  nlohmann::json bad = j;
  bad["left"][1].erase("gripper");
  EXPECT_INPUT_ERROR_MENTIONS(trajectory_from_json(bad), "left[1]: missing field 'gripper'");
  bad = j;
  bad["right"][0]["position"] = {1, 2};
  EXPECT_INPUT_ERROR_MENTIONS(trajectory_from_json(bad), "array of 3 numbers");
  bad = j;
  bad["right"][1]["t"] = 0.0;
  EXPECT_INPUT_ERROR_MENTIONS(trajectory_from_json(bad), "right[1]");
  bad = j;
  bad["left"][0]["quat_wxyz"] = {0.5, 0, 0, 0};
  EXPECT_INPUT_ERROR_MENTIONS(trajectory_from_json(bad), "norm");
  bad = j;
  bad["frame"] = "camera";
  EXPECT_INPUT_ERROR_MENTIONS(trajectory_from_json(bad), "frame");
  bad = j;
  bad["speed"] = 1;
  EXPECT_INPUT_ERROR_MENTIONS(trajectory_from_json(bad), "unknown field 'speed'");
  EXPECT_INPUT_ERROR_MENTIONS(trajectory_from_json(nlohmann::json::array()), "object");
  write((d / "broken.json").string(), "{\"left\": [");
  EXPECT_INPUT_ERROR_MENTIONS(read_trajectory_json((d / "broken.json").string()), "not valid JSON");
  fs::remove_all(d);
}

// Robot mode's joint angles ride along in the JSON format: written when a sample has them, read
// back exactly; malformed joints are refused.
TEST(TrajectoryJson, CarriesJointsForRobotMode) {
  DualArmTrajectory t = sample_trajectory();
  std::vector<ArmSample> left = t.left.samples();
  for (size_t i = 0; i < left.size(); ++i) left[i].joints = {0.1 * i, 1.0, -1.0, 0.0, 0.5, -0.25};
  t.left = ArmTrajectory(left, "left");
  const nlohmann::json j = trajectory_to_json(t);
  EXPECT_TRUE(j["left"][0].contains("joints"));
  EXPECT_FALSE(j["right"][0].contains("joints"));
  const DualArmTrajectory back = trajectory_from_json(j);
  for (size_t i = 0; i < left.size(); ++i) EXPECT_EQ(back.left.samples()[i].joints, left[i].joints) << i;
  EXPECT_TRUE(back.right.samples()[0].joints.empty());
  nlohmann::json bad = j;
  bad["left"][0]["joints"] = nlohmann::json::array();
  EXPECT_INPUT_ERROR_MENTIONS(trajectory_from_json(bad), "joints");
  bad["left"][0]["joints"] = {0.1, "x"};
  EXPECT_INPUT_ERROR_MENTIONS(trajectory_from_json(bad), "joints");
}

// --- RGBench joints CSVs ---------------------------------------------------------------------

TEST(RgbenchJoints, ReadsEndPosesIntoTheWorldFrameOnTheMasterTimeBase) {
  const fs::path d = scratch("rgb_read");
  // Two rows per arm as RGBench's csv_data.py writes them.
  write(d / kRgbenchLeftJointsCsv,
        std::string(kRgbenchJointsHeader) +
            "\n1753696464.5,0.1,0.2,0.3,0.4,0.5,0.6,0.035,0.10,0.00,0.20,0.7071067811865476,0,0,0.7071067811865476\n"
            "1753696465.5,0.1,0.2,0.3,0.4,0.5,0.6,0.0,0.20,0.05,0.30,1,0,0,0\n");
  write(d / kRgbenchRightJointsCsv,
        std::string(kRgbenchJointsHeader) +
            "\n1753696464.25,0,0,0,0,0,0,0.01,0.30,0.00,0.10,0,1,0,0\n"
            "1753696465.25,0,0,0,0,0,0,0.02,0.30,0.10,0.10,0,1,0,0\n");
  const DualArmTrajectory t = read_rgbench_joints_dir(d.string());
  EXPECT_DOUBLE_EQ(t.master_start_time, 1753696464.25);  // min first time over both arms
  ASSERT_EQ(t.left.size(), 2u);
  ASSERT_EQ(t.right.size(), 2u);
  EXPECT_NEAR(t.left.samples()[0].t, 0.25, 1e-6);
  EXPECT_NEAR(t.left.samples()[1].t, 1.25, 1e-6);
  EXPECT_NEAR(t.right.samples()[0].t, 0.0, 1e-6);
  EXPECT_NEAR(t.right.samples()[1].t, 1.0, 1e-6);
  // Base offsets: left (0, +0.25, 0), right (0, -0.25, 0).
  EXPECT_LT((t.left.samples()[0].position - Vec3(0.10, 0.25, 0.20)).norm(), 1e-12);
  EXPECT_LT((t.left.samples()[1].position - Vec3(0.20, 0.30, 0.30)).norm(), 1e-12);
  EXPECT_LT((t.right.samples()[1].position - Vec3(0.30, -0.15, 0.10)).norm(), 1e-12);
  // w-first quaternions: (0.707, 0, 0, 0.707) is a quarter turn about z; (0, 1, 0, 0) a half turn about x.
  EXPECT_NEAR(t.left.samples()[0].orientation.angularDistance(about_z(std::numbers::pi / 2)), 0, 1e-9);
  EXPECT_NEAR(t.left.samples()[0].orientation.z(), std::sqrt(0.5), 1e-12);
  EXPECT_NEAR(t.right.samples()[0].orientation.x(), 1.0, 1e-12);
  EXPECT_NEAR(t.right.samples()[0].orientation.w(), 0.0, 1e-12);
  EXPECT_DOUBLE_EQ(t.left.samples()[0].gripper, 0.035);
  EXPECT_DOUBLE_EQ(t.right.samples()[1].gripper, 0.02);
  // pos_1..pos_6 are the joints robot mode drives; a file of zeros throughout recorded none.
  EXPECT_EQ(t.left.samples()[1].joints, (std::vector<double>{0.1, 0.2, 0.3, 0.4, 0.5, 0.6}));
  EXPECT_NEAR(t.left.sample(0.75).joints[2], 0.3, 1e-12);  // interpolated
  EXPECT_TRUE(t.right.samples()[0].joints.empty());
  fs::remove_all(d);
}

TEST(RgbenchJoints, WriteThenReadRoundTrips) {
  const DualArmTrajectory t = sample_trajectory();  // left starts at 0: the master start is kept
  const fs::path d = scratch("rgb_write");
  write_rgbench_joints((d / "joints").string(), t);
  std::ifstream in(d / "joints" / kRgbenchRightJointsCsv);
  std::string header, first;
  std::getline(in, header);
  std::getline(in, first);
  EXPECT_EQ(header, kRgbenchJointsHeader);
  std::vector<double> f;
  std::stringstream row(first);
  for (std::string cell; std::getline(row, cell, ',');) f.push_back(std::stod(cell));
  ASSERT_EQ(f.size(), 15u);
  EXPECT_NEAR(f[0], t.master_start_time + 0.1, 1e-6);  // absolute time
  for (int k = 1; k <= 6; ++k) EXPECT_EQ(f[k], 0.0);    // no IK: zero joints
  EXPECT_EQ(f[7], 0.0);                                 // pos_gripper
  EXPECT_NEAR(f[9], -0.2 + 0.25, 1e-12);                // pos_y in the right base frame
  EXPECT_NEAR(f[11], t.right.samples()[0].orientation.w(), 1e-15);  // orn_w first
  // Absolute Unix times keep about 1e-7 s through the round trip.
  expect_same(t, read_rgbench_joints_dir((d / "joints").string()), 1e-6);
  EXPECT_TRUE(read_rgbench_joints_dir((d / "joints").string()).left.samples()[0].joints.empty());
  // With joints (robot mode's inverse kinematics fills them in) they come back.
  DualArmTrajectory with = t;
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    std::vector<ArmSample> s = with.arm(a).samples();
    for (size_t i = 0; i < s.size(); ++i) s[i].joints = {0.1 * i, 1.5, -0.8, 0.0, 0.9, -0.25};
    with.arm(a) = ArmTrajectory(s);
  }
  write_rgbench_joints((d / "joints2").string(), with);
  const DualArmTrajectory back = read_rgbench_joints_dir((d / "joints2").string());
  for (Arm a : {Arm::kLeft, Arm::kRight})
    for (size_t i = 0; i < back.arm(a).size(); ++i)
      for (size_t k = 0; k < 6; ++k)
        EXPECT_NEAR(back.arm(a).samples()[i].joints[k], with.arm(a).samples()[i].joints[k], 1e-12);
  fs::remove_all(d);
}

TEST(RgbenchJoints, MalformedFilesAreInputErrors) {
  const fs::path d = scratch("rgb_bad");
  const std::string ok_row = "1753696464.5,0,0,0,0,0,0,0.035,0.1,0,0.2,1,0,0,0\n";
  const std::string ok_row2 = "1753696465.5,0,0,0,0,0,0,0.035,0.1,0,0.2,1,0,0,0\n";
  const std::string good = std::string(kRgbenchJointsHeader) + "\n" + ok_row + ok_row2;
  const std::string l = (d / "l.csv").string(), r = (d / "r.csv").string();
  write(r, good);

  write(l, "time,pos_1,pos_2,pos_3,pos_4,pos_5,pos_6,pos_gripper,pos_x,pos_y,pos_z,orn_x,orn_y,orn_z\n" + ok_row);
  EXPECT_INPUT_ERROR_MENTIONS(read_rgbench_joints(l, r), "orn_w");
  write(l, std::string(kRgbenchJointsHeader) + "\n" + "1753696464.5,0,0,0,0,0,0,0.035,nan,0,0.2,1,0,0,0\n");
  EXPECT_INPUT_ERROR_MENTIONS(read_rgbench_joints(l, r), "l.csv:2");
  write(l, std::string(kRgbenchJointsHeader) + "\n" + "1753696464.5,0,0,0,0,0,0,0.035,0.1,0,0.2,1,0,0\n");
  EXPECT_INPUT_ERROR_MENTIONS(read_rgbench_joints(l, r), "expected 15 fields");
  write(l, std::string(kRgbenchJointsHeader) + "\n" + ok_row2 + ok_row);
  EXPECT_INPUT_ERROR_MENTIONS(read_rgbench_joints(l, r), "l.csv:3");
  write(l, std::string(kRgbenchJointsHeader) + "\n" + "1753696464.5,0,0,0,0,0,0,0.035,0.1,0,0.2,0,0,0,0\n");
  EXPECT_INPUT_ERROR_MENTIONS(read_rgbench_joints(l, r), "norm");
  write(l, std::string(kRgbenchJointsHeader) + "\n");
  EXPECT_INPUT_ERROR_MENTIONS(read_rgbench_joints(l, r), "no samples");
  write(l, "");
  EXPECT_INPUT_ERROR_MENTIONS(read_rgbench_joints(l, r), "empty file");
  EXPECT_INPUT_ERROR_MENTIONS(read_rgbench_joints((d / "missing.csv").string(), r), "cannot open");
  DualArmTrajectory one_arm;
  one_arm.left = sample_trajectory().left;
  EXPECT_INPUT_ERROR_MENTIONS(write_rgbench_joints((d / "out").string(), one_arm), "right arm");
  fs::remove_all(d);
}

}  // namespace
}  // namespace gd::tasks
