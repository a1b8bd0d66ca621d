#include "tasks/robot_reach.h"

#include <fmt/format.h>

#include <cmath>

#include "sim/demand.h"

namespace gd::tasks {

DualArmTrajectory thin_trajectory(const DualArmTrajectory& traj, int stride) {
  GD_DEMAND(stride >= 1, "thin_trajectory needs a stride >= 1");
  DualArmTrajectory out;
  out.master_start_time = traj.master_start_time;
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    const std::vector<ArmSample>& all = traj.arm(a).samples();
    std::vector<ArmSample> kept;
    for (size_t i = 0; i < all.size(); i += stride) kept.push_back(all[i]);
    if (!all.empty() && (all.size() - 1) % stride != 0) kept.push_back(all.back());
    if (!kept.empty()) out.arm(a) = ArmTrajectory(std::move(kept));
  }
  return out;
}

ReachFit fit_height_to_reach(const std::function<DualArmTrajectory(double)>& make, double wanted,
                             const RobotOptions& options, const std::shared_ptr<const robot::ArmModel>& model,
                             double max_tilt, double resolution, int stride) {
  if (stride < 1) throw sim::InputError(fmt::format("the reach fit's stride must be >= 1 (got {})", stride));
  GD_DEMAND(model != nullptr, "fit_height_to_reach needs an arm model");
  if (!std::isfinite(wanted) || wanted < 0)
    throw sim::InputError(
        fmt::format("the height to fit to the arms' reach must be finite and >= 0 m (got {})", wanted));
  if (!std::isfinite(max_tilt) || max_tilt < 0)
    throw sim::InputError(fmt::format("the hands' tilt bound must be finite and >= 0 rad (got {})", max_tilt));
  if (!(resolution > 0)) throw sim::InputError("the reach fit's resolution must be > 0 m");
  ReachFit fit;
  fit.wanted = wanted;
  // The tilt the arms need at h; < 0 where some pose is out of reach (the controller refuses it).
  auto tilt_at = [&](double h, bool refusal_throws) {
    ++fit.trials;
    try {
      const RobotController c(thin_trajectory(make(h), stride), options, model, /*log_ik=*/false);
      return c.ik_max_tilt();
    } catch (const sim::InputError&) {
      if (refusal_throws) throw;
      return -1.0;
    }
  };
  const double floor_tilt = tilt_at(0.0, true);  // the task without its lift: must be within reach
  fit.bound = std::max(max_tilt, floor_tilt);
  auto fits = [&](double t) { return t >= 0 && t <= fit.bound; };
  const double at_wanted = wanted > 0 ? tilt_at(wanted, false) : floor_tilt;
  if (fits(at_wanted)) {
    fit.height = wanted, fit.tilt = at_wanted;
    return fit;
  }
  double lo = 0, hi = wanted, lo_tilt = floor_tilt;  // lo fits, hi does not
  while (hi - lo > resolution) {
    const double mid = 0.5 * (lo + hi);
    const double t = tilt_at(mid, false);
    if (fits(t)) {
      lo = mid, lo_tilt = t;
    } else {
      hi = mid;
    }
  }
  fit.height = lo, fit.tilt = lo_tilt;
  return fit;
}

}  // namespace gd::tasks
