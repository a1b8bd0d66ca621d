#pragma once
/// \file
/// What drives a scene's cloth through a task, one step at a time: the pseudo-mode grippers
/// (grippers.h: virtual grasp points) or the robot arms of robot mode (robot_arms.h: URDF arms
/// whose fingers hold the cloth by contact and friction). run_until() steps a scene under one.

#include <functional>
#include <vector>

#include "sim/scene.h"
#include "tasks/frames.h"

namespace gd::tasks {

/// A grasp or release, for logs and tests.
struct GripperEvent {
  double t = 0;           ///< scene time at which it happened (start of the step)
  Arm arm = Arm::kLeft;
  bool grasp = true;      ///< false: release
  std::vector<int> vertices;  ///< pseudo mode: the vertices taken; robot mode: empty
};

class TaskController {
 public:
  virtual ~TaskController() = default;
  /// Sets up the scene (kinematic vertices, collider poses) for the step that ends at scene time
  /// t_end (> scene.time()). Throws sim::InputError for bad input.
  virtual void update(sim::Scene& scene, double t_end) = 0;
  /// Scene time minus this is trajectory time (RGBench's fixed-point fling waits first).
  virtual double sim_prepare_time() const { return 0; }
  /// Scene time at which the trajectory ends.
  virtual double end_time() const = 0;
  /// Grasps and releases so far.
  virtual const std::vector<GripperEvent>& events() const = 0;
};

/// Steps `scene` until its time reaches t_end (overshooting by less than one dt, like RGBench's
/// step_to_time), calling controller.update before every step and `after_step` (when given) after
/// it, also after a step that failed. Returns false if the scene failed.
bool run_until(sim::Scene& scene, TaskController& controller, double t_end,
               const std::function<void(const sim::StepStats&)>& after_step = {});

}  // namespace gd::tasks
