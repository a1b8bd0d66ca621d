#pragma once
/// \file
/// Robot mode (docs/robot.md): two arms from a URDF (RGBench's AgileX Piper by default) follow a
/// trajectory, and the cloth is held only by their gripper fingers' contact and friction. No
/// vertex is pinned.
///
/// * Arms: fixed bases at tasks::base_offset (left y = +0.25, right y = -0.25, not rotated). The
///   arm joints follow the trajectory's joint angles (RGBench's pos_1..pos_6, interpolated
///   linearly as RGBench does); samples without joints (our generated tasks, pose files) are
///   turned into joints by inverse kinematics along the trajectory, each sample seeded with the
///   previous answer; where the exact pose is out of reach the position is kept and the
///   orientation tilted as little as the joint limits allow (up to max_tilt). Their poses are of
///   the TOOL frame of the generators (tool z = approach,
///   tool x = the direction the fingers close along); the end effector (Piper: link7) is the
///   tool frame turned by RobotOptions::tool_to_ee.
/// * Fingers: a box pad per finger (robot::ArmModelOptions::pad), a kinematic collider posed by
///   forward kinematics every step, with Coulomb friction against the cloth. Between the poses
///   at a step's start and end a pad moves by linear interpolation of its position and SLERP
///   of its orientation. Pads yield (sim::Collider::set_yielding): one that stopped short of its
///   pose, where the cloth it pushed could not get out of the way in time, starts the next step
///   where it got to and catches up by at most half a contact distance per step (pad_catch_up).
/// * Gripper: a position-controlled, force-limited prismatic joint. The commanded opening comes
///   from the trajectory; while closing, the fingers move at most `finger_speed` and, once the
///   cloth pushes back (the mean of the two pads' barrier forces along their opening directions,
///   Scene::collider_forces), step half the way to `grip_force` by the squeeze's measured
///   stiffness; above it they give way. So the fingers stop on the cloth with that squeeze, as a
///   real gripper's force limit does; with cloth between them they keep a quarter of the
///   contact distance apart.
///   The pads' barrier is stiffer than the table's (sim::Collider::set_stiffness_scale: the grip
///   force over the weight of the cloth a pad's face covers), so the squeeze is carried at about
///   half the contact distance, as the table carries the cloth's weight.
/// * Table: a pad never goes below the table top plus `table_clearance`; a hand that would is
///   lifted as a whole (a real gripper stops on the table, it does not enter it).

#include <array>
#include <memory>
#include <string>
#include <vector>

#include "robot/arm_model.h"
#include "sim/contact/cuts.h"
#include "tasks/controller.h"
#include "tasks/trajectory.h"

namespace gd::tasks {

/// A pose a fraction u of the way from a to b: positions interpolated linearly, orientations by
/// SLERP (how a pad moves over a step).
Eigen::Isometry3d blend_pose(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double u);

/// Where a gripper pad that stopped short of its target (sim::Collider::set_yielding) is sent for
/// the coming step: from `at`, where it got to, towards `target`, by at most the target's own
/// motion since the last step (`last_target` to `target`) plus `max_extra` (m), along blend_pose.
/// A pad on its target follows it exactly; one that fell behind catches up by at most `max_extra`
/// per step instead of making up the whole lag in one step.
Eigen::Isometry3d pad_catch_up(const Eigen::Isometry3d& at, const Eigen::Isometry3d& last_target,
                               const Eigen::Isometry3d& target, double max_extra);

/// What a finger joint knows at the start of a step (finger_joint_step).
struct FingerJointInput {
  double opening = 0;      ///< m, the joint's opening now (0: the pads' inner faces meet)
  double command = 0;      ///< m, the opening the trajectory asks for
  /// N, the cloth's mean push on the two pads along their opening directions: > 0 squeezed
  /// between them (pushing them apart), < 0 pressing their outer faces (pushing them together).
  double squeeze = 0;
  double limit = 0;        ///< N, the joint's force limit now
  double stiffness = 0;    ///< N/m, the squeeze's secant stiffness against the opening; <= 0 unknown
  /// Fraction of their last step's motion the hand's pads made (the lesser of the two;
  /// sim::Scene::collider_reached): < 1 where they stopped short on cloth that could not get out
  /// of their way in time.
  double reached = 1;
  double max_step = 0;     ///< m, the joint's travel at full speed over the step
  double dhat = 0;         ///< m, the contact distance
  double opening_max = 0;  ///< m, the joint's upper limit
};

/// The opening after one step of a position-controlled, force-limited finger joint (the
/// gripper's prismatic joint): towards the command at full speed while the load is under 10% of
/// the limit, then in steps that approach the limit (half the way by the secant stiffness, or 5%
/// of the contact distance while it is unknown); above the limit the joint gives way, opening when
/// closing on cloth, closing when opening against it. It does not give way while the pads stand
/// stopped short (reached < 1): the squeeze then is the cloth the moving hand pressed, not the
/// load on the joint (docs/robot.md, "Holding while the pads are stopped short").
double finger_joint_step(const FingerJointInput& in);

/// A pad's cut through the cloth at least this fraction of its smallest half extent deep
/// threads the cloth on it (RobotArmState::pad_threaded_from).
inline constexpr double kThreadedDepth = 0.5;

/// RobotOptions::pad_stiffness's default, N/m.
inline constexpr double kDefaultPadStiffness = 3e5;

struct RobotOptions {
  std::string urdf;                 ///< path of the arms' URDF (required unless a model is given)
  robot::ArmModelOptions arm;       ///< links, finger joints and pads of the URDF
  /// Friction coefficient of the finger pads against the cloth; < 0: the garment material's own.
  double finger_friction = -1;
  /// N: squeeze at which a closing gripper stops; < 0: the finger joint's effort limit in the
  /// URDF (Piper: 10 N).
  double grip_force = -1;
  /// The squeeze limit over time instead of a constant: knots (t s, N), linear between, held
  /// beyond the first and last; empty: grip_force throughout. A hold whose limit falls slowly
  /// measures the force a garment needs: the hand lets go once friction at the falling limit no
  /// longer carries its share of the weight (RobotArmState::lost_at, docs/robot.md "The force a
  /// grip needs"). The pads' barrier stiffness is set for the larger of grip_force (or the URDF's
  /// limit) and the largest knot. A hand that lets go is seen only while the limit is above 0.
  std::vector<std::array<double, 2>> grip_force_schedule;
  /// m/s: fastest finger motion; < 0: the finger joint's velocity limit in the URDF, capped at
  /// 0.1 m/s.
  double finger_speed = -1;
  /// m: lowest pad point above the table top; < 0: 0.7 contact distances (a little above where
  /// lying cloth rests, so closing pads catch it with their faces' lower edges).
  double table_clearance = -1;
  /// rad: how far an IK target's orientation may be missed where the arm cannot reach it exactly
  /// (the position is always reached within 1 mm); the Piper cannot point straight down high
  /// above the table.
  double max_tilt = 2.1;
  /// rad: generated tasks whose lift (grasp) or fling height was left to its default (the
  /// garment's length plus 0.1 or 0.15 m, pseudo mode's) are lowered, in robot mode, to the
  /// highest height whose inverse kinematics tilts no hand more than this from pointing down
  /// (tasks/robot_reach.h; experiment::run_experiment). Pseudo mode's height is out of the
  /// Piper's reach for a T-shirt, and a pinch tilted by 68 degrees took 2-5 s per step to
  /// converge and was never seen to hold (docs/robot.md, "Within reach").
  double lift_max_tilt = 30 * 3.14159265358979323846 / 180;
  /// The arms' links collide with the cloth where the URDF gives them collision geometry that
  /// was found (robot::ArmModel::link_shapes; meshes on arm.package_paths): every link's shapes
  /// but the fingers' (the pads hold the cloth), each a kinematic collider posed by forward
  /// kinematics every step, with the pads' friction; the hand's lifted with the pads off the
  /// table. false: the pads alone (RGBench's Piper URDF without its meshes gives no shapes).
  bool link_colliders = true;
  /// A hand's two pads are one yield group (sim::Collider::set_yield_group): the predictor moves
  /// the cloth pinched between them with them, and where the cloth stops one short the other stops
  /// with it. false: each pad yields on its own (before 2026-12-02; a hand sweeping across its
  /// pads' faces then opened its pinch by the trailing pad's lag: docs/robot.md, "Pads that stop
  /// together").
  bool rigid_hands = true;
  /// N/m: a hand the cloth stops short of its pose goes on as one more unknown of the solve,
  /// pulled along its step by a spring of this stiffness (sim::SceneOptions::pad_stiffness, which
  /// robot mode's scenes take from here; docs/robot.md, "Pads in the solve"): 3e5 lags 1 mm per
  /// 300 N. 0: the predictor stops its pads short and they wait there for the step (before
  /// 2026-12-06).
  double pad_stiffness = kDefaultPadStiffness;
  /// Points sampled over the cloth's triangles a pad's half thickness apart are held out of the
  /// pads as its vertices are (sim::SceneOptions::pad_samples, which robot mode's scenes take from
  /// here): without them a pad thinner than the cloth's edges are long stood in the sheet, threaded
  /// (docs/robot.md, "Pads that cut through the cloth", "Surface samples"). On by default since
  /// 2026-12-07 (`gd run --no-pad-samples` turns them off).
  bool pad_samples = true;
  /// Rotation from the trajectory's tool frame to the end-effector link (IK targets only). Piper
  /// default: link7 y = tool z (approach), link7 z = tool x (closing direction).
  Eigen::Matrix3d tool_to_ee = (Eigen::Matrix3d() << 0, 0, 1, 1, 0, 0, 0, 1, 0).finished();

  /// Throws InputError naming a bad value (a missing URDF path only when `need_urdf`).
  void validate(bool need_urdf = true) const;
};

/// What one arm does at the latest update.
struct RobotArmState {
  std::vector<double> joints;       ///< arm joints at the step's end, rad
  double gripper = 0;               ///< finger opening at the step's end, m (each finger)
  double gripper_command = 0;       ///< what the trajectory asks, m
  double squeeze = 0;               ///< N: the cloth's mean push on the two pads at the step's start
  /// The squeeze split (squeeze = push_open + push_close): the mean push of the cloth on the
  /// two pads' inner faces (opening them, N >= 0) and round their outer faces (closing them, N
  /// <= 0), and the points of the cloth doing each: vertices and, with pad_samples, surface
  /// samples (Scene::collider_pushes).
  double push_open = 0, push_close = 0;
  int vertices_open = 0, vertices_close = 0;
  /// The smaller fraction of its last step's motion either pad made (1 unless the cloth stopped
  /// it short: Collider::set_yielding); the squeeze above is measured where the pads got to.
  double reached = 1;
  double table_lift = 0;            ///< m the hand was raised to stay off the table
  /// Where the hand's two pads cut through the cloth at the step's start (sim::collider_cuts): the
  /// contact keeps the cloth's vertices out of the pads, not its edges and faces, so cloth whose
  /// edges are longer than a pad is thick can stand threaded on it (docs/robot.md, "Pads that cut
  /// through the cloth"). pad_cuts: cloth edges through a pad plus cloth triangles a pad's edge
  /// passes through; pad_cut_depth: m, how far inside a pad the deepest of them passes.
  int pad_cuts = 0;
  double pad_cut_depth = 0;
  /// Over the run so far: the most cuts and the deepest cut at any step, when the first was seen
  /// and when the cloth was first threaded on a pad, a cut as deep as half the pad's half
  /// thickness (kThreadedDepth; s, < 0: not yet). Shallower cuts are chords across a pad's edge
  /// that the cloth wraps round (1.2 mm deep for cloth meshed at 5 mm round a Piper pad's tip).
  int pad_cuts_max = 0;
  double pad_cut_depth_max = 0;
  double pad_cuts_from = -1;
  double pad_threaded_from = -1;
  double grip_force = 0;            ///< N: the squeeze limit at the step's end (RobotOptions)
  /// s: when the closed fingers first squeezed the cloth with half their limit (< 0: not yet).
  double held_at = -1;
  /// s: when, after that, the squeeze fell below kLetGoFraction of the limit and the fingers,
  /// still commanded closed, came nearer than a quarter contact distance (cloth between the pads
  /// keeps them that far apart): the cloth left the pads (< 0: not yet); and the limit then, N. An
  /// opening command (a release) ends the watch: the hold is over.
  double lost_at = -1, force_at_loss = 0;
  /// s: when the fingers of the first grasp, open when it was commanded and not yet holding,
  /// stopped closing (at their command, or as near as the cloth between the pads lets them)
  /// squeezing less than half the limit: the grasp closed on little cloth (a hem's edge, a few
  /// vertices) or none (< 0: not so). A warning says so; a hold that comes later still sets held_at.
  double missed_at = -1;
  /// What the hand does with the cloth now. The first grasp is followed through held_at, lost_at
  /// and missed_at; a grasp after a release is judged by its squeeze alone (held at half the
  /// limit, closing below).
  Grip grip = Grip::kOpen;
  std::array<int, 2> colliders{-1, -1};  ///< the pads' scene collider ids
  std::vector<int> link_colliders;       ///< the links' scene collider ids (RobotOptions::link_colliders)
};

class RobotController final : public TaskController {
 public:
  /// Loads the URDF, solves inverse kinematics for samples without joints and validates
  /// everything. Throws InputError: options, a sample with the wrong number of joints, a pose the
  /// arm cannot reach (naming the arm, the time and by how far).
  RobotController(DualArmTrajectory traj, RobotOptions options);
  /// The same with the arms already loaded (the service loads a URDF once for many scenes);
  /// options.urdf then only names it. `log_ik`: log how many samples inverse kinematics solved,
  /// the orientation it missed and where the joints jump between samples (off for trial
  /// trajectories, tasks/robot_reach.h).
  RobotController(DualArmTrajectory traj, RobotOptions options, std::shared_ptr<const robot::ArmModel> model,
                  bool log_ik = true);

  /// `s` with its joints filled in: given joints are checked (count, finite, within the URDF's
  /// limits up to kJointLimitSlack, then clamped to them; with clamp_to_limits, joints farther
  /// out are clamped too instead of refused), a pose without joints is solved by inverse
  /// kinematics from `seed` (the previous sample's joints; empty: the joints at 0 within their
  /// limits). Throws InputError naming the arm, the time and, for a joint out of its limits, the
  /// joint, its value and the limits.
  ArmSample resolve(Arm a, ArmSample s, const std::vector<double>& seed, bool clamp_to_limits = false) const;
  /// How far a given joint may lie outside its URDF limit and still be taken (clamped): rad or m.
  static constexpr double kJointLimitSlack = 1e-3;
  /// Appends a sample after the arm's last one (resolved from the last sample's joints), for
  /// trajectories that arrive step by step (the service's scenes). Throws InputError.
  void append(Arm a, const ArmSample& s);

  void update(sim::Scene& scene, double t_end) override;
  double end_time() const override { return traj_.end_time(); }
  const std::vector<GripperEvent>& events() const override { return events_; }

  const RobotArmState& state(Arm a) const { return state_[static_cast<int>(a)]; }
  /// The trajectory with every sample's joints filled in (written as RGBench joints CSVs, it
  /// drives RGBench's own robot mode).
  const DualArmTrajectory& trajectory() const { return traj_; }
  const robot::ArmModel& arm_model() const { return *model_; }
  const RobotOptions& options() const { return options_; }
  /// Samples whose pose needed inverse kinematics.
  int ik_solved() const { return ik_solved_; }
  /// Largest orientation error (rad) inverse kinematics had to accept.
  double ik_max_tilt() const { return ik_max_tilt_; }
  /// Whether the arm holds its hand turned half a turn about the approach axis from the
  /// trajectory's orientation (its wrist reaches that way round; fingers swapped), decided at its
  /// first solved pose; false for arms driven by given joints.
  bool hand_half_turned(Arm a) const { return half_turned_[static_cast<int>(a)] == 1; }
  /// The squeeze limit at scene time t (RobotOptions::grip_force_schedule, else the constant), N.
  double grip_force_at(double t) const;
  /// A hand whose squeeze falls below this fraction of its limit while closed has let go.
  static constexpr double kLetGoFraction = 0.02;
  /// A hand squeezing with this fraction of its limit holds the cloth (RobotArmState::held_at; a
  /// grasp whose fingers stop short of it missed, RobotArmState::missed_at).
  static constexpr double kHoldFraction = 0.5;
  /// Whether a gripper command asks for a grip (RobotArmState::grip is then not kOpen; grasp and
  /// release events are its changes): a command below half `open_ref`, the opening the hand last
  /// stood open at (its pre-grasp opening: a hand hovering with its fingers 3 cm apart is open, and
  /// grips below 7.5 mm), or below half the full opening `gripper_max` where the hand has not stood
  /// open yet (open_ref below kMinOpenFraction of it: a trajectory that starts with the fingers shut).
  /// update() also ends a grip whose fingers came to rest at a command of at least that fraction,
  /// no longer changing, with nothing between the pads: the hand was pre-shaped, and stands open
  /// there.
  static bool grip_asked(double command, double open_ref, double gripper_max);
  static constexpr double kMinOpenFraction = 0.1;
  /// Recorded samples whose joints lay outside the URDF's limits (beyond kJointLimitSlack) and
  /// were clamped to them, and the largest excess (rad or m).
  int joints_clamped() const { return joints_clamped_; }
  double joint_clamp_max() const { return joint_clamp_max_; }
  /// World poses of an arm's two finger links for the given joints and opening.
  std::array<Eigen::Isometry3d, 2> finger_poses(Arm a, const std::vector<double>& joints, double gripper) const;
  /// World pose of an arm's end effector (fingers at 0) at its joints of the latest update.
  Eigen::Isometry3d ee_world(Arm a) const;
  /// The arm's chain at those joints, world frame (robot::ArmModel::chain_points): its skeleton.
  std::vector<Vec3> chain_world(Arm a) const;
  /// The four finger pads at scene time t within the latest step ([left 0, left 1, right 0,
  /// right 1]; before the first step: where they start): world poses of their boxes' centres.
  /// Their half extents are options().arm.pad.half_extents.
  std::array<Eigen::Isometry3d, 4> pad_poses(double t) const;

 private:
  struct PadPoses;
  struct LinkPoses;
  void attach(sim::Scene& scene);
  void attach_links(sim::Scene& scene, double mu);
  /// The four pads' cuts through the cloth at the scene's time (left's two, then right's).
  std::array<sim::ColliderCuts, 4> pad_cuts(const sim::Scene& scene) const;
  /// World pose of link shape `s` of arm `a` at joints q and opening g, the hand raised by `lift`.
  Eigen::Isometry3d shape_pose(Arm a, const robot::LinkShape& s, const Eigen::VectorXd& q, double g, double lift) const;

  DualArmTrajectory traj_;
  RobotOptions options_;
  std::shared_ptr<const robot::ArmModel> model_;
  bool log_ik_ = true;
  std::array<RobotArmState, 2> state_;
  std::shared_ptr<PadPoses> poses_;  ///< shared with the colliders' pose functions
  std::shared_ptr<LinkPoses> link_poses_;  ///< the same for the links' colliders
  std::vector<std::pair<Arm, int>> link_shape_of_;  ///< per link collider: its arm and link shape
  double grip_force_ = 0, finger_speed_ = 0;
  int ik_solved_ = 0;
  mutable double ik_max_tilt_ = 0;  ///< grows in resolve()
  mutable std::array<int, 2> half_turned_{-1, -1};  ///< per arm: -1 undecided, 0 as given, 1 half a turn (resolve())
  int joints_clamped_ = 0;
  double joint_clamp_max_ = 0;
  bool attached_ = false;
  std::array<bool, 2> closing_{false, false};
  struct Previous {
    double gripper = -1, squeeze = 0, stiffness = 0;  ///< the last update's opening and squeeze, N/m
    bool released = false;  ///< the hand opened after holding: RobotArmState::lost_at no longer watched
    double grasp_from = -1;  ///< m: the opening when the latest grasp was commanded
    double command = -1;     ///< m: the last update's gripper command
    /// m: the opening the hand last stood open at: the largest command since the start or the
    /// latest release (grip_asked); < 0 before the first update
    double open_ref = -1;
  };
  std::array<Previous, 2> prev_;
  std::vector<GripperEvent> events_;
};

}  // namespace gd::tasks
