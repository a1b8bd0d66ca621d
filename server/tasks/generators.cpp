#include "tasks/generators.h"

#include <spdlog/fmt/fmt.h>

#include <array>
#include <cmath>

#include "sim/demand.h"
#include "tasks/grippers.h"

namespace gd::tasks {

using sim::InputError;

void TaskParams::validate() const {
  auto positive = [](double v, const char* name) {
    if (!(std::isfinite(v) && v > 0)) throw InputError(fmt::format("task parameter {} must be a positive number", name));
  };
  auto nonneg = [](double v, const char* name) {
    if (!(std::isfinite(v) && v >= 0)) throw InputError(fmt::format("task parameter {} must be a finite number >= 0", name));
  };
  auto finite = [](double v, const char* name) {
    if (!std::isfinite(v)) throw InputError(fmt::format("task parameter {} must be finite", name));
  };
  positive(time_scale, "time_scale");
  positive(sample_dt, "sample_dt");
  nonneg(start_delay, "start_delay");
  nonneg(approach_height, "approach_height");
  positive(approach_duration, "approach_duration");
  positive(close_duration, "close_duration");
  finite(grasp_inset, "grasp_inset");
  finite(grasp_inset_side, "grasp_inset_side");
  if (!(std::isfinite(grasp_yaw) && std::abs(grasp_yaw) <= 360))
    throw InputError(fmt::format("task parameter grasp_yaw must be a finite angle in degrees within [-360, 360] (got {})",
                                 grasp_yaw));
  finite(grasp_depth, "grasp_depth");
  finite(lift_height, "lift_height");
  positive(lift_duration, "lift_duration");
  nonneg(hold_duration, "hold_duration");
  finite(fling_height, "fling_height");
  nonneg(fling_pause, "fling_pause");
  nonneg(fling_distance, "fling_distance");
  positive(fling_peak_speed, "fling_peak_speed");
  finite(fling_spread, "fling_spread");
  nonneg(fold_lift, "fold_lift");
  positive(fold_lift_duration, "fold_lift_duration");
  finite(fold_margin, "fold_margin");
  finite(fold_arc, "fold_arc");
  positive(fold_duration, "fold_duration");
  nonneg(place_height, "place_height");
  positive(lower_duration, "lower_duration");
  nonneg(retreat_height, "retreat_height");
  positive(retreat_duration, "retreat_duration");
  nonneg(settle_duration, "settle_duration");
  if (tuck_hood != 0 && tuck_hood != 1) throw InputError("task parameter tuck_hood must be 0 or 1");
}

namespace {

struct TaskParamField {
  const char* name;
  double TaskParams::*field;
};

constexpr TaskParamField kTaskParamFields[] = {
    {"time_scale", &TaskParams::time_scale},
    {"sample_dt", &TaskParams::sample_dt},
    {"start_delay", &TaskParams::start_delay},
    {"approach_height", &TaskParams::approach_height},
    {"approach_duration", &TaskParams::approach_duration},
    {"close_duration", &TaskParams::close_duration},
    {"grasp_inset", &TaskParams::grasp_inset},
    {"grasp_inset_side", &TaskParams::grasp_inset_side},
    {"grasp_yaw", &TaskParams::grasp_yaw},
    {"grasp_depth", &TaskParams::grasp_depth},
    {"lift_height", &TaskParams::lift_height},
    {"lift_duration", &TaskParams::lift_duration},
    {"hold_duration", &TaskParams::hold_duration},
    {"fling_height", &TaskParams::fling_height},
    {"fling_pause", &TaskParams::fling_pause},
    {"fling_distance", &TaskParams::fling_distance},
    {"fling_peak_speed", &TaskParams::fling_peak_speed},
    {"fling_spread", &TaskParams::fling_spread},
    {"fold_lift", &TaskParams::fold_lift},
    {"fold_lift_duration", &TaskParams::fold_lift_duration},
    {"fold_margin", &TaskParams::fold_margin},
    {"fold_duration", &TaskParams::fold_duration},
    {"fold_arc", &TaskParams::fold_arc},
    {"place_height", &TaskParams::place_height},
    {"lower_duration", &TaskParams::lower_duration},
    {"retreat_height", &TaskParams::retreat_height},
    {"retreat_duration", &TaskParams::retreat_duration},
    {"settle_duration", &TaskParams::settle_duration},
    {"tuck_hood", &TaskParams::tuck_hood},
};

}  // namespace

std::vector<std::string> task_param_names() {
  std::vector<std::string> names;
  for (const TaskParamField& f : kTaskParamFields) names.emplace_back(f.name);
  return names;
}

std::vector<std::pair<std::string, double>> task_param_values(const TaskParams& params) {
  std::vector<std::pair<std::string, double>> values;
  for (const TaskParamField& f : kTaskParamFields) values.emplace_back(f.name, params.*f.field);
  return values;
}

void set_task_param(TaskParams& params, const std::string& name, double value) {
  for (const TaskParamField& f : kTaskParamFields)
    if (name == f.name) {
      params.*f.field = value;
      return;
    }
  throw InputError(fmt::format("unknown task parameter '{}'; known: {}", name, fmt::join(task_param_names(), ", ")));
}

namespace {

/// Minimum-jerk profile: 0 -> 1 with zero velocity and acceleration at both ends.
double min_jerk(double u) { return u * u * u * (10.0 + u * (-15.0 + 6.0 * u)); }

/// Peak speed of a minimum-jerk stroke is 1.875 * distance / duration.
constexpr double kMinJerkPeak = 1.875;
constexpr double kPi = 3.14159265358979323846;

/// Both arms' end-effector positions and the common gripper opening at one waypoint.
struct Waypoint {
  std::array<Vec3, 2> pos;
  double gripper = kGripperOpen;
};

/// Appends minimum-jerk segments between waypoints to both arms' sample lists.
class Builder {
 public:
  /// `hand`: both grippers' orientation throughout (the tool frame, jaw down).
  Builder(const Waypoint& start, double sample_dt, const Eigen::Quaterniond& hand)
      : cur_(start), dt_(sample_dt), hand_(hand) {
    emit(0.0, start);
  }

  /// Moves to `to` over `duration` seconds (a hold when the positions do not change).
  void move(const Waypoint& to, double duration) {
    if (duration <= 0) return;
    const bool moves = (to.pos[0] - cur_.pos[0]).norm() > 0 || (to.pos[1] - cur_.pos[1]).norm() > 0;
    // Still arms and a linear gripper ramp need only the end sample (the trajectory interpolates).
    const int n = moves ? std::max(1, static_cast<int>(std::ceil(duration / dt_ - 1e-9))) : 1;
    for (int k = 1; k <= n; ++k) {
      const double u = static_cast<double>(k) / n;
      const double s = min_jerk(u);
      Waypoint w;
      for (int a = 0; a < 2; ++a) w.pos[a] = cur_.pos[a] + s * (to.pos[a] - cur_.pos[a]);
      w.gripper = cur_.gripper + u * (to.gripper - cur_.gripper);
      emit(t_ + u * duration, w);
    }
    t_ += duration;
    cur_ = to;
  }
  /// A page turn from the current waypoint to `to`: each arm moves on a half ellipse whose
  /// horizontal axis is the chord and whose vertical semi-axis is `rise` (m),
  ///   p(phi) = c - (to - from)/2 cos(phi) + rise sin(phi) z,  phi = pi s(u),
  /// s the minimum-jerk progress. A point of cloth held at the start swings about the chord's
  /// midpoint at a nearly constant distance, so the part of the garment between that midpoint
  /// and the gripper stays taut, like a page turned over its spine, and is laid down flat.
  void turn_page(const Waypoint& to, double rise, double duration) {
    if (duration <= 0) return;
    const int n = std::max(1, static_cast<int>(std::ceil(duration / dt_ - 1e-9)));
    for (int k = 1; k <= n; ++k) {
      const double u = static_cast<double>(k) / n;
      const double phi = kPi * min_jerk(u);
      Waypoint w;
      for (int a = 0; a < 2; ++a) {
        const Vec3 half = 0.5 * (to.pos[a] - cur_.pos[a]);
        w.pos[a] = cur_.pos[a] + half - std::cos(phi) * half + Vec3(0, 0, rise * std::sin(phi));
      }
      w.gripper = cur_.gripper + u * (to.gripper - cur_.gripper);
      emit(t_ + u * duration, w);
    }
    t_ += duration;
    cur_ = to;
  }
  void hold(double duration) { move(cur_, duration); }
  /// Opens or closes the gripper in place.
  void gripper(double opening, double duration) {
    Waypoint w = cur_;
    w.gripper = opening;
    move(w, duration);
  }
  const Waypoint& current() const { return cur_; }

  DualArmTrajectory finish() const {
    DualArmTrajectory out;
    out.left = ArmTrajectory(samples_[0], "generated left arm trajectory");
    out.right = ArmTrajectory(samples_[1], "generated right arm trajectory");
    return out;
  }

 private:
  void emit(double t, const Waypoint& w) {
    for (int a = 0; a < 2; ++a) samples_[a].push_back({t, w.pos[a], hand_, w.gripper});
  }
  Waypoint cur_;
  double dt_;
  Eigen::Quaterniond hand_;
  double t_ = 0;
  std::array<std::vector<ArmSample>, 2> samples_;
};

/// World-frame quantities every generator needs.
struct Setup {
  std::array<Vec3, 2> grasp;  ///< [left, right] grasp points, world
  Vec3 forward;               ///< garment +x in the world (unit)
  Eigen::Quaterniond hand;    ///< the grippers' orientation: jaw down, closing along forward turned by grasp_yaw
  double length = 0, width = 0;
  double shoulder_distance = 0;
  double hem_x = 0;           ///< garment-frame x of the hem (far) end
  std::array<Vec3, 2> grasp_local;  ///< grasp points in the garment frame
  std::array<Vec3, 2> hem_local;    ///< [left, right] hem grasp points (corners, grasp_inset in), garment frame
  std::array<Vec3, 2> hem_grasp;    ///< the same in the world
  bool hood = false;          ///< the garment has a hood (its landmarks below are set)
  std::array<Vec3, 2> hood_grasp;   ///< [left, right] face corners of the hood, world
  std::array<Vec3, 2> hood_local;   ///< the same in the garment frame
  double hood_fold_x = 0;     ///< garment-frame x of the line the hood folds about
};

Setup setup(const garments::Garment& g, const Eigen::Isometry3d& T, const TaskParams& p) {
  p.validate();
  if (!T.matrix().allFinite()) throw InputError("task generator: the garment pose has non-finite entries");
  if (!(std::isfinite(g.length) && g.length > 0 && std::isfinite(g.width) && g.width > 0))
    throw InputError(fmt::format("task generator: garment length ({}) and width ({}) must be positive", g.length, g.width));
  const auto& lm = g.landmarks;
  if (!lm.left_shoulder.allFinite() || !lm.right_shoulder.allFinite() || !lm.left_hem.allFinite() ||
      !lm.right_hem.allFinite())
    throw InputError("task generator: the garment's landmarks must be finite");
  if ((lm.left_shoulder - lm.right_shoulder).norm() < 1e-6)
    throw InputError("task generator: the garment's left and right shoulder landmarks coincide (landmarks not set?)");
  if (lm.left_shoulder.y() <= lm.right_shoulder.y())
    throw InputError(fmt::format(
        "task generator: the left shoulder landmark (y={}) must lie on the +y side of the right one (y={}) in the "
        "garment frame (the left arm's side)",
        lm.left_shoulder.y(), lm.right_shoulder.y()));
  Setup s;
  s.length = g.length;
  s.width = g.width;
  s.forward = T.linear() * Vec3::UnitX();
  // The fingers close along the garment's +x seen from above, turned by grasp_yaw about the vertical.
  const double heading = std::hypot(s.forward.x(), s.forward.y()) > 1e-9 ? std::atan2(s.forward.y(), s.forward.x()) : 0.0;
  s.hand = Eigen::AngleAxisd(heading + p.grasp_yaw * kPi / 180.0, Vec3::UnitZ()) * top_down_orientation();
  const Vec3 side = p.grasp_inset_side * Vec3::UnitY();  // towards the centre line: -y on the left, +y on the right
  s.grasp_local = {lm.left_shoulder + p.grasp_inset * Vec3::UnitX() - side,
                   lm.right_shoulder + p.grasp_inset * Vec3::UnitX() + side};
  if (s.grasp_local[0].y() <= s.grasp_local[1].y())
    throw InputError(fmt::format("task parameter grasp_inset_side {} m moves the grasp points across the garment's "
                                 "centre line (they are {:.3f} m apart); keep it below half that",
                                 p.grasp_inset_side, lm.left_shoulder.y() - lm.right_shoulder.y()));
  const Vec3 down = -std::max(0.0, p.grasp_depth) * Vec3::UnitZ();
  for (int a = 0; a < 2; ++a) s.grasp[a] = T * s.grasp_local[a] + down;
  s.shoulder_distance = (s.grasp[0] - s.grasp[1]).norm();
  // The hem: its landmarks when set (beyond the shoulders), else the garment's length.
  const double hem = 0.5 * (lm.left_hem.x() + lm.right_hem.x());
  s.hem_x = hem > 0.5 * (lm.left_shoulder.x() + lm.right_shoulder.x()) ? hem : g.length;
  s.hem_local = {lm.left_hem - p.grasp_inset * Vec3::UnitX() - side, lm.right_hem - p.grasp_inset * Vec3::UnitX() + side};
  for (int a = 0; a < 2; ++a) s.hem_grasp[a] = T * s.hem_local[a] + down;
  if (lm.has_hood) {
    if (!lm.left_hood.allFinite() || !lm.right_hood.allFinite() || !std::isfinite(lm.hood_fold_x))
      throw InputError("task generator: the garment's hood landmarks must be finite");
    if (lm.hood_fold_x <= 0.5 * (lm.left_hood.x() + lm.right_hood.x()))
      throw InputError(fmt::format("task generator: the hood's fold line (x={}) must lie beyond its face corners", lm.hood_fold_x));
    s.hood = true;
    s.hood_local = {lm.left_hood, lm.right_hood};
    for (int a = 0; a < 2; ++a) s.hood_grasp[a] = T * s.hood_local[a] + down;
    s.hood_fold_x = lm.hood_fold_x;
  }
  return s;
}

Waypoint at(const std::array<Vec3, 2>& pos, double gripper) {
  Waypoint w;
  w.pos = pos;
  w.gripper = gripper;
  return w;
}

std::array<Vec3, 2> raised(const std::array<Vec3, 2>& p, double dz) {
  return {p[0] + Vec3(0, 0, dz), p[1] + Vec3(0, 0, dz)};
}

/// Start above the grasp points, descend, close: the common opening of every task.
Builder approach_and_close(const Setup& s, const TaskParams& p) {
  const double k = p.time_scale;
  Builder b(at(raised(s.grasp, p.approach_height), kGripperOpen), p.sample_dt, s.hand);
  b.hold(p.start_delay * k);
  b.move(at(s.grasp, kGripperOpen), p.approach_duration * k);
  b.gripper(0.0, p.close_duration * k);
  return b;
}

/// Where grippers holding `from` (garment frame: from_local) put the flap down: each moved along
/// the garment's x to garment-frame x `to_x[a]`, forward (+x, `dir` = 1) or back (`dir` = -1).
/// Throws when that is no motion in that direction.
std::array<Vec3, 2> put_down_at(const Setup& s, const std::array<Vec3, 2>& from, const std::array<Vec3, 2>& from_local,
                                const std::array<double, 2>& to_x, double margin, const char* what, int dir = 1) {
  std::array<Vec3, 2> over;
  for (int a = 0; a < 2; ++a) {
    const double dx = to_x[a] - from_local[a].x();
    if (dx * dir <= 0)
      throw InputError(fmt::format("fold: fold_margin {} m leaves no {} motion for the {} (grasp at x={} m, put "
                                   "down at x={} m)", margin, dir > 0 ? "forward" : "backward", what,
                                   from_local[a].x(), to_x[a]));
    over[a] = from[a] + dx * s.forward;
  }
  return over;
}

/// The page turn's height from `from` to `over`: TaskParams::fold_arc (0: the level translation),
/// or where that is automatic (< 0) a circle about the fold line at grasp height (the chord's midpoint is
/// (fold_lift + place_height) / 2 above it).
double page_rise(const std::array<Vec3, 2>& from, const std::array<Vec3, 2>& over, const TaskParams& p) {
  if (p.fold_arc >= 0) return p.fold_arc;
  const double half = 0.5 * (over[0] - from[0]).norm();
  return std::max(0.0, half - 0.5 * (p.fold_lift + p.place_height));
}

/// The page turn shared by the hood and the body: lift by fold_lift, turn over to `over` (see
/// TaskParams::fold_arc) in `duration` (unscaled), pause, open, retreat upwards.
void turn_over_and_let_go(Builder& b, const std::array<Vec3, 2>& from, const std::array<Vec3, 2>& over,
                          double duration, const TaskParams& p) {
  const double k = p.time_scale;
  b.move(at(raised(from, p.fold_lift), 0.0), p.fold_lift_duration * k);
  if (p.fold_arc == 0) {  // the paper's level translation, then lower
    b.move(at(raised(over, p.fold_lift), 0.0), duration * k);
    b.move(at(raised(over, p.place_height), 0.0), p.lower_duration * k);
  } else {
    // Turn the flap over like a page about the fold line (midway between the grasp points and
    // where they are put down), ending just above the table; then a pause before opening.
    b.turn_page(at(raised(over, p.place_height), 0.0), page_rise(from, over, p), duration * k);
    b.hold(p.lower_duration * k);
  }
  b.gripper(kGripperOpen, p.close_duration * k);
  b.move(at(raised(over, p.place_height + p.retreat_height), kGripperOpen), p.retreat_duration * k);
}

}  // namespace

DualArmTrajectory make_grasp(const garments::Garment& g, const Eigen::Isometry3d& T, const TaskParams& p) {
  const Setup s = setup(g, T, p);
  const double k = p.time_scale;
  const double lift = p.lift_height >= 0 ? p.lift_height : s.length + kLiftAboveLength;
  Builder b = approach_and_close(s, p);
  b.move(at(raised(s.grasp, lift), 0.0), p.lift_duration * k);
  b.hold(p.hold_duration * k);
  return b.finish();
}

DualArmTrajectory make_fling(const garments::Garment& g, const Eigen::Isometry3d& T, const TaskParams& p) {
  const Setup s = setup(g, T, p);
  const double k = p.time_scale;
  const double height = p.fling_height >= 0 ? p.fling_height : s.length + kFlingAboveLength;
  Builder b = approach_and_close(s, p);
  const std::array<Vec3, 2> up = raised(s.grasp, height);
  b.move(at(up, 0.0), p.lift_duration * k);
  b.hold(p.fling_pause * k);
  // The sweep: forward along world +x (away from the robots), then back, spreading the arms to
  // fling_spread about their midpoint on the way back.
  const double d = p.fling_distance;
  const double stroke = d > 0 ? kMinJerkPeak * d / p.fling_peak_speed : 0.0;
  const Vec3 fwd(d, 0, 0);
  b.move(at({up[0] + fwd, up[1] + fwd}, 0.0), stroke);
  const double spread = p.fling_spread >= 0 ? p.fling_spread : s.shoulder_distance;
  const Vec3 mid = 0.5 * (up[0] + up[1]);
  Vec3 across = up[0] - up[1];
  across.z() = 0;
  across = across.norm() > 1e-9 ? across.normalized() : Vec3::UnitY();
  const std::array<Vec3, 2> end{mid + 0.5 * spread * across, mid - 0.5 * spread * across};
  b.move(at(end, 0.0), std::max(stroke, 1e-3));
  b.hold(p.hold_duration * k);
  return b.finish();
}

namespace {

/// Where the fold's body turn takes the flap (`from`) and puts it down (`over`): the shoulders to
/// the hem minus the margin, or for a hooded garment folded as people fold one (fold_hooded) the
/// hem grasp points to the shoulders' grasp x plus the margin.
struct Turn {
  std::array<Vec3, 2> from, over;
};
Turn body_turn(const Setup& s, const TaskParams& p) {
  if (s.hood && p.tuck_hood == 1) {
    std::array<double, 2> to;
    for (int a = 0; a < 2; ++a) to[a] = s.grasp_local[a].x() + p.fold_margin;
    return {s.hem_grasp, put_down_at(s, s.hem_grasp, s.hem_local, to, p.fold_margin, "hem", -1)};
  }
  const double hem_put = s.hem_x - p.fold_margin;
  return {s.grasp, put_down_at(s, s.grasp, s.grasp_local, {hem_put, hem_put}, p.fold_margin, "body")};
}

/// A hooded garment (TaskParams::tuck_hood), as people fold a hoodie: the hood is laid over onto
/// the back first, then the hem is brought up to the shoulders. The hood ends between the two
/// halves and never rides on a moving flap: carried on the shoulders' flap, it hangs off once the
/// flap passes vertical and heaps at the neck (docs/validation.md, "The hoodie fold").
DualArmTrajectory fold_hooded(const Setup& s, const TaskParams& p) {
  const double k = p.time_scale;
  // The body: the hem grasp points go to the shoulders' grasp x plus the margin, the mirror of
  // the shoulders-to-hem fold.
  const std::array<Vec3, 2> body_over = body_turn(s, p).over;
  const double body_chord = (body_over[0] - s.hem_grasp[0]).norm();
  // The hood: its face corners go to their mirror image about the neck line, the margin short of
  // it, at the body turn's pace (the duration scales with the chord).
  std::array<double, 2> hood_to;
  for (int a = 0; a < 2; ++a) hood_to[a] = 2 * s.hood_fold_x - s.hood_local[a].x() - p.fold_margin;
  const std::array<Vec3, 2> hood_over = put_down_at(s, s.hood_grasp, s.hood_local, hood_to, p.fold_margin, "hood");
  const double hood_chord = (hood_over[0] - s.hood_grasp[0]).norm();

  Setup hs = s;
  hs.grasp = s.hood_grasp;
  Builder b = approach_and_close(hs, p);                                           // take the hood
  turn_over_and_let_go(b, s.hood_grasp, hood_over, p.fold_duration * hood_chord / body_chord, p);  // onto the back
  b.move(at(raised(s.hem_grasp, p.approach_height), kGripperOpen), p.approach_duration * k);  // over the hem
  b.move(at(s.hem_grasp, kGripperOpen), p.approach_duration * k);                 // down
  b.gripper(0.0, p.close_duration * k);                                             // take the hem
  turn_over_and_let_go(b, s.hem_grasp, body_over, p.fold_duration, p);             // up onto the shoulders
  b.hold(p.settle_duration * k);
  return b.finish();
}

}  // namespace

DualArmTrajectory make_fold(const garments::Garment& g, const Eigen::Isometry3d& T, const TaskParams& p) {
  const Setup s = setup(g, T, p);
  if (s.hood && p.tuck_hood == 1) return fold_hooded(s, p);
  const Turn turn = body_turn(s, p);  // the shoulders to the hem minus the margin
  Builder b = approach_and_close(s, p);
  turn_over_and_let_go(b, turn.from, turn.over, p.fold_duration, p);
  b.hold(p.settle_duration * p.time_scale);
  return b.finish();
}

double fold_page_rise(const garments::Garment& g, const Eigen::Isometry3d& T, const TaskParams& p) {
  const Turn turn = body_turn(setup(g, T, p), p);
  return page_rise(turn.from, turn.over, p);
}

DualArmTrajectory make_task(const std::string& name, const garments::Garment& g, const Eigen::Isometry3d& T,
                            const TaskParams& p) {
  switch (task_kind_from_name(name)) {
    case TaskKind::kGrasp: return make_grasp(g, T, p);
    case TaskKind::kFling: return make_fling(g, T, p);
    case TaskKind::kFold: return make_fold(g, T, p);
  }
  throw InputError(fmt::format("unknown task '{}'", name));
}

}  // namespace gd::tasks
