#include "tasks/robot_reach.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "sim/demand.h"

namespace gd::tasks {
namespace {

/// The hands' largest tilt from pointing down over every `stride`-th sample of traj (and each
/// arm's last), solved by a RobotController as the run's; -1 where a pose is out of reach, or the
/// controller's InputError rethrown when `refusal_throws`.
double tilt_needed(const DualArmTrajectory& traj, const RobotOptions& options,
                   const std::shared_ptr<const robot::ArmModel>& model, int stride, bool refusal_throws) {
  try {
    const RobotController c(thin_trajectory(traj, stride), options, model, /*log_ik=*/false);
    return c.ik_max_tilt();
  } catch (const sim::InputError&) {
    if (refusal_throws) throw;
    return -1.0;
  }
}

}  // namespace

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
                             double max_tilt, double resolution, int stride, double lowest) {
  if (stride < 1) throw sim::InputError(fmt::format("the reach fit's stride must be >= 1 (got {})", stride));
  GD_DEMAND(model != nullptr, "fit_height_to_reach needs an arm model");
  if (!std::isfinite(wanted) || wanted < 0)
    throw sim::InputError(
        fmt::format("the height to fit to the arms' reach must be finite and >= 0 m (got {})", wanted));
  if (!std::isfinite(max_tilt) || max_tilt < 0)
    throw sim::InputError(fmt::format("the hands' tilt bound must be finite and >= 0 rad (got {})", max_tilt));
  if (!(resolution > 0)) throw sim::InputError("the reach fit's resolution must be > 0 m");
  if (!std::isfinite(lowest) || lowest < 0 || lowest > wanted)
    throw sim::InputError(fmt::format("the lowest height to fit must lie in [0, {}] m (got {})", wanted, lowest));
  ReachFit fit;
  fit.wanted = wanted;
  // The tilt the arms need at h; < 0 where some pose is out of reach (the controller refuses it).
  auto tilt_at = [&](double h, bool refusal_throws) {
    ++fit.trials;
    return tilt_needed(make(h), options, model, stride, refusal_throws);
  };
  const double floor_tilt = tilt_at(lowest, true);  // the task at its lowest: must be within reach
  constexpr double kDegree = 3.14159265358979323846 / 180;
  fit.bound = floor_tilt > max_tilt ? floor_tilt + kDegree : max_tilt;
  auto fits = [&](double t) { return t >= 0 && t <= fit.bound; };
  const double at_wanted = wanted > lowest ? tilt_at(wanted, false) : floor_tilt;
  if (fits(at_wanted)) {
    fit.height = wanted, fit.tilt = at_wanted;
    return fit;
  }
  double lo = lowest, hi = wanted, lo_tilt = floor_tilt;  // lo fits, hi does not
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

std::vector<double> default_placement_shifts() {
  // Nearest the given placement first (a tie keeps the earlier): 0, +2.5, -2.5, +5, -5 cm, ...
  std::vector<double> shifts{0.0};
  for (int k = 1; k <= 12; ++k) {
    shifts.push_back(0.025 * k);
    if (k <= 4) shifts.push_back(-0.025 * k);
  }
  return shifts;
}

PlacementFit place_within_reach(const std::function<DualArmTrajectory(double, double)>& make, double wanted,
                                bool fit_height, const std::vector<double>& shifts, const RobotOptions& options,
                                const std::shared_ptr<const robot::ArmModel>& model, double max_tilt,
                                double resolution, int stride, double lowest) {
  if (shifts.empty()) throw sim::InputError("automatic placement needs at least one shift to try");
  for (double s : shifts)
    if (!std::isfinite(s)) throw sim::InputError(fmt::format("automatic placement: a shift is not finite ({})", s));
  if (!std::isfinite(max_tilt) || max_tilt < 0)
    throw sim::InputError(fmt::format("the hands' tilt bound must be finite and >= 0 rad (got {})", max_tilt));
  if (!(resolution > 0)) throw sim::InputError("the reach fit's resolution must be > 0 m");
  if (stride < 1) throw sim::InputError(fmt::format("the reach fit's stride must be >= 1 (got {})", stride));
  GD_DEMAND(model != nullptr, "place_within_reach needs an arm model");
  constexpr double kTiltTie = 3.14159265358979323846 / 180;  // a degree
  // Heights are compared on every kScreen-th of the fit's samples (a quarter of the trials' cost),
  // and the winner's height fitted again on the fit's own samples.
  constexpr int kScreen = 4;
  const int screen = fit_height ? kScreen * stride : stride;
  PlacementFit best;
  best.height_fitted = fit_height;
  bool found = false;
  for (double shift : shifts) {
    if (found && fit_height && best.reach.height >= wanted) break;  // the height asked: nothing can beat it
    ++best.candidates;
    ReachFit here;
    if (fit_height) {
      // A shift that cannot carry the best height so far one step higher cannot win: one trial.
      if (found) {
        ++best.trials;
        const double t = tilt_needed(make(shift, best.reach.height + resolution), options, model, screen, false);
        if (t < 0 || t > std::max(max_tilt, best.reach.bound)) {
          if (t >= 0) ++best.reachable;
          continue;
        }
      }
      try {
        here = fit_height_to_reach([&](double h) { return make(shift, h); }, wanted, options, model, max_tilt,
                                   resolution, screen, lowest);
        best.trials += here.trials;
      } catch (const sim::InputError&) {  // out of reach even without the lift
        best.trials += 1;
        continue;
      }
    } else {
      ++best.trials;
      here.wanted = here.height = wanted;
      here.tilt = tilt_needed(make(shift, wanted), options, model, stride, false);
      here.bound = max_tilt;
      here.trials = 1;
      if (here.tilt < 0) continue;
    }
    ++best.reachable;
    const bool wins = !found || (fit_height ? here.height > best.reach.height + 0.5 * resolution
                                            : here.tilt < best.reach.tilt - kTiltTie);
    if (wins) {
      best.shift = shift;
      best.reach = here;
      found = true;
    }
  }
  if (!found) {
    const auto [lo, hi] = std::minmax_element(shifts.begin(), shifts.end());
    throw sim::InputError(fmt::format(
        "automatic placement: the task is out of the arms' reach with the garment moved anywhere from {:+.3f} to "
        "{:+.3f} m along x; place it with --garment-position",
        *lo, *hi));
  }
  if (fit_height && screen != stride) {  // the winner's height on the fit's own samples
    const ReachFit fine = fit_height_to_reach([&](double h) { return make(best.shift, h); }, wanted, options, model,
                                              max_tilt, resolution, stride, lowest);
    best.trials += fine.trials;
    best.reach = fine;
  }
  return best;
}

}  // namespace gd::tasks
