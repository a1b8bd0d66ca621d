// libFuzzer target: our trajectory CSV (tasks::parse_trajectory_csv), as SubmitJob's
// `trajectory` with trajectory_format "csv" and `gd run --trajectory FILE.csv` read it.
// Expected: a trajectory, or sim::InputError. An accepted trajectory must be valid and survive
// format_trajectory_csv -> parse_trajectory_csv unchanged.

#include "fuzz_common.h"
#include "trajectory_checks.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  gd::fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  gd::tasks::DualArmTrajectory t;
  if (!gd::fuzz::input_errors_only([&] { t = gd::tasks::parse_trajectory_csv(text, "fuzz.csv"); })) return 0;
  gd::fuzz::check_trajectory(t);
  gd::tasks::DualArmTrajectory back;
  try {
    back = gd::tasks::parse_trajectory_csv(gd::tasks::format_trajectory_csv(t), "written.csv");
  } catch (const gd::sim::InputError& e) {
    gd::fuzz::fail(std::string("format_trajectory_csv wrote a CSV that parse_trajectory_csv refuses: ") + e.what());
  }
  gd::fuzz::check_same(t, back, "CSV round trip");
  return 0;
}
