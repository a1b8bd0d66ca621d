// libFuzzer target: our trajectory JSON, parsed the way SubmitJob parses its `trajectory` with
// trajectory_format "json" (server/service/job_queue.cpp): nlohmann::json::parse, then
// tasks::trajectory_from_json. Expected: a trajectory; a nlohmann::json::exception from the parse
// (not JSON: parse_error, or out_of_range for a number past double's range; the handler answers
// both with INVALID_ARGUMENT); sim::InputError from trajectory_from_json. An accepted trajectory must be
// valid and survive trajectory_to_json -> dump -> parse -> trajectory_from_json unchanged.

#include <nlohmann/json.hpp>

#include "fuzz_common.h"
#include "trajectory_checks.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  gd::fuzz::quiet_logs();
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  nlohmann::json j;
  bool parsed = false;
  gd::fuzz::no_exceptions([&] {
    try {
      j = nlohmann::json::parse(data, data + size);
      parsed = true;
    } catch (const nlohmann::json::exception&) {
    }
  });
  if (!parsed) return 0;
  gd::tasks::DualArmTrajectory t;
  if (!gd::fuzz::input_errors_only([&] { t = gd::tasks::trajectory_from_json(j, "fuzz.json"); })) return 0;
  gd::fuzz::check_trajectory(t);
  gd::tasks::DualArmTrajectory back;
  try {
    back = gd::tasks::trajectory_from_json(nlohmann::json::parse(gd::tasks::trajectory_to_json(t).dump()), "written");
  } catch (const gd::sim::InputError& e) {
    gd::fuzz::fail(std::string("trajectory_to_json wrote a trajectory that trajectory_from_json refuses: ") + e.what());
  }
  gd::fuzz::check_same(t, back, "JSON round trip");
  return 0;
}
