#include "tasks/controller.h"

#include <algorithm>
#include <cmath>

namespace gd::tasks {

bool run_until(sim::Scene& scene, TaskController& controller, double t_end,
               const std::function<void(const sim::StepStats&)>& after_step) {
  const double dt = scene.options().dt;
  while (scene.time() < t_end - 1e-9 * std::max(1.0, std::abs(t_end))) {
    if (scene.failed()) return false;
    controller.update(scene, scene.time() + dt);
    const bool ok = scene.step();
    if (after_step) after_step(scene.last_stats());
    if (!ok) return false;
  }
  return !scene.failed();
}

}  // namespace gd::tasks
