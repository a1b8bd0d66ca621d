#include "tasks/grippers.h"

#include <spdlog/fmt/fmt.h>
#include <spdlog/fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "sim/demand.h"
#include "sim/log.h"

namespace gd::tasks {

using sim::InputError;

TaskKind task_kind_from_name(const std::string& name) {
  if (name == "grasp") return TaskKind::kGrasp;
  if (name == "fling") return TaskKind::kFling;
  if (name == "fold") return TaskKind::kFold;
  throw InputError(fmt::format("unknown task '{}' (expected grasp, fling or fold)", name));
}

const char* task_name(TaskKind k) {
  switch (k) {
    case TaskKind::kGrasp: return "grasp";
    case TaskKind::kFling: return "fling";
    case TaskKind::kFold: return "fold";
  }
  return "?";
}

void GripperOptions::validate() const {
  auto nonneg = [](double v, const char* name) {
    if (!(std::isfinite(v) && v >= 0)) throw InputError(fmt::format("gripper option {} must be a finite number >= 0", name));
  };
  nonneg(close_threshold, "close_threshold");
  nonneg(jaw_radius, "jaw_radius");
  if (jaw_radius > kMaxJawRadius)
    throw InputError(fmt::format("gripper option jaw_radius must be at most {} m (got {} m)", kMaxJawRadius, jaw_radius));
  if (!(max_reach >= 0)) throw InputError("gripper option max_reach must be >= 0 (infinity allowed)");
  if (!std::isfinite(grab_time)) throw InputError("gripper option grab_time must be finite");
  nonneg(fling_prepare_time, "fling_prepare_time");
  nonneg(fling_wait_time, "fling_wait_time");
  if (mode == GraspMode::kFixedPoint && action == TaskKind::kFling &&
      (shoulder_vertices[0] < 0 || shoulder_vertices[1] < 0))
    throw InputError(
        "fixed-point fling needs shoulder_vertices [left, right] (the garment's shoulder_index), both >= 0");
}

GripperController::GripperController(DualArmTrajectory traj, GripperOptions options)
    : traj_(std::move(traj)), options_(options) {
  options_.validate();
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    if (traj_.arm(a).empty())
      throw InputError(fmt::format("gripper controller: the {} arm's trajectory has no samples", arm_name(a)));
    arm_traj_[static_cast<int>(a)] = std::make_shared<ArmTrajectory>(traj_.arm(a));
  }
}

double GripperController::sim_prepare_time() const {
  if (options_.mode == GraspMode::kFixedPoint && options_.action == TaskKind::kFling)
    return options_.fling_prepare_time + options_.fling_wait_time;
  return 0;
}

void GripperController::append(Arm a, const ArmSample& s) {
  const std::string what = fmt::format("{} arm command", arm_name(a));
  arm_traj_[static_cast<int>(a)]->append(s, what);
  traj_.arm(a).append(s, what);
}

ArmSample GripperController::ee(Arm a, double t) const {
  ArmSample s = arm_traj_[static_cast<int>(a)]->sample(t - sim_prepare_time());
  s.t = t;
  return s;
}

void GripperController::set_group(sim::Scene& scene, int arm, int group) {
  if (group_[arm] >= 0) scene.release(group_[arm]);
  group_[arm] = group;
}

void GripperController::release_all(sim::Scene& scene) {
  for (int a = 0; a < 2; ++a) {
    set_group(scene, a, -1);
    state_[a].held.clear();
    state_[a].closed = false;
  }
}

void GripperController::update(sim::Scene& scene, double t_end) {
  if (!std::isfinite(t_end) || t_end <= scene.time())
    throw InputError(fmt::format("gripper update: step end time {} must be after the scene time {}", t_end, scene.time()));
  if (!started_) {
    initial_ = scene.positions();
    started_ = true;
    if (options_.mode == GraspMode::kFixedPoint) {
      const int n = scene.vertex_count();
      if (options_.action == TaskKind::kFling) {
        for (int a = 0; a < 2; ++a) {
          const int v = options_.shoulder_vertices[a];
          if (v < 0 || v >= n)
            throw InputError(fmt::format("fixed-point fling: {} shoulder vertex {} is out of range [0, {})",
                                         arm_name(static_cast<Arm>(a)), v, n));
          pinned_[a] = v;
        }
      }
      // Grasp and fold choose their pins at grab_time (choose_grab_pins): a streamed trajectory
      // (the service's one command per step) knows the arms' pose at grab_time only then.
    }
  }
  if (options_.mode == GraspMode::kPseudoGrasp) {
    update_pseudo(scene, t_end);
  } else {
    update_fixed(scene, t_end);
  }
}

void GripperController::update_pseudo(sim::Scene& scene, double t_end) {
  const double t_now = scene.time();
  for (int a = 0; a < 2; ++a) {
    const Arm arm = static_cast<Arm>(a);
    const ArmSample s = ee(arm, t_end);
    ArmState& st = state_[a];
    st.ee = make_pose(s.position, s.orientation);
    const bool closed = s.gripper < options_.close_threshold;
    if (!closed && st.closed) {
      if (group_[a] >= 0) {
        events_.push_back({t_now, arm, false, st.held});
        gd::log().debug("t={:.4f}: {} gripper opens, releases {} vertices", t_now, arm_name(arm), st.held.size());
      }
      set_group(scene, a, -1);
      st.held.clear();
    } else if (closed && !st.closed) {
      // The closing moment: take the free vertices within the jaw radius of the end-effector now.
      const ArmSample now = ee(arm, t_now);
      const std::vector<Vec3> x = scene.positions();
      std::vector<char> busy(x.size(), 0);
      for (int v : scene.kinematic_vertices()) busy[v] = 1;
      std::vector<int> take;
      int nearest = -1;
      double nearest_d = std::numeric_limits<double>::infinity();
      for (size_t i = 0; i < x.size(); ++i) {
        if (busy[i]) continue;
        const double d = (x[i] - now.position).norm();
        if (d <= options_.jaw_radius) take.push_back(static_cast<int>(i));
        if (d < nearest_d) nearest_d = d, nearest = static_cast<int>(i);
      }
      if (take.empty() && nearest >= 0 && nearest_d <= options_.max_reach) take.push_back(nearest);
      if (take.empty()) {
        gd::log().debug("t={:.4f}: {} gripper closes on nothing (nearest free vertex {:.3f} m away)", t_now,
                        arm_name(arm), nearest_d);
      } else {
        std::shared_ptr<const ArmTrajectory> traj = arm_traj_[a];  // sees later appends
        const double shift = sim_prepare_time();
        const int g = scene.attach(take, [traj, shift](double t) { return traj->pose(t - shift); });
        set_group(scene, a, g);
        st.held = take;
        events_.push_back({t_now, arm, true, take});
        gd::log().debug("t={:.4f}: {} gripper closes on {} vertices", t_now, arm_name(arm), take.size());
      }
    }
    st.closed = closed;
  }
}

void GripperController::choose_grab_pins() {
  const int n = static_cast<int>(initial_.size());
  for (int a = 0; a < 2; ++a) {
    const Vec3 p = ee(static_cast<Arm>(a), options_.grab_time).position;
    int best = 0;
    double best_d = std::numeric_limits<double>::infinity();
    for (int i = 0; i < n; ++i) {
      const double d = (initial_[i] - p).squaredNorm();
      if (d < best_d) best_d = d, best = i;
    }
    pinned_[a] = best;
    gd::log().debug("fixed point: {} arm pins vertex {} ({:.4f} m from its end-effector at t={})",
                    arm_name(static_cast<Arm>(a)), best, std::sqrt(best_d), options_.grab_time);
  }
  if (pinned_[0] == pinned_[1])
    gd::log().warn("fixed point: both arms pin vertex {} (their end-effectors are closest to it at t={})", pinned_[0],
                   options_.grab_time);
}

void GripperController::update_fixed(sim::Scene& scene, double t_end) {
  // RGBench's rule: at grab_time, the initial vertex nearest each arm's end-effector position then.
  if (options_.action != TaskKind::kFling && pinned_[0] < 0 && scene.time() >= options_.grab_time - 1e-9)
    choose_grab_pins();
  const double t_now = scene.time();
  const bool fling = options_.action == TaskKind::kFling;
  for (int a = 0; a < 2; ++a) {
    const Arm arm = static_cast<Arm>(a);
    ArmState& st = state_[a];
    const int v = pinned_[a];
    Vec3 target;
    bool active = true;
    if (fling) {
      const double prep = options_.fling_prepare_time, wait = options_.fling_wait_time;
      const Vec3 first = arm_traj_[a]->sample(arm_traj_[a]->start_time()).position;
      if (t_end < prep) {
        const double alpha = t_end / prep;
        target = initial_[v] + alpha * (first - initial_[v]);
      } else if (t_end < prep + wait) {
        target = first;
      } else {
        target = ee(arm, t_end).position;
      }
    } else {
      // RGBench overwrites the vertex once sim_time >= grab_time, then steps.
      active = t_now >= options_.grab_time - 1e-9;
      target = ee(arm, t_end).position;
    }
    const ArmSample s = ee(arm, t_end);
    st.ee = make_pose(s.position, s.orientation);
    if (!active) continue;
    if (!st.closed) {
      events_.push_back({t_now, arm, true, {v}});
      gd::log().debug("t={:.4f}: fixed point: {} arm starts driving vertex {}", t_now, arm_name(arm), v);
    }
    set_group(scene, a, scene.set_targets({v}, {target}));
    st.closed = true;
    st.held = {v};
  }
}

}  // namespace gd::tasks
