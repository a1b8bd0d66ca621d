#include "tasks/robot_arms.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>

#include "sim/contact/collider.h"
#include "sim/contact/cuts.h"
#include "sim/demand.h"
#include "sim/log.h"

namespace gd::tasks {

using sim::InputError;

namespace {

constexpr double kMaxFingerSpeed = 0.1;        ///< m/s: cap on the URDF's finger velocity limit
constexpr double kIkPositionTolerance = 1e-3;  ///< m: how near inverse kinematics must put the tool
constexpr double kIkJumpWarning = 0.5;         ///< rad between neighbouring samples that gets a warning
/// rad: how much closer to a pose the hand turned half a turn must come before it is preferred
/// (resolve()); a tie keeps the trajectory's own orientation.
constexpr double kHalfTurnPreference = 1e-3;
/// Default lowest pad point above the table, in contact distances. Lying cloth rests at half the
/// contact distance: pads whose bottom is within ~0.3 of it catch the cloth with their faces'
/// lower edges and bunch it up between them (0.6-0.8 grasp in tests/tasks/robot_arms_test.cpp);
/// higher, the cloth slips under them; at 0.5 or lower a pad landing on the cloth leaves it no
/// room above the table.
constexpr double kTableClearance = 0.7;

Eigen::Isometry3d base_pose(Arm a) {
  Eigen::Isometry3d b = Eigen::Isometry3d::Identity();
  b.translation() = base_offset(a);
  return b;
}

Eigen::VectorXd to_vector(const std::vector<double>& q) { return Eigen::Map<const Eigen::VectorXd>(q.data(), q.size()); }

}  // namespace

void RobotOptions::validate(bool need_urdf) const {
  if (need_urdf && urdf.empty()) throw InputError("robot mode needs the arms' URDF (--urdf PATH, e.g. RGBench's piper_with_gripper.urdf)");
  auto check = [](double v, const char* name) {
    if (!std::isfinite(v)) throw InputError(fmt::format("robot option {} must be finite", name));
  };
  check(finger_friction, "finger_friction");
  check(grip_force, "grip_force");
  check(finger_speed, "finger_speed");
  check(table_clearance, "table_clearance");
  check(max_tilt, "max_tilt");
  if (max_tilt < 0) throw InputError("robot option max_tilt must be >= 0 rad");
  check(lift_max_tilt, "lift_max_tilt");
  if (lift_max_tilt < 0) throw InputError("robot option lift_max_tilt must be >= 0 rad");
  if (!(pad_stiffness >= 0) || !std::isfinite(pad_stiffness))
    throw InputError(fmt::format("robot option pad_stiffness must be a finite number >= 0 N/m (0: pads wait where "
                                 "the cloth stops them), got {}", pad_stiffness));
  if (grip_force == 0) throw InputError("robot option grip_force must be > 0 N (or < 0 for the URDF's effort limit)");
  for (size_t k = 0; k < grip_force_schedule.size(); ++k) {
    const auto [t, f] = grip_force_schedule[k];
    if (!std::isfinite(t) || !std::isfinite(f) || f < 0)
      throw InputError(fmt::format("robot option grip_force_schedule: knot {} ({} s, {} N) needs a finite time and a "
                                   "finite force >= 0", k, t, f));
    if (k > 0 && !(t > grip_force_schedule[k - 1][0]))
      throw InputError(fmt::format("robot option grip_force_schedule: knot {} at {} s is not after the one before ({} s); "
                                   "give the knots in increasing time", k, t, grip_force_schedule[k - 1][0]));
  }
  if (!grip_force_schedule.empty() &&
      std::all_of(grip_force_schedule.begin(), grip_force_schedule.end(), [](const auto& k) { return k[1] == 0; }))
    throw InputError("robot option grip_force_schedule: every knot is 0 N; the fingers could never hold");
  if (finger_speed == 0) throw InputError("robot option finger_speed must be > 0 m/s (or < 0 for the URDF's limit)");
  if (!tool_to_ee.allFinite() || (tool_to_ee.transpose() * tool_to_ee - Eigen::Matrix3d::Identity()).norm() > 1e-6 ||
      tool_to_ee.determinant() < 0)
    throw InputError("robot option tool_to_ee must be a rotation matrix");
  if (!arm.pad.half_extents.allFinite() || arm.pad.half_extents.minCoeff() <= 0 || !arm.pad.center.allFinite())
    throw InputError("robot finger pad: half extents must be finite and > 0, the centre finite");
}

namespace {
/// A collider's pose at time t of a step [t0, t1] from its poses at the start and end (blend_pose).
Eigen::Isometry3d pose_over_step(const std::array<Eigen::Isometry3d, 2>& p, double t0, double t1, double t) {
  const double u = t1 > t0 ? std::clamp((t - t0) / (t1 - t0), 0.0, 1.0) : 1.0;
  return blend_pose(p[0], p[1], u);
}
}  // namespace

/// Each pad's pose at the start and end of the coming step (shared with the colliders).
struct RobotController::PadPoses {
  double t0 = 0, t1 = 0;
  std::array<std::array<Eigen::Isometry3d, 2>, 4> pose;  ///< [arm * 2 + finger][start, end]
  std::array<Eigen::Isometry3d, 4> target;                ///< where each pad was asked to be at t1

  Eigen::Isometry3d at(int pad, double t) const { return pose_over_step(pose[pad], t0, t1, t); }
};

/// The links' colliders' poses at a step's start and end (attach_links, update).
struct RobotController::LinkPoses {
  double t0 = 0, t1 = 0;
  std::vector<std::array<Eigen::Isometry3d, 2>> pose;  ///< per link collider: [start, end]

  Eigen::Isometry3d at(int k, double t) const { return pose_over_step(pose[k], t0, t1, t); }
};

Eigen::Isometry3d blend_pose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double u) {
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  out.linear() = Eigen::Quaterniond(a.linear()).slerp(u, Eigen::Quaterniond(b.linear())).normalized().toRotationMatrix();
  out.translation() = (1 - u) * a.translation() + u * b.translation();
  return out;
}

Eigen::Isometry3d pad_catch_up(const Eigen::Isometry3d& at, const Eigen::Isometry3d& last_target,
                               const Eigen::Isometry3d& target, double max_extra) {
  const double own = (target.translation() - last_target.translation()).norm();
  const double move = (target.translation() - at.translation()).norm();
  const double reach = own + max_extra;
  return move > reach ? blend_pose(at, target, reach / move) : target;
}

namespace {

/// RobotArmState::grip after an update: `released`, the first grasp is over.
Grip grip_now(const RobotArmState& st, bool closing, bool released, double squeeze, double limit) {
  if (!closing) return Grip::kOpen;
  if (released) return squeeze >= RobotController::kHoldFraction * limit && limit > 0 ? Grip::kHeld : Grip::kClosing;
  if (st.lost_at >= 0) return Grip::kLost;
  if (st.held_at >= 0) return Grip::kHeld;
  return st.missed_at >= 0 ? Grip::kMissed : Grip::kClosing;
}

}  // namespace

bool RobotController::grip_asked(double command, double open_ref, double gripper_max) {
  const double ref = open_ref >= kMinOpenFraction * gripper_max ? open_ref : gripper_max;
  return command < 0.5 * ref;
}

double finger_joint_step(const FingerJointInput& in) {
  const double g = in.opening;
  if (in.command < g) {
    // Closing: full speed until the squeeze passes 10% of the limit (below it, a pad pressing on
    // cloth from above or pushing it aside says nothing of the grip); then steps of half the way
    // to the limit by the secant stiffness (the barrier's force rises from 0 to the limit within
    // the contact distance, so fixed steps would swing past it), or 5% of the contact distance
    // while the stiffness is unknown. Above the limit the fingers give way the same way, but not
    // while the pads stand stopped short: opening on that squeeze let the T-shirt's fling slip out
    // of a hand after the turn (docs/robot.md, "Holding while the pads are stopped short").
    const double error = in.limit - std::max(0.0, in.squeeze);
    double step = in.max_step;
    if (in.squeeze > 0.1 * in.limit)
      step = std::min(step, in.stiffness > 0 ? 0.5 * std::abs(error) / in.stiffness : 0.05 * in.dhat);
    if (error < 0 && in.reached < 1.0) step = 0;
    return error >= 0 ? std::max(in.command, g - step) : std::min(in.opening_max, g + step);
  }
  if (in.command > g) {
    // Opening against cloth that presses the pads' outer faces inwards (cloth folded round the
    // fingers, or lying beside them on the table): the same joint, so the same force limit. Full
    // speed while the push is below 10% of the limit, then steps of 5% of the contact distance
    // (the barrier's force rises from 0 to any value within it); the fingers stop at the limit and
    // give way (close) above it, down to the floor below. A kinematic pad that opened regardless
    // pressed the cloth it swept against the table and the layers beneath with hundreds of
    // newtons, until the cloth ended inside a pad (docs/robot.md, "Opening against the cloth").
    const double resist = std::max(0.0, -in.squeeze);
    double step = in.max_step;
    if (resist > 0.1 * in.limit) step = std::min(step, 0.05 * in.dhat);
    return resist <= in.limit ? std::min(in.command, g + step) : std::max(0.0, g - step);
  }
  return g;
}

RobotController::RobotController(DualArmTrajectory traj, RobotOptions options)
    : RobotController(std::move(traj), options, [&] {
        options.validate();  // the URDF's path first of all
        return std::make_shared<const robot::ArmModel>(robot::ArmModel::load(options.urdf, options.arm));
      }()) {}

RobotController::RobotController(DualArmTrajectory traj, RobotOptions options,
                                 std::shared_ptr<const robot::ArmModel> model, bool log_ik)
    : traj_(std::move(traj)), options_(std::move(options)), model_(std::move(model)), log_ik_(log_ik),
      poses_(std::make_shared<PadPoses>()), link_poses_(std::make_shared<LinkPoses>()) {
  GD_DEMAND(model_ != nullptr, "RobotController needs an arm model");
  options_.validate(false);
  const robot::ArmModel& m = *model_;
  grip_force_ = options_.grip_force > 0 ? options_.grip_force : m.finger_limits().effort;
  for (const auto& k : options_.grip_force_schedule) grip_force_ = std::max(grip_force_, k[1]);  // the pads' stiffness
  for (RobotArmState& st : state_) st.grip_force = grip_force_at(0.0);
  if (!(grip_force_ > 0))
    throw InputError(fmt::format("URDF {}: finger joint '{}' gives no effort limit; set the grip force", options_.urdf,
                                 options_.arm.finger_joints[0]));
  finger_speed_ = options_.finger_speed > 0 ? options_.finger_speed
                                            : std::min(kMaxFingerSpeed, m.finger_limits().velocity > 0
                                                                            ? m.finger_limits().velocity
                                                                            : kMaxFingerSpeed);
  // Joints for every sample: the recorded ones, or inverse kinematics along the trajectory, each
  // sample seeded by the previous answer.
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    const ArmTrajectory& arm = traj_.arm(a);
    if (arm.empty()) throw InputError(fmt::format("robot mode: the {} arm has no trajectory samples", arm_name(a)));
    std::vector<ArmSample> samples = arm.samples();
    for (size_t i = 0; i < samples.size(); ++i) {
      const bool solve = samples[i].joints.empty();
      const std::vector<double> given = samples[i].joints;
      // Recorded joints (a real arm's, whose limits may differ a little from the URDF's) are
      // clamped to the URDF's limits and counted, not refused.
      samples[i] = resolve(a, samples[i], i > 0 ? samples[i - 1].joints : std::vector<double>{}, true);
      if (solve) {
        ++ik_solved_;
        continue;
      }
      double excess = 0;
      for (size_t k = 0; k < given.size(); ++k) excess = std::max(excess, std::abs(given[k] - samples[i].joints[k]));
      if (excess > kJointLimitSlack) {
        ++joints_clamped_;
        joint_clamp_max_ = std::max(joint_clamp_max_, excess);
      }
    }
    // The state before the first step: the first sample's joints and opening.
    RobotArmState& st = state_[static_cast<int>(a)];
    st.joints = samples.front().joints;
    st.gripper_command = std::clamp(samples.front().gripper, 0.0, m.gripper_max());
    st.gripper = st.gripper_command;
    traj_.arm(a) = ArmTrajectory(std::move(samples), fmt::format("{} arm", arm_name(a)));
  }
  if (joints_clamped_ > 0)
    gd::log().warn("robot mode: {} recorded samples have joints outside the URDF's limits (by up to {:.4f}); clamped "
                   "to the limits",
                   joints_clamped_, joint_clamp_max_);
  if (ik_solved_ > 0 && log_ik_)
    gd::log().info("robot mode: inverse kinematics for {} trajectory samples (orientation missed by up to {:.1f} deg)",
                   ik_solved_, ik_max_tilt_ * 180 / 3.14159265358979323846);
}

ArmSample RobotController::resolve(Arm a, ArmSample s, const std::vector<double>& seed_joints,
                                   bool clamp_to_limits) const {
  const robot::ArmModel& m = *model_;
  const int dofs = m.arm_dofs();
  if (!s.joints.empty()) {
    if (static_cast<int>(s.joints.size()) != dofs)
      throw InputError(fmt::format("robot mode: the {} arm's sample at t={:.4f} s has {} joint values, the URDF's "
                                   "arm has {} ({})",
                                   arm_name(a), s.t, s.joints.size(), dofs, fmt::join(m.arm_joint_names(), ", ")));
    for (int k = 0; k < dofs; ++k)
      if (!std::isfinite(s.joints[k]))
        throw InputError(fmt::format("robot mode: the {} arm's sample at t={:.4f} s has a non-finite value for {}",
                                     arm_name(a), s.t, m.arm_joint_names()[k]));
    for (int k = 0; k < dofs; ++k) {
      const robot::JointLimits& l = m.arm_limits()[k];
      if (!clamp_to_limits && (s.joints[k] < l.lower - kJointLimitSlack || s.joints[k] > l.upper + kJointLimitSlack))
        throw InputError(fmt::format("robot mode: the {} arm's {} at t={:.4f} s is {:.4f}, outside the URDF's limits "
                                     "[{:.4f}, {:.4f}]; keep the joints within them",
                                     arm_name(a), m.arm_joint_names()[k], s.t, s.joints[k], l.lower, l.upper));
      s.joints[k] = std::clamp(s.joints[k], l.lower, l.upper);
    }
    return s;
  }
  Eigen::VectorXd seed(dofs);
  if (static_cast<int>(seed_joints.size()) == dofs) {
    seed = to_vector(seed_joints);
  } else {
    for (int k = 0; k < dofs; ++k) {
      const robot::JointLimits& l = m.arm_limits()[k];
      seed[k] = std::clamp(0.0, l.lower, l.upper);
    }
  }
  if (!s.position.allFinite() || !s.orientation.coeffs().allFinite())
    throw InputError(fmt::format("robot mode: the {} arm's sample at t={:.4f} s has a non-finite pose", arm_name(a), s.t));
  const Eigen::Isometry3d tool = base_pose(a).inverse() * make_pose(s.position, s.orientation.normalized());
  // The tool's pose, or the same turned half a turn about its approach axis: a parallel gripper's
  // two fingers are interchangeable, so both hold the cloth alike, but one may lie outside the
  // wrist's limits (the Piper's joint6 stops at -120 degrees: a left arm reaching across its
  // base to the garment's corner could not square its fingers with the garment's edge, tilted
  // the hand, lifted it off the table by a millimetre more and closed above the cloth). The
  // arm's first solved pose decides (both tried; the turned one only when it comes closer), and
  // the arm keeps that way round for the whole trajectory, so its wrist never flips in between.
  auto solve = [&](bool turned) {
    Eigen::Isometry3d ee = tool;
    if (turned) ee.linear() = ee.linear() * Eigen::AngleAxisd(M_PI, Vec3::UnitZ()).toRotationMatrix();
    ee.linear() = ee.linear() * options_.tool_to_ee;
    return m.ik_position_first(ee, seed, options_.max_tilt, kIkPositionTolerance);
  };
  int& turned = half_turned_[static_cast<int>(a)];
  robot::IkResult r;
  if (turned < 0) {
    const robot::IkResult plain = solve(false), half = solve(true);
    const bool take_half = half.ok && (!plain.ok || half.rotation_error < plain.rotation_error - kHalfTurnPreference);
    turned = take_half ? 1 : 0;
    r = take_half ? half : plain;
  } else {
    r = solve(turned == 1);
  }
  if (!r.ok)
    throw InputError(fmt::format("robot mode: the {} arm cannot reach its pose at t={:.3f} s (world position "
                                 "{:.3f}, {:.3f}, {:.3f}): {:.1f} mm and {:.2f} deg away at best; move the task "
                                 "within reach (a lower lift or fling height, a fold's wider fold_margin or lower "
                                 "fold_arc, or the garment nearer the arms' bases)",
                                 arm_name(a), s.t, s.position.x(), s.position.y(), s.position.z(),
                                 1e3 * r.position_error, r.rotation_error * 180 / 3.14159265358979323846));
  s.joints.assign(r.q.data(), r.q.data() + dofs);
  // A jump between neighbouring samples (another branch of the inverse kinematics) would sweep
  // the pads through the cloth within one step.
  if (log_ik_ && static_cast<int>(seed_joints.size()) == dofs && (r.q - seed).cwiseAbs().maxCoeff() > kIkJumpWarning)
    gd::log().warn("robot mode: the {} arm's joints jump by {:.2f} rad up to t={:.3f} s (inverse kinematics changed "
                   "branch); sample the trajectory more finely",
                   arm_name(a), (r.q - seed).cwiseAbs().maxCoeff(), s.t);
  ik_max_tilt_ = std::max(ik_max_tilt_, r.rotation_error);
  return s;
}

void RobotController::append(Arm a, const ArmSample& s) {
  ArmTrajectory& arm = traj_.arm(a);
  const bool solve = s.joints.empty();
  ArmSample r = resolve(a, s, arm.empty() ? std::vector<double>{} : arm.samples().back().joints);
  arm.append(r, fmt::format("{} arm command", arm_name(a)));
  if (solve) ++ik_solved_;
}

std::array<Eigen::Isometry3d, 2> RobotController::finger_poses(Arm a, const std::vector<double>& joints,
                                                                double gripper) const {
  const Eigen::VectorXd q = to_vector(joints);
  std::array<Eigen::Isometry3d, 2> out;
  for (int f = 0; f < 2; ++f) out[f] = base_pose(a) * model_->link_pose(model_->finger_links()[f], q, gripper);
  return out;
}

Eigen::Isometry3d RobotController::ee_world(Arm a) const {
  const RobotArmState& st = state_[static_cast<int>(a)];
  return base_pose(a) * model_->ee_pose(to_vector(st.joints));
}

std::vector<Vec3> RobotController::chain_world(Arm a) const {
  const Eigen::Isometry3d base = base_pose(a);
  std::vector<Vec3> out;
  for (const Eigen::Vector3d& p : model_->chain_points(to_vector(state_[static_cast<int>(a)].joints)))
    out.push_back(base * p);
  return out;
}

std::array<Eigen::Isometry3d, 4> RobotController::pad_poses(double t) const {
  std::array<Eigen::Isometry3d, 4> out;
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
  offset.translation() = options_.arm.pad.center;
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    const RobotArmState& st = state_[static_cast<int>(a)];
    const auto fp = finger_poses(a, st.joints, st.gripper);
    for (int f = 0; f < 2; ++f) {
      const int k = 2 * static_cast<int>(a) + f;
      out[k] = attached_ ? poses_->at(k, t) : fp[f] * offset;
    }
  }
  return out;
}

void RobotController::attach(sim::Scene& scene) {
  const double t = scene.time();
  const double mu = options_.finger_friction >= 0 ? options_.finger_friction : scene.material().friction;
  const robot::FingerPad& pad = options_.arm.pad;
  poses_->t0 = poses_->t1 = t;
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    RobotArmState& st = state_[static_cast<int>(a)];
    const ArmSample s = traj_.arm(a).sample(t);
    st.joints = s.joints;
    st.gripper_command = std::clamp(s.gripper, 0.0, model_->gripper_max());
    st.gripper = st.gripper_command;
    const auto fp = finger_poses(a, st.joints, st.gripper);
    for (int f = 0; f < 2; ++f) {
      const int k = 2 * static_cast<int>(a) + f;
      // The pad's box sits off its link frame's origin.
      Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
      offset.translation() = pad.center;
      poses_->pose[k] = {fp[f] * offset, fp[f] * offset};
      poses_->target[k] = fp[f] * offset;
      sim::Collider c = sim::Collider::box(pad.half_extents);
      std::shared_ptr<PadPoses> poses = poses_;
      c.set_pose([poses, k](double time) { return poses->at(k, time); });
      c.set_friction(mu);
      c.set_yielding(true);  // stops short where the cloth it pushes cannot get out of the way in time
      if (options_.rigid_hands) c.set_yield_group(static_cast<int>(a));  // and with it its hand's other pad
      // The barrier's stiffness as calibrated for the table balances a vertex's weight at half
      // the contact distance; a pad must carry the grip force there instead, spread over the
      // cloth under its face: the grip force over the weight of that much cloth.
      const double face = 4 * pad.half_extents.x() * pad.half_extents.y();
      c.set_stiffness_scale(std::max(1.0, grip_force_ / (scene.material().density * face * sim::kGravity)));
      st.colliders[f] = scene.add_collider(std::move(c));
    }
  }
  if (options_.link_colliders) attach_links(scene, mu);
  attached_ = true;
}

Eigen::Isometry3d RobotController::shape_pose(Arm a, const robot::LinkShape& s, const Eigen::VectorXd& q, double g,
                                              double lift) const {
  Eigen::Isometry3d p = base_pose(a) * model_->link_pose(s.link, q, g) * s.origin;
  if (model_->is_hand_link(s.link)) p.translation().z() += lift;
  return p;
}

std::array<sim::ColliderCuts, 4> RobotController::pad_cuts(const sim::Scene& scene) const {
  std::array<sim::ColliderCuts, 4> out;
  const sim::Collider box = sim::Collider::box(options_.arm.pad.half_extents);
  const std::vector<Vec3> x = scene.positions();
  for (int k = 0; k < 4; ++k) out[k] = sim::collider_cuts(box, poses_->at(k, scene.time()), x, scene.mesh().tris);
  return out;
}

void RobotController::attach_links(sim::Scene& scene, double mu) {
  const double t = scene.time();
  link_poses_->t0 = link_poses_->t1 = t;
  const auto& fingers = model_->finger_links();
  const std::vector<robot::LinkShape>& shapes = model_->link_shapes();
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    RobotArmState& st = state_[static_cast<int>(a)];
    const Eigen::VectorXd q = to_vector(st.joints);
    for (int i = 0; i < static_cast<int>(shapes.size()); ++i) {
      const robot::LinkShape& s = shapes[i];
      if (s.link == fingers[0] || s.link == fingers[1]) continue;  // the pads hold the cloth
      sim::Collider c = s.kind == robot::LinkShape::Kind::kBox      ? sim::Collider::box(s.half_extents)
                        : s.kind == robot::LinkShape::Kind::kSphere ? sim::Collider::capsule(s.radius, 0)
                                                                     : sim::Collider::mesh(s.vertices, s.triangles);
      const int k = static_cast<int>(link_poses_->pose.size());
      const Eigen::Isometry3d p = shape_pose(a, s, q, st.gripper, 0);
      link_poses_->pose.push_back({p, p});
      std::shared_ptr<LinkPoses> poses = link_poses_;
      c.set_pose([poses, k](double time) { return poses->at(k, time); });
      c.set_friction(mu);
      gd::log().debug("robot mode: {} arm link {}: {} ({} triangles)", arm_name(a), s.link, s.source, s.triangles.size());
      st.link_colliders.push_back(scene.add_collider(std::move(c)));
      link_shape_of_.emplace_back(a, i);
    }
  }
  if (!link_shape_of_.empty())
    gd::log().info("robot mode: {} link colliders from the URDF's collision geometry", link_shape_of_.size());
  for (const std::string& uri : model_->skipped_meshes())
    gd::log().debug("robot mode: link mesh {} not found on the package path; that link has no collider", uri);
}

double RobotController::grip_force_at(double t) const {
  const auto& k = options_.grip_force_schedule;
  if (k.empty()) return grip_force_;
  if (t <= k.front()[0]) return k.front()[1];
  if (t >= k.back()[0]) return k.back()[1];
  const auto hi = std::upper_bound(k.begin(), k.end(), t, [](double v, const auto& knot) { return v < knot[0]; });
  const auto lo = hi - 1;
  const double u = (t - (*lo)[0]) / ((*hi)[0] - (*lo)[0]);
  return (*lo)[1] + u * ((*hi)[1] - (*lo)[1]);
}

void RobotController::update(sim::Scene& scene, double t_end) {
  const double t0 = scene.time();
  if (!(t_end > t0)) throw InputError(fmt::format("robot mode: step end {} is not after the scene time {}", t_end, t0));
  if (!attached_) attach(scene);
  const sim::SceneOptions& so = scene.options();
  const double dhat = sim::effective_contact_distance(so, scene.material().thickness);
  const double clearance = options_.table_clearance >= 0 ? options_.table_clearance : kTableClearance * dhat;
  const robot::FingerPad& pad = options_.arm.pad;
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
  offset.translation() = pad.center;
  const double dt = t_end - t0;
  const std::vector<int> pads = {state_[0].colliders[0], state_[0].colliders[1], state_[1].colliders[0],
                                 state_[1].colliders[1]};
  // Each pad where it got to: one that stopped short of its pose last step (the cloth it pushed
  // could not get out of the way in time) starts this step from there.
  const std::vector<double> reached = scene.collider_reached(pads);
  for (int k = 0; k < 4; ++k)
    if (reached[k] < 1.0) poses_->pose[k][1] = poses_->at(k, poses_->t0 + reached[k] * (poses_->t1 - poses_->t0));
  // The cloth's push on the four pads now along their opening directions (each pad's z), split
  // into the cloth on their inner faces (opening them) and round their outer faces (closing them).
  const std::vector<sim::ColliderPush> pushes = scene.collider_pushes(pads);
  const std::array<sim::ColliderCuts, 4> cuts = pad_cuts(scene);
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    const int ai = static_cast<int>(a);
    RobotArmState& st = state_[ai];
    const ArmSample s = traj_.arm(a).sample(t_end);
    // The mean push on the two pads along each pad's opening direction (its link's z).
    double squeeze = 0;
    bool pressed = false;  // cloth pushes some pad's inner face apart
    st.reached = std::min(reached[2 * ai], reached[2 * ai + 1]);
    st.push_open = st.push_close = 0;
    st.vertices_open = st.vertices_close = 0;
    for (int f = 0; f < 2; ++f) {
      const sim::ColliderPush& p = pushes[2 * ai + f];
      const double push = p.along_z + p.against_z;
      squeeze += 0.5 * push;
      pressed = pressed || push > 0;
      st.push_open += 0.5 * p.along_z, st.push_close += 0.5 * p.against_z;
      st.vertices_open += p.vertices_along, st.vertices_close += p.vertices_against;
    }
    st.squeeze = squeeze;
    // Where the pads cut through the cloth (a diagnostic: the solve keeps the vertices and the
    // surface samples out, SceneOptions::pad_samples, not every point of the cloth).
    st.pad_cuts = cuts[2 * ai].total() + cuts[2 * ai + 1].total();
    st.pad_cut_depth = std::max(cuts[2 * ai].depth, cuts[2 * ai + 1].depth);
    if (st.pad_cuts > 0 && st.pad_cuts_from < 0) st.pad_cuts_from = t0;
    st.pad_cuts_max = std::max(st.pad_cuts_max, st.pad_cuts);
    st.pad_cut_depth_max = std::max(st.pad_cut_depth_max, st.pad_cut_depth);
    if (st.pad_cut_depth >= kThreadedDepth * pad.half_extents.minCoeff() && st.pad_threaded_from < 0)
      st.pad_threaded_from = t0;
    // A position-controlled, force-limited finger joint.
    const double command = std::clamp(s.gripper, 0.0, model_->gripper_max());
    const double limit = grip_force_at(t_end);
    st.grip_force = limit;
    // The trajectory asks for a grip: the command against the opening the hand last stood open at.
    if (!closing_[ai]) prev_[ai].open_ref = std::max(prev_[ai].open_ref, command);
    bool closing = grip_asked(command, prev_[ai].open_ref, model_->gripper_max());
    // Whether the hand holds the cloth: it squeezed with half its limit, and later, still commanded
    // closed, felt (almost) nothing and closed nearer than cloth between the pads lets them (below):
    // the cloth left the pads.
    if (!closing) {
      if (st.held_at >= 0) prev_[ai].released = true;  // the hold is over
    } else if (const double was = grip_force_at(t0); !prev_[ai].released && was > 0) {  // the squeeze is of t0
      if (st.held_at < 0 && squeeze >= kHoldFraction * was) {
        st.held_at = t0;
        gd::log().info("robot mode: the {} hand got hold of the cloth at {:.3f} s ({:.3g} N)", arm_name(a), t0, squeeze);
      }
      if (st.held_at >= 0 && st.lost_at < 0 && squeeze < kLetGoFraction * was && st.gripper < 0.25 * dhat) {
        st.lost_at = t0;
        st.force_at_loss = was;
        gd::log().info("robot mode: the {} hand let go of the cloth at {:.3f} s (squeeze limit {:.3g} N)", arm_name(a),
                       t0, st.force_at_loss);
      }
    }
    // The squeeze's stiffness against the opening, from the last two measurements (a secant).
    if (st.gripper != prev_[ai].gripper && squeeze > 0) {
      const double k = (squeeze - prev_[ai].squeeze) / (prev_[ai].gripper - st.gripper);
      if (k > 0) prev_[ai].stiffness = k;
    }
    prev_[ai].gripper = st.gripper;
    prev_[ai].squeeze = squeeze;
    double g = finger_joint_step({.opening = st.gripper, .command = command, .squeeze = squeeze, .limit = limit,
                                  .stiffness = prev_[ai].stiffness, .reached = st.reached,
                                  .max_step = finger_speed_ * dt, .dhat = dhat, .opening_max = model_->gripper_max()});
    // Never so near that the pads' faces meet with cloth between them (no room left for it). Cloth
    // pressing one pad's inner face counts even when cloth wrapped round the other pad's outer face
    // pulls the mean squeeze below zero (a towel turned over in a fold or a fling: the fingers then
    // closed to 0 on the cloth between them and trapped it inside a pad).
    if (pressed) g = std::max(g, 0.25 * dhat);
    // Fingers that came to rest at a command that no longer changes, with nothing between the pads
    // and still a tenth of the full opening or more apart, stand open there: a pre-shape (from 35
    // mm to 15 mm, say), not a grasp; the next grip is judged against that opening. (Fingers
    // following a closing ramp are not at rest: a grasp's events are where the command says.)
    const bool at_rest = g == command && command == prev_[ai].command;
    if (closing && at_rest && command >= kMinOpenFraction * model_->gripper_max() && st.vertices_open == 0 &&
        squeeze <= 0.1 * limit)
      closing = false;
    prev_[ai].command = command;
    if (closing != closing_[ai]) {  // a grasp or release event
      events_.push_back({t0, a, closing, {}});
      closing_[ai] = closing;
      if (closing) prev_[ai].grasp_from = st.gripper;
      else prev_[ai].open_ref = command;  // released: judged against the opening from here on
    }
    // A first grasp whose fingers, open when it was commanded, stop closing (at their command, or
    // on the floor above) before they squeeze with half the limit closed on little cloth (a hem's
    // edge, a few vertices) or none. Said once; a later hold still counts.
    if (closing && !prev_[ai].released && prev_[ai].grasp_from > command && st.held_at < 0 && st.missed_at < 0 &&
        g >= st.gripper && squeeze < kHoldFraction * limit && limit > 0) {
      st.missed_at = t0;
      if (st.vertices_open == 0)
        gd::log().warn("robot mode: the {} hand closed on nothing: its fingers shut at {:.3f} s with no cloth "
                       "between its pads (the grasp point is off the garment)",
                       arm_name(a), t0);
      else
        gd::log().warn("robot mode: the {} hand closed on little cloth: at {:.3f} s its fingers stopped {:.2f} mm "
                       "apart with {} vertices on their pads, squeezing {:.2g} N, under half its {:.3g} N limit "
                       "(what counts as a hold); the grip may slip (a grasp point further onto the cloth, e.g. "
                       "--task-param grasp_inset=0.01 on a generated task, or the mesh refined under the pads, "
                       "--refine-grasp, gives the pads more cloth)",
                       arm_name(a), t0, 2e3 * g, st.vertices_open, std::max(0.0, squeeze), limit);
    }
    st.gripper_command = command;
    st.gripper = g;
    st.grip = grip_now(st, closing, prev_[ai].released, squeeze, limit);
    st.joints = s.joints;
    // Pads at the step's end; the whole hand lifted where a pad would go below the table.
    std::array<Eigen::Isometry3d, 2> end = finger_poses(a, st.joints, g);
    double lowest = std::numeric_limits<double>::infinity();
    for (int f = 0; f < 2; ++f) {
      end[f] = end[f] * offset;
      for (int c = 0; c < 8; ++c) {
        const Vec3 corner((c & 1 ? 1 : -1) * pad.half_extents.x(), (c & 2 ? 1 : -1) * pad.half_extents.y(),
                          (c & 4 ? 1 : -1) * pad.half_extents.z());
        lowest = std::min(lowest, (end[f] * corner).z());
      }
    }
    st.table_lift = so.table ? std::max(0.0, so.table_height + clearance - lowest) : 0.0;
    for (int f = 0; f < 2; ++f) {
      end[f].translation().z() += st.table_lift;
      const int k = 2 * ai + f;
      auto& p = poses_->pose[k];
      p[0] = p[1];  // where the pad got to (short of its target where it stopped: Scene::collider_reached)
      // A pad that fell behind catches up by at most half a contact distance per step beyond its
      // target's own motion: making up the whole lag in one step pressed the cloth that had held
      // it back with hundreds of newtons, and the fling lost the towel (docs/robot.md, "Pads that
      // stop short").
      p[1] = pad_catch_up(p[0], poses_->target[k], end[f], 0.5 * dhat);
      poses_->target[k] = end[f];
    }
  }
  poses_->t0 = t0;
  poses_->t1 = t_end;
  // The links at the step's end, the hand lifted with its pads.
  const std::vector<robot::LinkShape>& shapes = model_->link_shapes();
  for (size_t k = 0; k < link_shape_of_.size(); ++k) {
    const auto [a, i] = link_shape_of_[k];
    const RobotArmState& st = state_[static_cast<int>(a)];
    auto& p = link_poses_->pose[k];
    p[0] = p[1];
    p[1] = shape_pose(a, shapes[i], to_vector(st.joints), st.gripper, st.table_lift);
  }
  link_poses_->t0 = t0;
  link_poses_->t1 = t_end;
}

}  // namespace gd::tasks
