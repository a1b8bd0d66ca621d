// libFuzzer target: RGBench's joints CSV pair (tasks::read_rgbench_joints), as a job with a
// capture reads <capture>/joints/{left,right}_arm_joint_states_and_end_pose.csv. The input is
// the left file, a line "---", then the right file; without that line both files get the whole
// input. Expected: a trajectory, or sim::InputError.

#include <cstring>
#include <string_view>

#include "fuzz_common.h"
#include "trajectory_checks.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  gd::fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view in(reinterpret_cast<const char*>(data), size);
  constexpr std::string_view kSep = "\n---\n";
  const size_t cut = in.find(kSep);
  const std::string_view left = cut == std::string_view::npos ? in : in.substr(0, cut + 1);
  const std::string_view right = cut == std::string_view::npos ? in : in.substr(cut + kSep.size());
  const std::string l = gd::fuzz::write_input(gd::tasks::kRgbenchLeftJointsCsv,
                                              reinterpret_cast<const uint8_t*>(left.data()), left.size());
  const std::string r = gd::fuzz::write_input(gd::tasks::kRgbenchRightJointsCsv,
                                              reinterpret_cast<const uint8_t*>(right.data()), right.size());
  gd::tasks::DualArmTrajectory t;
  if (!gd::fuzz::input_errors_only([&] { t = gd::tasks::read_rgbench_joints(l, r); })) return 0;
  gd::fuzz::check_trajectory(t);
  GD_FUZZ_CHECK(!t.left.empty() && !t.right.empty(), "an arm without samples");
  GD_FUZZ_CHECK(std::min(t.left.start_time(), t.right.start_time()) == 0, "times not relative to the first sample");
  return 0;
}
