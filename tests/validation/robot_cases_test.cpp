// Robot mode's validation cases as tests (server/validation/robot_cases.h): forward kinematics
// against an independent chain of the URDF through RGBench's joints CSVs, and the Piper's fingers
// holding a strip by friction (and losing it without). They need RGBench's URDF (../shared).
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>

#include "sim/material.h"
#include "validation/robot_cases.h"

namespace gd::validation {
namespace {

std::string piper_urdf() {
  const char* s = std::getenv("GD_SHARED_DIR");
  if (!s || !*s) return "";
  const auto p = std::filesystem::path(s) / "data" / "rgbench" / "piper_with_gripper.urdf";
  return std::filesystem::exists(p) ? p.string() : "";
}

TEST(RobotFk, KdlMatchesTheHandChainedUrdfThroughRgbenchCsvsWithinATenthOfAMillimetre) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  const CaseResult r = robot_fk_case(piper_urdf());
  EXPECT_TRUE(r.pass) << r.detail;
  EXPECT_LT(r.measured, 0.1) << r.detail;
}

class RobotPinch : public ::testing::TestWithParam<std::string> {};

// The lightest and thinnest (silk), a middling (cotton) and the thickest, stiffest (leather)
// fabric all go up with the hand under their own friction and the URDF's 10 N squeeze.
TEST_P(RobotPinch, FingersHoldTheStripWithTheFabricsFriction) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  const CaseResult r = robot_pinch_case(sim::MaterialLibrary::load_default().get(GetParam()), piper_urdf());
  EXPECT_TRUE(r.pass) << r.detail;
}

INSTANTIATE_TEST_SUITE_P(ThreeFabrics, RobotPinch, ::testing::Values("silk", "cotton", "leather"));

// Without friction a limp cotton strip slides out from between the pads and falls.
TEST(RobotPinchCotton, SlipsWithoutFriction) {
  if (piper_urdf().empty()) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  double slipped = 0;
  const CaseResult r = robot_pinch_case(sim::MaterialLibrary::load_default().get("cotton"), piper_urdf(), &slipped);
  EXPECT_LT(slipped, -0.03) << r.detail;
}

}  // namespace
}  // namespace gd::validation
