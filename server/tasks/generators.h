#pragma once
/// \file
/// Two-arm Grasp, Fling and Fold trajectories after the RGBench paper's task descriptions,
/// parameterised by the garment's size and landmarks (docs/tasks.md):
///
/// * Grasp: from the flat garment both arms descend onto grasp points at the shoulders, close,
///   lift vertically until the garment hangs clear of the table, and hold.
/// * Fling: grasp the shoulders, lift until the garment hangs clear, then a rapid forward-then-
///   backward sweep (+x, then back) that makes it flutter; it ends held in the air with the arms
///   apart at about the shoulder distance, so the garment hangs spread.
/// * Fold: grasp the shoulders, lift slightly, turn the top half over onto the bottom half like a
///   page (half circles about the fold line) to just short of the hem, open, retreat upwards. A
///   hood is first laid over onto the body the same way.
///
/// The garment lies as RGBench's T-shirt mesh does (garments/garment.h): length along +x away
/// from the robots, shoulders at the small-x end. Grasp points are the shoulder landmarks mapped
/// to the world with `garment_to_world` (frames.h default_garment_pose()). The gripper points its
/// jaw down (top_down_orientation(), its fingers closing along the garment's +x turned by
/// TaskParams::grasp_yaw), is 0.035 m open and 0 closed. Between waypoints the arms move
/// along minimum-jerk profiles, sampled every `sample_dt`; the result starts at t = 0 with
/// master_start_time 0, and can be replayed by GripperController in pseudo-grasp mode.

#include <Eigen/Geometry>
#include <string>
#include <utility>
#include <vector>

#include "garments/garment.h"
#include "tasks/trajectory.h"

namespace gd::tasks {

/// Durations (s), distances (m) and speeds (m/s) of the generators. Negative "auto" values are
/// derived from the garment. Defaults give tasks of 10-15 s, like RGBench's captures.
struct TaskParams {
  /// Multiplies every duration except the fling sweep (whose timing follows fling_peak_speed);
  /// < 1 makes quasi-static parts faster, e.g. for tests.
  double time_scale = 1.0;
  double sample_dt = 0.01;            ///< s between trajectory samples (not scaled)

  double start_delay = 1.0;           ///< s at rest, open, above the grasp points
  double approach_height = 0.08;      ///< m above the grasp points where the arms start
  double approach_duration = 2.0;     ///< s to descend onto the grasp points
  double close_duration = 0.6;        ///< s for the gripper to close (or open)
  /// m added to each grasp point along garment +x (inwards from the collar edge); 0: the landmark.
  double grasp_inset = 0.0;
  /// m each grasp point moves from the garment's side towards its centre line (garment y; the hem
  /// corners too); 0: the landmark. A landmark on the side edge (a towel's corners) leaves one of
  /// robot mode's fingers, which close along garment x, beside the cloth's corner rather than over
  /// the cloth.
  double grasp_inset_side = 0.0;
  /// degrees the gripper turns about the vertical before it comes down: the direction its fingers
  /// close along (robot mode) from the garment's +x (0: across a collar or waist edge, which runs
  /// along garment y) towards its +y (90: along that edge, both fingers on the same side of it).
  /// The jaw keeps pointing down and keeps this turn through the whole task.
  double grasp_yaw = 0.0;
  /// m the grippers reach below each grasp point (world -z). Negative: automatic, 0 for the
  /// pseudo modes; robot mode (experiment) takes 5 mm plus the highest grasp landmark's height
  /// above the table, so the fingers go down to the table however high the grasp points lie, and
  /// its clearance stops them (tasks/robot_arms.h), as a real gripper's fingertips touch it.
  double grasp_depth = -1;

  // Grasp
  double lift_height = -1;            ///< m above the grasp point; < 0: garment length + 0.1
  double lift_duration = 4.0;         ///< s
  double hold_duration = 3.0;         ///< s held still at the end (grasp, fling)

  // Fling
  double fling_height = -1;           ///< m above the grasp point; < 0: garment length + 0.15
  double fling_pause = 1.0;           ///< s held still before the sweep (lets the swing die down)
  double fling_distance = 0.25;       ///< m forward (+x) and back
  double fling_peak_speed = 1.0;      ///< m/s peak speed of each minimum-jerk stroke
  /// m between the arms at the end; < 0: the shoulder distance (the arms keep their grasp spacing).
  double fling_spread = -1;

  // Fold
  double fold_lift = 0.06;            ///< m lifted before translating
  double fold_lift_duration = 1.0;    ///< s
  /// m short of the hem where the shoulders are put down, measured along garment x.
  double fold_margin = 0.03;
  double fold_duration = 3.5;         ///< s for the forward translation
  /// How the shoulders travel to the hem. < 0 (default): a page turn, each gripper on a half circle
  /// about the fold line (midway between where it grasped and where it puts down) from the lifted
  /// grasp point to place_height above the put-down point, so the top half stays taut and is laid
  /// flat instead of landing slack and bunching into a loop at the fold. > 0: the same half ellipse
  /// with this vertical semi-axis (m). 0: the paper's level translation at fold_lift, then a vertical
  /// lowering to place_height in lower_duration.
  double fold_arc = -1;
  double place_height = 0.01;         ///< m above the grasp height where the gripper opens
  double lower_duration = 1.0;        ///< s: lowering (level translation) or pause before opening
  double retreat_height = 0.1;        ///< m lifted after opening
  double retreat_duration = 1.0;      ///< s
  double settle_duration = 2.0;       ///< s of stillness at the end of a fold
  /// Hooded garments (Landmarks::has_hood): 1 (default) folds them as people fold a hoodie: both
  /// arms take the hood's face corners and turn it over the neck line like a page onto the back,
  /// let go, then take the hem corners and turn the bottom half up onto the top half, so that the
  /// hood ends between the halves without riding on a moving flap. 0: the ordinary fold, the hood
  /// trailing the shoulders and landing on top.
  double tuck_hood = 1;

  /// Throws InputError naming a bad value (non-finite, non-positive durations, ...).
  void validate() const;
};

/// Sets the TaskParams field called `name` (e.g. "fold_duration") to `value`. Throws InputError
/// for an unknown name (the message lists the known ones); the value is checked by validate().
void set_task_param(TaskParams& params, const std::string& name, double value);

/// The names set_task_param knows, in TaskParams order.
std::vector<std::string> task_param_names();

/// Every parameter of `params` as (name, value), in TaskParams order (e.g. for a run's summary).
std::vector<std::pair<std::string, double>> task_param_values(const TaskParams& params);

/// m above the garment's length by which a grasp lifts (TaskParams::lift_height < 0) and a
/// fling raises (fling_height < 0) its grasp points: the garment hangs clear of the table.
inline constexpr double kLiftAboveLength = 0.1;
inline constexpr double kFlingAboveLength = 0.15;

/// Grasp: approach, close on the shoulders, lift by lift_height, hold.
DualArmTrajectory make_grasp(const garments::Garment& g, const Eigen::Isometry3d& garment_to_world,
                             const TaskParams& p = {});
/// Fling: approach, close, lift by fling_height, pause, forward-and-back sweep (spreading the
/// arms to fling_spread on the way back), hold.
DualArmTrajectory make_fling(const garments::Garment& g, const Eigen::Isometry3d& garment_to_world,
                             const TaskParams& p = {});
/// Fold: approach, close, lift by fold_lift, turn over to the hem minus fold_margin (see
/// TaskParams::fold_arc), open, retreat, settle. A hooded garment (TaskParams::tuck_hood) is folded
/// the other way round after its hood is laid over: approach the hood's face corners, close, lift,
/// turn it over the neck line to fold_margin short of its mirror image, open, retreat; then
/// approach the hem corners, close, turn the bottom half over to fold_margin beyond the
/// shoulders' grasp points, open, retreat, settle.
DualArmTrajectory make_fold(const garments::Garment& g, const Eigen::Isometry3d& garment_to_world,
                            const TaskParams& p = {});
/// m: the height of the fold's page turn (its body turn's, the longest) as make_fold draws it:
/// TaskParams::fold_arc where > 0, else, automatic, a half circle about the fold line (0 where
/// fold_arc == 0, the level translation). Robot mode lowers an automatic one to the arms' reach
/// (docs/robot.md, "Within reach").
double fold_page_rise(const garments::Garment& g, const Eigen::Isometry3d& garment_to_world, const TaskParams& p = {});
/// "grasp" | "fold" | "fling"; InputError otherwise.
DualArmTrajectory make_task(const std::string& name, const garments::Garment& g,
                            const Eigen::Isometry3d& garment_to_world, const TaskParams& p = {});

}  // namespace gd::tasks
