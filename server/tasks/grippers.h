#pragma once
/// \file
/// Drives a sim::Scene's cloth from a two-arm end-effector trajectory, in one of two modes:
///
/// * kPseudoGrasp (ours, design.md section 6): a gripper is closed while its opening is below
///   `close_threshold`. When it closes it takes the free vertices within `jaw_radius` of the
///   end-effector position (at least the nearest free vertex, if that lies within
///   `max_reach`), skipping vertices the other gripper or anyone else holds; they then follow the
///   end-effector's rigid motion (position and orientation) from that moment:
///   x(t) = EE(t) * EE(t_grasp)^-1 * x(t_grasp). When it opens they are released (free again,
///   velocities kept). Re-grasping takes a fresh set of vertices.
/// * kFixedPoint (RGBench's `fixed_point` pseudo mode, rgbench-format.md section 3), selected per
///   action:
///   - grasp/fold: at `grab_time` (RGBench's evaluate.start_calculate_time) each arm pins the vertex
///     nearest (Euclidean) to its end-effector position at grab_time among the cloth's initial
///     positions (the positions when the controller first saw the scene). From grab_time on that
///     vertex is moved to the interpolated end-effector position every step (position only; the
///     first step makes it jump there). Before grab_time it is free (as in RGBench's MuJoCo
///     environment; its PyBullet one holds it still from t = 0). Nothing is ever released; the
///     gripper columns are ignored.
///   - fling: the pins are the given shoulder vertices [left, right], held from t = 0. Phase 1
///     (t < prepare_time): linear move from the vertex's initial position to the arm's first
///     trajectory position (alpha = t / prepare_time); phase 2 (t < prepare_time + wait_time): hold
///     there; phase 3: follow the trajectory at trajectory time t - prepare_time - wait_time.
///     RGBench compares sim time minus sim_prepare_time() with the capture's times.
///
/// Use: call update(scene, t_end) before every step with the end time of that step, or let
/// run_until() do it.
///
///   GripperController c(traj, GripperOptions{});          // pseudo grasp
///   run_until(*scene, c, traj.end_time());
///   auto held = c.state(Arm::kLeft).held;

#include <array>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "sim/scene.h"
#include "tasks/controller.h"
#include "tasks/trajectory.h"

namespace gd::tasks {

enum class GraspMode {
  kPseudoGrasp,  ///< vertices within the jaw radius follow the closed gripper (ours)
  kFixedPoint,   ///< RGBench's fixed-point semantics (comparable with the paper's numbers)
};

/// The three RGBench actions; fixed-point mode treats fling differently from grasp/fold.
enum class TaskKind { kGrasp, kFling, kFold };

/// "grasp" | "fling" | "fold" -> TaskKind; anything else throws InputError listing the names.
TaskKind task_kind_from_name(const std::string& name);
const char* task_name(TaskKind k);

/// Largest jaw radius of a pseudo grasp, m: wider than any gripper's jaws (a radius of 1e300
/// took the whole garment).
inline constexpr double kMaxJawRadius = 0.2;

struct GripperOptions {
  GraspMode mode = GraspMode::kPseudoGrasp;

  // --- pseudo grasp ---------------------------------------------------------------------------
  double close_threshold = 0.01;  ///< m: the gripper counts as closed while its opening is below this
  double jaw_radius = 0.02;       ///< m: a closing gripper takes the free vertices within this distance (<= kMaxJawRadius)
  /// m: if even the nearest free vertex is farther than this, a closing gripper takes nothing (it
  /// closed in the air). Infinity restores "always at least the nearest vertex".
  double max_reach = 0.05;

  // --- fixed point (RGBench) ----------------------------------------------------------------
  TaskKind action = TaskKind::kGrasp;    ///< which fixed-point semantics (grasp/fold vs fling)
  double grab_time = 0;                  ///< s: grasp/fold pin time (evaluate.start_calculate_time)
  std::array<int, 2> shoulder_vertices{-1, -1};  ///< fling: [left, right] (cloth_params shoulder_index)
  double fling_prepare_time = 5.0;       ///< s: fling phase 1 (main.yaml fling_prepare_time)
  double fling_wait_time = 5.0;          ///< s: fling phase 2 (main.yaml fling_wait_time)

  /// Throws InputError naming a bad value.
  void validate() const;
};

/// What one arm does at the latest update.
struct ArmState {
  bool closed = false;              ///< pseudo: opening < threshold; fixed point: pin active
  std::vector<int> held;            ///< vertices this arm drives during the coming step, ascending
  Eigen::Isometry3d ee = Eigen::Isometry3d::Identity();  ///< end-effector pose at the step's end
};

class GripperController final : public TaskController {
 public:
  /// Validates the options and that both arms have samples (InputError otherwise).
  GripperController(DualArmTrajectory traj, GripperOptions options = {});

  /// Sets up the kinematic vertices of `scene` for the step that ends at scene time t_end
  /// (> scene.time()). Throws InputError for bad shoulder vertices or a t_end not after the
  /// scene's time.
  void update(sim::Scene& scene, double t_end) override;

  /// Scene time minus this is trajectory time: fling_prepare_time + fling_wait_time for a
  /// fixed-point fling, else 0. RGBench's evaluation shifts its comparison by the same amount.
  double sim_prepare_time() const override;
  /// Scene time at which the trajectory ends (its end time + sim_prepare_time()).
  double end_time() const override { return traj_.end_time() + sim_prepare_time(); }

  const ArmState& state(Arm a) const { return state_[static_cast<int>(a)]; }
  const std::vector<GripperEvent>& events() const override { return events_; }
  const DualArmTrajectory& trajectory() const { return traj_; }
  const GripperOptions& options() const { return options_; }

  /// The end-effector sample of an arm at scene time t (trajectory time t - sim_prepare_time()).
  ArmSample ee(Arm a, double t) const;

  /// Appends a sample to an arm's trajectory (trajectory time, after its last sample): live
  /// control, where each step's command extends the trajectory. Held vertices follow the
  /// extended motion. Throws InputError for an invalid or out-of-order sample.
  void append(Arm a, const ArmSample& s);

  /// Releases every group this controller created (the vertices become free).
  void release_all(sim::Scene& scene);

 private:
  void update_pseudo(sim::Scene& scene, double t_end);
  /// Fixed-point grasp/fold: pins, per arm, the initial vertex nearest its end-effector at grab_time.
  void choose_grab_pins();
  void update_fixed(sim::Scene& scene, double t_end);
  void set_group(sim::Scene& scene, int arm, int group);

  DualArmTrajectory traj_;
  std::array<std::shared_ptr<ArmTrajectory>, 2> arm_traj_;  ///< shared with the attach poses
  GripperOptions options_;
  std::array<ArmState, 2> state_;
  std::array<int, 2> group_{-1, -1};     ///< scene group per arm (-1: none)
  std::array<int, 2> pinned_{-1, -1};    ///< fixed point: the pinned vertex per arm
  std::vector<Vec3> initial_;            ///< positions at the first update
  bool started_ = false;
  std::vector<GripperEvent> events_;
};


}  // namespace gd::tasks
