#include "experiment/experiment.h"

#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>

#include "experiment/shape_stats.h"
#include "garments/generator.h"
#include "garments/refine.h"
#include "garments/obj_import.h"
#include "metrics/alignment.h"
#include "metrics/cloud_io.h"
#include "metrics/report.h"
#include "sim/backend/cpu/omp_threads.h"
#include "sim/demand.h"
#include "sim/log.h"
#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/scene.h"
#include "tasks/frames.h"
#include "tasks/robot_reach.h"
#include "tasks/trajectory.h"

namespace gd::experiment {
namespace fs = std::filesystem;
using sim::InputError;
using sim::Vec3;

namespace {

using Clock = std::chrono::steady_clock;

bool ends_with(const std::string& s, const std::string& suffix) {
  return s.size() >= suffix.size() && std::equal(suffix.rbegin(), suffix.rend(), s.rbegin(),
                                                 [](char a, char b) { return std::tolower(a) == std::tolower(b); });
}

metrics::Cloud to_cloud(const std::vector<Vec3>& x) {
  metrics::Cloud c(x.size());
  for (size_t i = 0; i < x.size(); ++i) c[i] = x[i].cast<float>();
  return c;
}

/// First time at which an arm's gripper is below the closing threshold (fixed-point grab time of
/// generated trajectories); the trajectory start if it never closes.
double first_close_time(const tasks::ArmTrajectory& a, double threshold) {
  for (const tasks::ArmSample& s : a.samples())
    if (s.gripper < threshold) return s.t;
  return a.empty() ? 0.0 : a.start_time();
}

std::string shared_dir() {
  if (const char* e = std::getenv("GD_SHARED_DIR"); e && *e) return e;
#ifdef GD_DEFAULT_SHARED_DIR
  return GD_DEFAULT_SHARED_DIR;
#else
  return "";
#endif
}

/// Robot mode's default TaskParams::grasp_depth, m: the fingertips aim this far below the grasp
/// point, at the table, which stops them (below, robot_grasp_depth adds how high the grasp points lie).
constexpr double kRobotGraspDepth = 0.005;

/// Robot mode's automatic TaskParams::grasp_depth: the fingertips go down to the table, as a
/// gripper picking cloth off a table does, however high the grasp points lie: kRobotGraspDepth
/// below the highest of the task's grasp landmarks above the table top. A flat garment's landmarks
/// lie on the cloth on the table (the depth grows by a few millimetres); a skirt's waist corners sit on its side folds, which
/// stand 2-4 cm tall as loops of fabric, and fingertips aimed 5 mm below them closed in the air
/// on the loop's top and caught it or not by chance (docs/robot.md, "Down to the table").
double robot_grasp_depth(const garments::Garment& g, const Eigen::Isometry3d& place, tasks::TaskKind kind,
                         double table_height) {
  double top = 0;
  for (const Vec3& l : garments::grasp_landmarks(g.landmarks, kind == tasks::TaskKind::kFold))
    top = std::max(top, (place * l).z() - table_height);
  return kRobotGraspDepth + top;
}

/// Writes `data` as a float32 .npy array of `shape` (C order).
void write_npy_f32(const std::string& path, const std::vector<float>& data, const std::vector<size_t>& shape) {
  std::string dims;  // "F, N, 3", or "N," for one dimension
  for (size_t k = 0; k < shape.size(); ++k) dims += (k == 0 ? "" : ", ") + std::to_string(shape[k]);
  if (shape.size() == 1) dims += ",";
  std::string header = fmt::format("{{'descr': '<f4', 'fortran_order': False, 'shape': ({}), }}", dims);
  header.append(63 - (10 + header.size()) % 64, ' ');  // magic (6) + version (2) + length (2): 64-byte aligned
  header.push_back('\n');
  std::ofstream f(path, std::ios::binary);
  if (!f) throw InputError(fmt::format("cannot write '{}'", path));
  const uint16_t len = static_cast<uint16_t>(header.size());
  f.write("\x93NUMPY\x01\x00", 8);
  f.write(reinterpret_cast<const char*>(&len), 2);  // little-endian hosts only (x86-64, arm64)
  f << header;
  f.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size() * sizeof(float)));
  if (!f) throw InputError(fmt::format("error while writing '{}'", path));
}

/// The capture run's animation: kCaptureAnimationFrames (sim, real) pairs, evenly spaced over the
/// record window, each cloud resampled to kCaptureAnimationPoints points.
constexpr int kCaptureAnimationFrames = 60;
constexpr int kCaptureAnimationPoints = 3000;

/// The simulation of one experiment: scene, controller, bookkeeping of statistics and the
/// time series. advance() is the only place that steps the scene (through tasks::run_until).
class Run {
 public:
  Run(std::unique_ptr<sim::Scene> scene, std::unique_ptr<tasks::TaskController> controller, double frame_interval,
      const ProgressFn& progress, const StepObserver& observe, double end_time)
      : scene_(std::move(scene)),
        controller_(std::move(controller)),
        frame_interval_(frame_interval),
        progress_(progress),
        observe_(observe),
        end_time_(end_time),
        robot_(dynamic_cast<const tasks::RobotController*>(controller_.get())) {
    record();
  }

  /// Writes the positions as OUT/meshes/t_<ms>.obj every `interval` seconds from now on.
  void write_meshes(const sim::Mesh& mesh, const std::string& dir, double interval) {
    mesh_ = &mesh;
    mesh_dir_ = dir;
    mesh_interval_ = interval;
    fs::create_directories(dir);
    write_mesh();
  }

  /// Steps until the scene time reaches t (overshoot < 1 dt); false once the scene has failed.
  bool advance(double t) {
    const auto t0 = Clock::now();
    const bool ok = tasks::run_until(*scene_, *controller_, t, [this](const sim::StepStats& s) {
      ++steps_;
      intersecting_max_ = std::max(intersecting_max_, s.intersecting_pairs);
      contacts_max_ = std::max(contacts_max_, s.contacts);
      contact_hessians_ |= 1u << static_cast<unsigned>(s.contact_hessian);
      newton_ += s.newton_iters;
      pcg_ += s.pcg_iters;
      converged_ += s.converged ? 1 : 0;
      stage_ += s.stage;
      if (scene_->failed()) return;
      if (scene_->time() >= next_record_ - 1e-9) record();
      if (mesh_ && scene_->time() >= next_mesh_ - 1e-9) write_mesh();
      if (progress_) progress_(scene_->time(), end_time_, s);
      if (observe_) observe_(*scene_, *controller_);
    });
    stepping_seconds_ += std::chrono::duration<double>(Clock::now() - t0).count();
    return ok;
  }

  sim::Scene& scene() { return *scene_; }
  const tasks::TaskController& controller() const { return *controller_; }
  int steps() const { return steps_; }
  /// Wall seconds spent in advance(): the steps with their controller and bookkeeping, not the
  /// set-up (meshing, loading, settling before planning) or the files written at the end.
  double stepping_seconds() const { return stepping_seconds_; }
  int intersecting_max() const { return intersecting_max_; }
  int contacts_max() const { return contacts_max_; }
  /// The self-contact pair Hessians the steps assembled (StepStats::contact_hessian), in the enum's
  /// order, joined by '+' (one name unless colliders came or went); "" when no step had self-contact.
  std::string contact_hessians() const {
    std::string out;
    for (const auto kind : {sim::ContactHessianKind::kGaussNewton, sim::ContactHessianKind::kProjected,
                            sim::ContactHessianKind::kTermwise})
      if (contact_hessians_ & (1u << static_cast<unsigned>(kind)))
        out += (out.empty() ? "" : "+") + std::string(sim::contact_hessian_name(kind));
    return out;
  }
  long newton() const { return newton_; }
  long pcg() const { return pcg_; }
  long converged() const { return converged_; }
  /// Seconds spent in each solver stage, summed over the steps.
  const sim::StageTimes& stage_seconds() const { return stage_; }

  /// The recorded frames' positions as OUT/animation.npy (float32, (frames, N, 3), world m) and
  /// their times; at most kMaxAnimationFrames (and kMaxAnimationBytes), evenly spaced over the run.
  nlohmann::json write_animation(const std::string& path) const {
    write_npy_f32(path, anim_, {anim_times_.size(), static_cast<size_t>(scene_->vertex_count()), 3});
    const size_t frames = anim_times_.size();
    return {{"file", fs::path(path).filename().string()}, {"frames", frames}, {"times", anim_times_}};
  }

  void write_timeseries(const std::string& path) const {
    std::ofstream f(path);
    if (!f) throw InputError(fmt::format("cannot write '{}'", path));
    f << "t,min_z,max_z,mean_z,extent_x,extent_y,kinetic,contacts,intersecting_pairs,newton_iters,pcg_iters,ms";
    if (robot_)
      f << ",left_gripper,right_gripper,left_squeeze_n,right_squeeze_n,left_table_lift,right_table_lift,"
           "left_grip_limit_n,right_grip_limit_n,left_push_open_n,left_push_close_n,right_push_open_n,"
           "right_push_close_n,left_vertices_open,left_vertices_close,right_vertices_open,right_vertices_close,"
           "left_reached,right_reached,left_pad_cuts,right_pad_cuts,left_pad_cut_depth_mm,right_pad_cut_depth_mm";
    f << "\n";
    for (const std::string& r : rows_) f << r << "\n";
  }

 private:
  void record() {
    const std::vector<Vec3> x = scene_->positions();
    const ClothShape s = shape_of(x, scene_->data().mass);
    const sim::StepStats& st = scene_->last_stats();
    rows_.push_back(fmt::format("{:.5f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6e},{},{},{},{},{:.3f}", scene_->time(),
                                s.min_z, s.max_z, s.mean_z, s.extent_x, s.extent_y, scene_->energies().kinetic,
                                st.contacts, st.intersecting_pairs, st.newton_iters, st.pcg_iters,
                                1e3 * st.seconds));
    if (robot_) {  // robot mode: each hand's opening (m per finger), squeeze (N) and lift off the table (m)
      const tasks::RobotArmState &l = robot_->state(tasks::Arm::kLeft), &r = robot_->state(tasks::Arm::kRight);
      rows_.back() += fmt::format(",{:.6f},{:.6f},{:.4f},{:.4f},{:.6f},{:.6f},{:.4f},{:.4f}", l.gripper, r.gripper,
                                  l.squeeze, r.squeeze, l.table_lift, r.table_lift, l.grip_force, r.grip_force);
      // The squeeze split by the side the cloth pushes from (RobotArmState::push_open ...).
      rows_.back() += fmt::format(",{:.4f},{:.4f},{:.4f},{:.4f},{},{},{},{},{:.4f},{:.4f}", l.push_open, l.push_close,
                                  r.push_open, r.push_close, l.vertices_open, l.vertices_close, r.vertices_open,
                                  r.vertices_close, l.reached, r.reached);
      // Where the pads cut through the cloth (RobotArmState::pad_cuts): count and depth, mm.
      rows_.back() += fmt::format(",{},{},{:.3f},{:.3f}", l.pad_cuts, r.pad_cuts, 1e3 * l.pad_cut_depth,
                                  1e3 * r.pad_cut_depth);
    }
    next_record_ = scene_->time() + frame_interval_;
    // Every anim_stride_-th frame for the animation; past kMaxAnimationFrames every other
    // frame kept is dropped and the stride doubles, so the frames stay evenly spaced.
    if (anim_count_++ % anim_stride_ != 0) return;
    for (const Vec3& p : x)
      for (int k = 0; k < 3; ++k) anim_.push_back(static_cast<float>(p[k]));
    anim_times_.push_back(scene_->time());
    // At most kMaxAnimationFrames, and at most kMaxAnimationBytes (a report's file; 16 frames at least).
    const size_t cap = std::clamp<size_t>(kMaxAnimationBytes / (12 * std::max<size_t>(1, x.size())), 16,
                                          kMaxAnimationFrames);
    if (anim_times_.size() > cap) {
      const size_t n = x.size() * 3;
      size_t kept = 0;
      for (size_t i = 0; i < anim_times_.size(); i += 2, ++kept) {
        std::copy_n(anim_.begin() + i * n, n, anim_.begin() + kept * n);
        anim_times_[kept] = anim_times_[i];
      }
      anim_.resize(kept * n);
      anim_times_.resize(kept);
      anim_stride_ *= 2;
    }
  }
  static constexpr size_t kMaxAnimationFrames = 160;
  static constexpr size_t kMaxAnimationBytes = size_t(32) << 20;

  void write_mesh() {
    const long ms = std::lround(1e3 * scene_->time());
    sim::write_obj(*mesh_, scene_->positions(), fmt::format("{}/t_{:06d}.obj", mesh_dir_, ms));
    next_mesh_ = scene_->time() + mesh_interval_;
  }

  std::unique_ptr<sim::Scene> scene_;
  std::unique_ptr<tasks::TaskController> controller_;
  double frame_interval_;
  const sim::Mesh* mesh_ = nullptr;  // set by write_meshes
  std::string mesh_dir_;
  double mesh_interval_ = 0, next_mesh_ = 0;
  ProgressFn progress_;
  StepObserver observe_;
  double end_time_;
  const tasks::RobotController* robot_;  ///< the controller in robot mode (its arms' columns), else null
  double next_record_ = 0;
  int steps_ = 0, intersecting_max_ = 0, contacts_max_ = 0;
  unsigned contact_hessians_ = 0;  ///< bit k: a step assembled ContactHessianKind k
  double stepping_seconds_ = 0;
  long newton_ = 0, pcg_ = 0, converged_ = 0;
  sim::StageTimes stage_;
  std::vector<std::string> rows_;
  std::vector<float> anim_;           ///< the animation's frames, (frames, N, 3)
  std::vector<double> anim_times_;
  long anim_count_ = 0, anim_stride_ = 1;
};

}  // namespace

sim::SceneOptions ExperimentConfig::default_scene_options() {
  sim::SceneOptions o;
  o.self_contact = true;
  return o;
}

namespace {

/// The config's garment_params as GarmentParams (InputError for an unknown name or bad value).
garments::GarmentParams garment_sizes(const ExperimentConfig& c) {
  garments::GarmentParams sizes;
  for (const auto& [name, value] : c.garment_params) garments::set_garment_param(sizes, name, value);
  return sizes;
}

}  // namespace

void ExperimentConfig::validate() const {
  tasks::task_kind_from_name(task);  // throws with the known names
  if (mode != "pseudo" && mode != "fixed_point" && mode != "robot")
    throw InputError(fmt::format("unknown mode '{}'; use pseudo, fixed_point or robot", mode));
  if (mode == "robot") robot.validate();  // the URDF first of all
  if (out_dir.empty()) throw InputError("no output directory given (--out DIR)");
  if (!garment_position.allFinite() || garment_position.z() <= 0 || std::abs(garment_position.x()) > 10 ||
      std::abs(garment_position.y()) > 10 || garment_position.z() > 2)
    throw InputError(fmt::format("garment position ({}, {}, {}) must be finite, above the table (z > 0, at most 2 m) "
                                 "and within 10 m of the robots",
                                 garment_position.x(), garment_position.y(), garment_position.z()));
  if (garment.empty()) throw InputError("no garment given: a garment type or an .obj path");
  if (place_within_reach && mode != "robot")
    throw InputError(fmt::format("automatic placement (--place-within-reach) fits a task to the robot arms' reach; "
                                 "it needs --mode robot (got '{}')",
                                 mode));
  if (place_within_reach && (!trajectory_file.empty() || !capture_dir.empty()))
    throw InputError("automatic placement (--place-within-reach) moves the garment for a generated task; a given "
                     "trajectory or capture fixes where the garment lies (use --garment-position)");
  if (!(frame_interval > 0) || !std::isfinite(frame_interval))
    throw InputError(fmt::format("frame_interval must be positive (got {})", frame_interval));
  if (!(settle_after >= 0) || !std::isfinite(settle_after))
    throw InputError(fmt::format("settle_after must be >= 0 s (got {})", settle_after));
  if (keep_frames < 0) throw InputError("keep_frames must be >= 0");
  if (!(mesh_interval >= 0) || !std::isfinite(mesh_interval))
    throw InputError(fmt::format("mesh_interval must be >= 0 s (got {})", mesh_interval));
  if (refine_grasp_edge != 0 && !(std::isfinite(refine_grasp_edge) && refine_grasp_edge >= 1e-3))
    throw InputError(fmt::format("the refined edge near the grasp points must be 0 (off) or at least 1 mm (got {} m)",
                                 refine_grasp_edge));
  if (!(std::isfinite(refine_grasp_radius) && refine_grasp_radius > 0))
    throw InputError(fmt::format("the refinement radius round the grasp points must be positive (got {} m)",
                                 refine_grasp_radius));
  if (!garment_params.empty() && ends_with(garment, ".obj"))
    throw InputError("garment_params size a generated garment; an .obj mesh takes none");
  if (!garment_params.empty()) garments::make_pattern(garment, garment_sizes(*this));  // sizes that make no garment
  scene.validate();
  task_params.validate();
}

garments::Garment make_experiment_garment(const ExperimentConfig& c) {
  garments::Garment g = ends_with(c.garment, ".obj") ? garments::load_garment_obj(c.garment)
                                                     : garments::make_garment(c.garment, c.vertices, garment_sizes(c));
  if (c.refine_grasp_edge > 0) {
    garments::RefineRegion region;
    region.centres = garments::grasp_landmarks(g.landmarks, tasks::task_kind_from_name(c.task) == tasks::TaskKind::kFold);
    region.radius = c.refine_grasp_radius;
    region.edge = c.refine_grasp_edge;
    region.max_vertices = c.max_vertices;
    const size_t before = g.mesh.x.size();
    int added = 0;
    try {
      added = garments::refine_near(g, region);
    } catch (const garments::TooManyVertices& e) {
      if (c.max_vertices <= 0) throw;
      throw garments::TooManyVertices(fmt::format("{} ({}: {} vertices)", e.what(), c.vertices_limit_name, c.max_vertices));
    }
    gd::log().info("garment refined to {:.1f} mm edges within {:.1f} cm of its {} grasp points: {} -> {} vertices",
                   1e3 * region.edge, 1e2 * region.radius, region.centres.size(), before, before + added);
  }
  return g;
}

namespace {

/// A garment's state after settling on the table.
struct Settled {
  std::vector<Vec3> x, v;
  int steps = 0;
  double seconds = 0;  ///< wall time of the settling steps
};

/// A generated task plans its grasp points on the garment as it lies when the arms arrive, not on
/// the layout it starts from: a sewn garment laid out flat is not at rest (gathered tiers
/// contract, the layers drop onto each other and the table, by centimetres in the first second;
/// the cake skirt's right grasp point had moved 2-5 cm by the time its gripper closed). The
/// garment settles for `seconds` in a scene of its own; its landmarks then move with their
/// nearest vertices and its mesh takes the settled shape (garment frame). The run starts from the
/// returned state.
Settled settle_before_planning(const sim::Mesh& mesh, const sim::Material& material, const sim::SceneOptions& opt,
                               double seconds, const Eigen::Isometry3d& place, garments::Garment* g) {
  const auto t0 = Clock::now();
  auto scene = sim::Scene::create(mesh, material, opt);
  const int steps = static_cast<int>(std::ceil(seconds / opt.dt - 1e-9));
  for (int k = 0; k < steps; ++k)
    if (!scene->step()) break;  // the run meets the same failure and reports it
  Settled st{scene->positions(), scene->velocities(), steps, std::chrono::duration<double>(Clock::now() - t0).count()};
  const Eigen::Isometry3d inv = place.inverse();
  const auto move = [&](Vec3& p) {  // p in the garment frame
    const int best = sim::nearest_vertex(g->mesh, p);
    p += inv.linear() * (st.x[best] - mesh.x[best]);
  };
  garments::Landmarks& l = g->landmarks;
  for (Vec3* p : {&l.left_shoulder, &l.right_shoulder, &l.left_hem, &l.right_hem}) move(*p);
  if (l.has_hood)
    for (Vec3* p : {&l.left_hood, &l.right_hood}) move(*p);
  for (size_t i = 0; i < g->mesh.x.size(); ++i) g->mesh.x[i] = inv * st.x[i];
  gd::log().info("garment settled for {:.2f} s before planning ({} steps)", seconds, steps);
  return st;
}

/// The height of a generated task that robot mode fits to the arms' reach: the grasp's lift, the
/// fling's height or the fold's page turn (TaskParams::fold_arc), fitted where left to its default
/// (< 0), and the height wanted: pseudo mode's default (the garment's length plus 0.1 / 0.15 m;
/// the fold's half circle about its fold line) or the one given.
struct TaskHeight {
  double tasks::TaskParams::*member = nullptr;  ///< &TaskParams::lift_height, fling_height or fold_arc
  const char* param = "";                        ///< its name as --task-param takes it
  const char* what = "";                         ///< what it is, for the log
  bool defaulted = false;                        ///< left to its default: fitted to the reach
  double wanted = 0.0;
  /// m: the lowest fitted. The fold's turns are fitted from 1 cm up: fold_arc = 0 is another
  /// path (the level translation), not the lowest turn.
  double lowest = 0.0;
  /// rad: the hands' tilt allowed. A lift's: RobotOptions::lift_max_tilt. The fold's turn is
  /// lowered only where the arms cannot follow it at all (RobotOptions::max_tilt): a lower turn
  /// leaves the flap slack and the garment slides (docs/validation.md).
  double max_tilt = 0.0;
  /// m, >= 0 for the fold's put-down margin (fold_margin_to_reach): the widest margin tried, and
  /// the fitted "height" h is widest - margin (the highest h, the narrowest margin within reach).
  /// < 0: the parameter is h itself.
  double widest = -1.0;

  /// The parameter's value at fitted height h.
  double value(double h) const { return widest < 0 ? h : widest - h; }
  /// Sets the parameter in *p to its value at fitted height h.
  void set(tasks::TaskParams* p, double h) const { p->*member = value(h); }
};

/// The widest put-down margin robot mode gives a fold, as a fraction of the garment's length:
/// the shoulders are then put down a quarter of the length short of the hem, still on the bottom
/// half (docs/robot.md, "A shorter stroke instead of a lower turn").
constexpr double kWidestFoldMargin = 0.25;

TaskHeight task_height(const ExperimentConfig& config, const garments::Garment& garment, const tasks::TaskParams& p) {
  TaskHeight h;
  if (config.task == "grasp") {
    h = {&tasks::TaskParams::lift_height, "lift_height", "grasp's lift"};
  } else if (config.task == "fling") {
    h = {&tasks::TaskParams::fling_height, "fling_height", "fling's height"};
  } else if (config.task == "fold") {
    h = {&tasks::TaskParams::fold_arc, "fold_arc", "fold's page turn"};
  } else {
    return h;
  }
  h.defaulted = p.*h.member < 0;
  if (!h.defaulted) {
    h.wanted = p.*h.member;
  } else if (config.task == "fold") {  // the chord, so the rise, is the same wherever the garment lies
    constexpr double kLowestTurn = 0.01;
    h.wanted = tasks::fold_page_rise(garment, Eigen::Isometry3d::Identity(), p);
    h.lowest = kLowestTurn;
    h.max_tilt = config.robot.max_tilt;
    if (h.wanted <= kLowestTurn) h.defaulted = false;  // a turn that low is nothing to lower
    return h;
  } else {
    h.wanted = garment.length + (config.task == "grasp" ? tasks::kLiftAboveLength : tasks::kFlingAboveLength);
  }
  h.max_tilt = config.robot.lift_max_tilt;
  return h;
}

/// A generated fold's put-down margin (TaskParams::fold_margin) as robot mode fits it where the
/// arms cannot follow the fold's half circle: widened, up to kWidestFoldMargin of the garment's
/// length, until they can. A shorter stroke keeps the half circle (so a taut flap) with its far
/// end and its top nearer the arms' bases. Not fitted (`member` null) where the fold's page turn
/// or its margin was given (a margin other than TaskParams' default).
TaskHeight fold_margin_to_reach(const ExperimentConfig& config, const garments::Garment& garment,
                                const tasks::TaskParams& p) {
  TaskHeight h;
  if (config.task != "fold" || p.fold_arc >= 0 || p.fold_margin != tasks::TaskParams{}.fold_margin) return h;
  h = {&tasks::TaskParams::fold_margin, "fold_margin", "fold's put-down margin"};
  h.widest = std::max(p.fold_margin, kWidestFoldMargin * garment.length);
  h.defaulted = h.widest > p.fold_margin;
  h.wanted = h.widest - p.fold_margin;
  h.lowest = 0;
  h.max_tilt = config.robot.max_tilt;
  return h;
}

/// Says what a fold's lowered page turn costs, where it was lowered.
void warn_slack_turn(const tasks::ReachFit& fit) {
  if (fit.lowered())
    gd::log().warn("robot mode: the fold's page turn is {:.0f}% of pseudo mode's half circle: the flap is slack on "
                   "the way over, and a T-shirt may slide along the table rather than fold (docs/robot.md, \"The fold "
                   "within reach\")",
                   100 * fit.height / fit.wanted);
}

/// A generated task's parameter robot mode fitted to the arms' reach (summary.json's
/// robot.height_fitted): `reach` holds the parameter's own values (m), wanted and taken.
struct FittedParam {
  const char* param = "";  ///< its name as --task-param takes it
  tasks::ReachFit reach;
  bool lowered = false;    ///< a height taken lower than wanted (a margin is widened, not lowered)
};

/// `fit`, found for `v`'s fitted height h, in the parameter's own values.
FittedParam fitted(const TaskHeight& v, tasks::ReachFit fit) {
  FittedParam f;
  f.param = v.param;
  f.lowered = v.widest < 0 && fit.lowered();
  fit.wanted = v.value(fit.wanted);
  fit.height = v.value(fit.height);
  f.reach = fit;
  return f;
}

/// Logs what a fit changed: a lift, a fling's height or a page turn lowered, a margin widened.
void log_fit(const TaskHeight& v, const FittedParam& f, double seconds) {
  constexpr double kDeg = 180 / 3.14159265358979323846;
  const tasks::ReachFit& r = f.reach;
  if (r.height == r.wanted) return;
  gd::log().warn("robot mode: the {} {} from {:.3f} m (pseudo mode's) to {:.3f} m, the {} at which the arms keep their "
                 "hands within {:.0f} deg of pointing down ({:.1f} deg; {} inverse-kinematics trials, {:.1f} s); give "
                 "--task-param {}=VALUE to choose",
                 v.what, v.widest < 0 ? "lowered" : "widened", r.wanted, r.height,
                 v.widest < 0 ? "highest" : "narrowest", r.bound * kDeg, r.tilt * kDeg, r.trials, seconds, v.param);
}

/// Robot mode: a generated grasp's lift, fling's height or fold's page turn left to its default
/// (pseudo mode's: the garment's length plus 0.1 / 0.15 m, a half circle about the fold line)
/// fitted to the arms' reach and written into *planned: a lift or a fling's height lowered to the
/// highest one the arms reach with their hands within TaskHeight::max_tilt of pointing down, or a
/// degree beyond what the task needs at its lowest where that is more (tasks/robot_reach.h). A fold
/// whose half circle they cannot follow first has its put-down margin widened (fold_margin_to_reach:
/// the flap stays taut), and only where no margin up to the widest brings it within reach its turn
/// lowered. A height the user gave is kept as it is (an unreachable one is refused by the
/// controller, naming the pose).
std::optional<FittedParam> fit_to_reach(const ExperimentConfig& config, const garments::Garment& garment,
                                        const Eigen::Isometry3d& place,
                                        const std::shared_ptr<const robot::ArmModel>& arms,
                                        tasks::TaskParams* planned) {
  auto fit = [&](const TaskHeight& v) {
    const auto t0 = std::chrono::steady_clock::now();
    const FittedParam f = fitted(
        v, tasks::fit_height_to_reach(
               [&](double h) {
                 tasks::TaskParams p = *planned;
                 v.set(&p, h);
                 return tasks::make_task(config.task, garment, place, p);
               },
               v.wanted, config.robot, arms, v.max_tilt, 0.01, 8, v.lowest));
    planned->*v.member = f.reach.height;
    log_fit(v, f, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    return f;
  };
  const TaskHeight height = task_height(config, garment, *planned);
  if (!height.member || !height.defaulted) return std::nullopt;
  if (config.task == "fold") {
    TaskHeight half_circle = height;
    half_circle.lowest = half_circle.wanted;  // one trial: the half circle as it is
    try {
      return fit(half_circle);
    } catch (const InputError&) {
      // out of reach: a wider margin, else a lower turn
    }
    const TaskHeight margin = fold_margin_to_reach(config, garment, *planned);
    if (margin.member && margin.defaulted) {
      try {
        return fit(margin);
      } catch (const InputError&) {
        // out of reach even at the widest margin
      }
    }
  }
  try {
    const FittedParam f = fit(height);
    if (config.task == "fold") warn_slack_turn(f.reach);
    return f;
  } catch (const InputError&) {
    if (config.task != "fold") throw;
    return std::nullopt;  // no low turn within reach: the run takes pseudo mode's (or refuses it, naming the pose)
  }
}

/// What place_to_reach found: where, and the parameter fitted there (absent: none was).
struct Placed {
  tasks::PlacementFit fit;  ///< reach.height / wanted in the fitted parameter's values where one was
  std::optional<FittedParam> param;
};

/// Robot mode with ExperimentConfig::place_within_reach: the garment moved along x to where the
/// arms follow the generated task best (tasks::place_within_reach), a default lift or fling height
/// fitted there as fit_to_reach does. A fold keeps pseudo mode's half circle where the arms follow
/// it at some place (placed where the hands tilt least); else it is placed where the narrowest
/// put-down margin brings the half circle within reach (fold_margin_to_reach), and where none
/// does, where its lowest turn tilts the hands least (its ends, which no turn moves, set that),
/// its turn lowered there. Moves *place, the world-frame mesh and the settled state by the shift
/// found (the table is a plane: the settled shape is the same anywhere on it) and writes a fitted
/// parameter into *planned.
Placed place_to_reach(const ExperimentConfig& config, const garments::Garment& garment,
                      const std::shared_ptr<const robot::ArmModel>& arms, Eigen::Isometry3d* place, sim::Mesh* mesh,
                      Settled* settled, tasks::TaskParams* planned) {
  const TaskHeight height = task_height(config, garment, *planned);
  const TaskHeight margin = fold_margin_to_reach(config, garment, *planned);
  const bool fit_height = height.member && height.defaulted;
  const auto t0 = std::chrono::steady_clock::now();
  const Eigen::Isometry3d given = *place;
  auto make_with = [&](const TaskHeight& v) {
    return [&](double shift, double h) {
      tasks::TaskParams p = *planned;
      if (v.member) v.set(&p, h);
      Eigen::Isometry3d moved = given;
      moved.translation().x() += shift;
      return tasks::make_task(config.task, garment, moved, p);
    };
  };
  auto place_at = [&](const TaskHeight& v, double h, bool fit_h, double max_tilt) {
    return tasks::place_within_reach(make_with(v), h, fit_h, tasks::default_placement_shifts(), config.robot, arms,
                                     max_tilt, 0.01, 8, v.lowest);
  };
  Placed placed;
  const TaskHeight* fitted_by = nullptr;  // the parameter fitted, where one was
  if (!fit_height || config.task != "fold") {
    placed.fit = place_at(height, height.wanted, fit_height, config.robot.lift_max_tilt);
    if (fit_height) fitted_by = &height;
  } else {
    try {
      placed.fit = place_at(height, height.wanted, false, config.robot.lift_max_tilt);
    } catch (const InputError&) {
      bool widened = false;
      if (margin.member && margin.defaulted) {
        try {
          placed.fit = place_at(margin, margin.wanted, true, margin.max_tilt);
          fitted_by = &margin;
          widened = true;
        } catch (const InputError&) {
          // no margin up to the widest brings the half circle within reach anywhere
        }
      }
      if (!widened) {
        placed.fit = place_at(height, height.lowest, false, config.robot.lift_max_tilt);
        const int trials = placed.fit.trials;
        placed.fit.reach = tasks::fit_height_to_reach([&](double h) { return make_with(height)(placed.fit.shift, h); },
                                                      height.wanted, config.robot, arms, height.max_tilt, 0.01, 8,
                                                      height.lowest);
        placed.fit.trials = trials + placed.fit.reach.trials;
        placed.fit.height_fitted = true;
        fitted_by = &height;
      }
    }
  }
  if (fitted_by) {
    placed.param = fitted(*fitted_by, placed.fit.reach);
    placed.fit.reach = placed.param->reach;
    planned->*fitted_by->member = placed.param->reach.height;
  }
  const Vec3 dx(placed.fit.shift, 0, 0);
  place->translation() += dx;
  for (Vec3& p : mesh->x) p += dx;
  for (Vec3& p : settled->x) p += dx;
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  constexpr double kDeg = 180 / 3.14159265358979323846;
  gd::log().info("robot mode: garment moved {:.3f} m along x, {} the arms' bases (x {:.3f} -> {:.3f} m), "
                 "where {}the hands tilt at most {:.1f} deg ({} of {} placements within reach, {} inverse-kinematics "
                 "trials, {:.1f} s)",
                 std::abs(placed.fit.shift), placed.fit.shift < 0 ? "towards" : "away from", given.translation().x(),
                 place->translation().x(),
                 fitted_by ? fmt::format("the {} is {:.3f} m and ", fitted_by->what, placed.fit.reach.height) : "",
                 placed.fit.reach.tilt * kDeg, placed.fit.reachable, placed.fit.candidates, placed.fit.trials, s);
  if (fitted_by == &height && config.task == "fold") warn_slack_turn(placed.fit.reach);
  return placed;
}

/// Runs argv[0] (looked up in PATH) with its stdout sent to our stderr (or to /dev/null when
/// quiet) and waits. No shell, so paths need no quoting. Returns the exit status (-1: could not run).
int run_process(const std::vector<std::string>& args, bool quiet) {
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  if (quiet) {
    posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 2, "/dev/null", O_WRONLY, 0);
  } else {
    posix_spawn_file_actions_adddup2(&fa, 2, 1);
  }
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, argv[0], &fa, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) return -1;
  int status = 0;
  while (waitpid(pid, &status, 0) < 0)
    if (errno != EINTR) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

}  // namespace

bool run_plot_script(const std::string& script_name, const std::string& dir) {
  std::vector<std::string> pythons;
  if (const char* e = std::getenv("GD_PYTHON"); e && *e) pythons.emplace_back(e);
#ifdef GD_BUILD_VENV_PYTHON
  pythons.emplace_back(GD_BUILD_VENV_PYTHON);
#endif
  pythons.emplace_back("python3");
  const std::string script = std::string(GD_SOURCE_DIR) + "/scripts/" + script_name;
  if (!fs::exists(script)) {
    gd::log().warn("plots skipped: {} not found", script);
    return false;
  }
  for (const std::string& py : pythons) {
    if (py != "python3" && !fs::exists(py)) continue;
    if (run_process({py, "-c", "import matplotlib"}, true) != 0) continue;
    if (run_process({py, script, dir}, false) == 0) return true;
    gd::log().warn("plots: {} {} {} failed", py, script, dir);
    return false;
  }
  gd::log().warn("plots skipped: no Python with matplotlib (set GD_PYTHON or run scripts/build)");
  return false;
}

namespace {

/// Robot mode on a generated task: the median longest edge of the cloth's triangles within 3 cm of
/// the grasp points (summary.json's robot.grasp_edge_m), and a line saying so where it is longer
/// than the pads are thick and their surface samples are on: such cloth cannot fold between the
/// closing pads (docs/robot.md, "The garment refined under the pads"). Not a warning: with the
/// fingertips down at the table every hand of the garments' grasps, folds and flings tried at 2000
/// vertices held the cloth as meshed ("The skirts' folds and flings at the table").
double check_grasp_mesh(const ExperimentConfig& c, const garments::Garment& g) {
  constexpr double kRadius = 0.03;
  const double edge = garments::edge_near(g, garments::grasp_landmarks(g.landmarks, tasks::task_kind_from_name(c.task) ==
                                                                                        tasks::TaskKind::kFold),
                                          kRadius);
  const double thickness = 2 * c.robot.arm.pad.half_extents.minCoeff();
  if (c.robot.pad_samples && edge > thickness && thickness > 0)
    gd::log().info("robot mode: the cloth round the grasp points is meshed at {:.1f} mm (the median edge within {:.0f} "
                   "cm), coarser than the pads are thick ({:.1f} mm): it cannot fold between the closing pads; with "
                   "the fingertips down at the table every hand of the garments' grasps, folds and flings tried at "
                   "2000 vertices held it as meshed; where a hand misses, --refine-grasp 0.008 --refine-grasp-radius "
                   "0.03 meshes it finer there and --task-param grasp_inset=0.01 takes the grasp points 1 cm onto "
                   "the cloth (together at some 2-3 times the cost of a step; docs/robot.md, \"The skirts' folds "
                   "and flings at the table\")",
                   1e3 * edge, 1e2 * kRadius, 1e3 * thickness);
  return edge;
}

}  // namespace

bool plot_report(const std::string& dir) { return run_plot_script("plot_report.py", dir); }

ExperimentResult run_experiment(const ExperimentConfig& config, const ProgressFn& progress,
                                const StepObserver& observe) {
  config.validate();
  const auto t0 = Clock::now();
  fs::create_directories(config.out_dir);
  const std::string out = config.out_dir;
  const tasks::TaskKind kind = tasks::task_kind_from_name(config.task);
  const bool fixed_point = config.mode == "fixed_point";

  // Garment, placed at RGBench's initial pose (its position config.garment_position).
  garments::Garment garment = make_experiment_garment(config);
  Eigen::Isometry3d place = tasks::default_garment_pose();
  place.translation() = config.garment_position;
  sim::Mesh mesh = garment.mesh;
  for (Vec3& p : mesh.x) p = place * p;
  const sim::Material base = sim::MaterialLibrary::load_default().get(config.material);
  const sim::Material material = config.material_params.empty() ? base
                                                                : sim::with_catalogue_params(base, config.material_params);

  // Capture and trajectory.
  std::optional<metrics::Capture> capture;
  if (!config.capture_dir.empty()) {
    metrics::CaptureOptions co;
    co.experiment_library = config.experiment_library;
    capture = metrics::load_capture(config.capture_dir, co);
  }
  tasks::DualArmTrajectory traj;
  std::string traj_source;
  // The generated task's parameters, "auto" ones resolved (summary.json records these).
  tasks::TaskParams planned = config.task_params;
  if (planned.grasp_depth < 0) planned.grasp_depth = config.mode == "robot" ? kRobotGraspDepth : 0.0;
  std::optional<Settled> settled;  // generated tasks: the garment settled before planning
  // Robot mode: the arms, loaded once (the reach fit and the controller share them).
  std::shared_ptr<const robot::ArmModel> loaded_arms;
  auto arm_model = [&] {
    if (!loaded_arms) {
      config.robot.validate();
      loaded_arms = std::make_shared<const robot::ArmModel>(robot::ArmModel::load(config.robot.urdf, config.robot.arm));
    }
    return loaded_arms;
  };
  std::optional<FittedParam> reach;  // robot mode: a generated task's lift, height, turn or margin fitted to the arms' reach
  std::optional<tasks::PlacementFit> placement;  // robot mode: the garment placed within the arms' reach
  if (!config.trajectory_file.empty()) {
    traj = tasks::read_trajectory(config.trajectory_file);
    traj_source = config.trajectory_file;
  } else if (capture) {
    if (!capture->has_left_joints || !capture->has_right_joints)
      throw InputError(fmt::format("capture '{}' has no joints/{{left,right}}_arm_joint_states_and_end_pose.csv; "
                                   "give a trajectory file (--trajectory)",
                                   capture->dir));
    traj = tasks::read_rgbench_joints(capture->left_joints_csv, capture->right_joints_csv);
    traj_source = "capture joints";
  } else {
    settled = settle_before_planning(mesh, material, config.scene, config.task_params.start_delay, place, &garment);
    if (config.mode == "robot" && config.task_params.grasp_depth < 0)  // down to the table from the settled grasp points
      planned.grasp_depth = robot_grasp_depth(garment, place, kind, config.scene.table_height);
    if (config.mode == "robot" && config.place_within_reach) {
      Placed placed = place_to_reach(config, garment, arm_model(), &place, &mesh, &*settled, &planned);
      placement = placed.fit;
      reach = placed.param;  // summary.json's robot.height_fitted, as without placement
    } else if (config.mode == "robot") {
      reach = fit_to_reach(config, garment, place, arm_model(), &planned);
    }
    traj = tasks::make_task(config.task, garment, place, planned);
    traj_source = "generated " + config.task;
  }
  tasks::write_trajectory_csv(out + "/trajectory.csv", traj);

  // Grippers.
  tasks::GripperOptions go = config.grippers;
  go.mode = fixed_point ? tasks::GraspMode::kFixedPoint : tasks::GraspMode::kPseudoGrasp;
  go.action = kind;
  if (fixed_point) {
    go.grab_time = capture && capture->has_window ? capture->window.start_calculate_time
                                                  : first_close_time(traj.left, go.close_threshold);
    go.shoulder_vertices = config.shoulder_vertices;
    if (go.shoulder_vertices[0] < 0) go.shoulder_vertices[0] = garment.landmarks.left_shoulder_vertex;
    if (go.shoulder_vertices[1] < 0) go.shoulder_vertices[1] = garment.landmarks.right_shoulder_vertex;
  }
  std::unique_ptr<tasks::TaskController> controller;
  const tasks::RobotController* robot = nullptr;
  std::optional<double> grasp_edge;  // robot mode, generated task: how finely the cloth is meshed round the grasp points
  if (config.mode == "robot" && settled) grasp_edge = check_grasp_mesh(config, garment);
  if (config.mode == "robot") {
    auto r = std::make_unique<tasks::RobotController>(traj, config.robot, arm_model());
    robot = r.get();
    // The arms' joints (recorded or solved) as RGBench's joints CSVs: its own robot mode replays them.
    tasks::write_rgbench_joints(out + "/joints", r->trajectory());
    controller = std::move(r);
  } else {
    controller = std::make_unique<tasks::GripperController>(traj, go);
  }
  const double prepare = controller->sim_prepare_time();

  // Schedule: with a capture, RGBench's per-real-frame loop; otherwise the trajectory + settling.
  std::vector<metrics::ScheduledFrame> schedule;
  double end_time = controller->end_time() + config.settle_after;
  if (capture) {
    schedule = metrics::evaluation_schedule(*capture, traj.master_start_time, prepare);
    if (schedule.empty())
      throw InputError(fmt::format("capture '{}': no frame at or after the trajectory's start time {:.6f}",
                                   capture->dir, traj.master_start_time));
    end_time = 0;
    for (const auto& f : schedule)
      if (metrics::in_record_window(capture->window, f.compensated - prepare)) end_time = f.compensated;
    if (end_time <= 0) end_time = schedule.back().compensated;
  }

  const double steps = end_time / config.scene.dt;
  if (config.max_steps > 0 && steps > static_cast<double>(config.max_steps))
    throw InputError(fmt::format("the run would take {:.3g} steps ({:.4g} s simulated at dt {:g} s), over the limit of "
                                 "{} ({}); shorten it (time_scale, settle, dt) or raise the limit",
                                 steps, end_time, config.scene.dt, config.max_steps, config.steps_limit_name));
  sim::SceneOptions scene_options = config.scene;
  if (config.mode == "robot") {
    scene_options.pad_stiffness = config.robot.pad_stiffness;  // the hands' lag spring
    scene_options.pad_samples = config.robot.pad_samples;      // the cloth's surface samples held out of the pads
  }
  auto scene = sim::Scene::create(mesh, material, scene_options);
  if (settled) scene->set_state(settled->x, settled->v);
  gd::log().info("experiment: {} ({} vertices, {} triangles), {}, {} in {} mode from {}, {:.2f} s simulated",
                 garment.type, scene->vertex_count(), mesh.tris.size(), config.material, config.task, config.mode,
                 traj_source, end_time);
  const std::vector<Vec3> x0 = scene->positions();
  sim::write_obj(mesh, x0, out + "/initial.obj");
  Run run(std::move(scene), std::move(controller), config.frame_interval, progress, observe, end_time);
  if (config.mesh_interval > 0) run.write_meshes(mesh, out + "/meshes", config.mesh_interval);

  ExperimentResult result;
  nlohmann::json& s = result.summary;
  if (capture) {
    metrics::EvalOptions eo;
    eo.master_start_time = traj.master_start_time;
    eo.prepare_time = prepare;
    eo.keep_frames = config.keep_frames;
    eo.animation_frames = kCaptureAnimationFrames;
    eo.animation_points = kCaptureAnimationPoints;
    if (config.icp) {
      // The first evaluated frame shows the garment lying on the table before the arms act (the
      // paper aligns the initial state with a template): register it against the simulated
      // garment at that frame's instant (the scene is stepped there first; the evaluation then
      // starts from it). Point-to-point, since point-to-plane cannot pin the in-plane motion of a
      // flat sheet; a correction that fits no better than the calibration is refused.
      const metrics::ScheduledFrame& first = schedule.front();
      if (!run.advance(first.compensated)) {
        gd::log().warn("ICP skipped: the simulation failed before the first capture frame");
        s["icp"] = {{"accepted", false}, {"skipped", "the simulation failed before the first frame"}};
      } else {
        metrics::IcpReport rep;
        metrics::IcpOptions io;
        io.point_to_plane = false;
        const Eigen::Matrix4d T = metrics::refine_world_to_camera(to_cloud(run.scene().positions()),
                                                                  metrics::frame_in_camera(*capture, first.frame),
                                                                  capture->world_to_camera, io, &rep);
        eo.world_to_camera = T;
        s["icp"] = {{"accepted", rep.accepted},       {"converged", rep.converged},
                    {"fitness", rep.fitness},         {"initial_fitness", rep.initial_fitness},
                    {"rotation_deg", rep.rotation_deg}, {"translation", rep.translation},
                    {"sim_time", run.scene().time()}};
      }
    }
    const metrics::EvalResult ev = metrics::run_evaluation(*capture, eo, [&](double t) {
      metrics::SimSample smp;
      if (!run.advance(t)) return smp;  // no vertices: the frame is skipped
      smp.vertices = to_cloud(run.scene().positions());
      smp.sim_time = run.scene().time();
      return smp;
    });
    result.rows = ev.rows;
    const metrics::Summary sum = metrics::summarize(ev.rows, capture->window);
    nlohmann::json extra = {{"garment", capture->garment.empty() ? garment.type : capture->garment},
                            {"action", config.task},
                            {"sample", capture->sample},
                            {"simulator", "garmentdynamics"},
                            {"mode", config.mode},
                            {"camera_delay", capture->camera_delay},
                            {"capture_kind", capture->synthetic.empty() ? "real" : "synthetic"}};
    metrics::write_metrics_csv(out + "/metrics.csv", ev.rows, capture->window);
    metrics::write_summary_json(out + "/metrics_summary.json", ev.rows, capture->window, extra);
    metrics::write_report_frames(out, ev.kept);
    if (!ev.animation.empty()) {  // OUT/capture_animation.npy: (frames, 2: sim and real, points, 3), world m
      std::vector<float> a;
      a.reserve(ev.animation.size() * 2 * kCaptureAnimationPoints * 3);
      nlohmann::json times = nlohmann::json::array();
      for (const metrics::FramePair& p : ev.animation) {
        for (const metrics::Cloud* c : {&p.sim, &p.real})
          for (const auto& q : *c)
            for (int k = 0; k < 3; ++k) a.push_back(q[k]);
        times.push_back(p.sim_time);
      }
      write_npy_f32(out + "/capture_animation.npy", a,
                    {ev.animation.size(), 2, static_cast<size_t>(kCaptureAnimationPoints), 3});
      s["capture_animation"] = {{"file", "capture_animation.npy"}, {"frames", ev.animation.size()},
                                {"points", kCaptureAnimationPoints}, {"times", times}};
    }
    const nlohmann::json mean = metrics::to_json(sum.mean), sd = metrics::to_json(sum.std_dev);
    for (auto it = mean.begin(); it != mean.end(); ++it) s[it.key()] = it.value();
    s["metrics_std"] = sd;
    s["frames_in_window"] = sum.frames;
    s["camera_delay"] = capture->camera_delay;
    s["capture"] = capture->dir;
    s["capture_kind"] = capture->synthetic.empty() ? "real" : "synthetic";
    if (!capture->synthetic.empty()) s["capture_synthetic"] = capture->synthetic;
    const std::string base = config.baselines_csv.empty() ? shared_dir() + "/data/rgbench/paper_baselines.csv"
                                                          : config.baselines_csv;
    if (fs::exists(base)) {
      const std::string g = extra["garment"];
      metrics::write_comparison(out, g, config.task, config.mode, "garmentdynamics (ours)", sum.mean, 1,
                                metrics::load_paper_baselines(base, metrics::paper_garment(g), config.task),
                                capture->synthetic);
    }
  } else {
    run.advance(end_time);
  }
  if (progress) progress(end_time, end_time, run.scene().last_stats());

  // Files and summary.
  sim::Scene& sc = run.scene();
  const std::vector<Vec3> xf = sc.positions();
  sim::write_obj(mesh, xf, out + "/final.obj");
  run.write_timeseries(out + "/timeseries.csv");
  result.summary["animation"] = run.write_animation(out + "/animation.npy");
  const ClothShape fin = shape_of(xf, sc.data().mass), ini = shape_of(x0, sc.data().mass);
  const double wall = std::chrono::duration<double>(Clock::now() - t0).count();
  s["garment"] = garment.type;
  s["garment_source"] = config.garment;
  s["garment_params"] = nlohmann::json::object();
  for (const auto& [name, value] : config.garment_params) s["garment_params"][name] = value;
  s["material"] = config.material;
  if (!config.material_params.empty()) s["material_params"] = config.material_params;
  s["task"] = config.task;
  s["mode"] = config.mode;
  // Where the garment lay: the given position, moved by automatic placement where that ran.
  const Vec3 position = config.garment_position + Vec3(placement ? placement->shift : 0.0, 0, 0);
  s["garment_position"] = {position.x(), position.y(), position.z()};
  if (config.refine_grasp_edge > 0)
    s["refine_grasp"] = {{"edge_m", config.refine_grasp_edge}, {"radius_m", config.refine_grasp_radius}};
  s["trajectory"] = traj_source;
  // The generated task's parameters (defaults included); none for a trajectory file or capture.
  s["task_params"] = nlohmann::json::object();
  if (config.trajectory_file.empty() && !capture)
    for (const auto& [name, value] : tasks::task_param_values(planned)) s["task_params"][name] = value;
  s["vertices"] = sc.vertex_count();
  s["triangles"] = mesh.tris.size();
  s["steps"] = run.steps();
  s["frames"] = capture ? result.rows.size() : static_cast<size_t>(std::floor(sc.time() / config.frame_interval)) + 1;
  s["dt"] = config.scene.dt;
  s["sim_seconds"] = sc.time();
  s["wall_seconds"] = wall;
  // Per step of the run: its stepping time only. Meshing or loading the garment, settling it
  // before planning (its own steps, reported apart) and writing the files are set-up.
  s["stepping_seconds"] = run.stepping_seconds();
  s["setup_seconds"] = wall - run.stepping_seconds();
  s["ms_per_step"] = run.steps() > 0 ? 1e3 * run.stepping_seconds() / run.steps() : 0.0;
  s["settle_steps"] = settled ? settled->steps : 0;
  s["settle_ms_per_step"] = settled && settled->steps > 0 ? 1e3 * settled->seconds / settled->steps : 0.0;
  s["newton_per_step"] = run.steps() > 0 ? double(run.newton()) / run.steps() : 0.0;
  s["pcg_per_step"] = run.steps() > 0 ? double(run.pcg()) / run.steps() : 0.0;
  s["converged_fraction"] = run.steps() > 0 ? double(run.converged()) / run.steps() : 0.0;
  // Where the steps' time went: mean milliseconds per step in each solver stage.
  s["stage_ms_per_step"] = nlohmann::json::object();
  if (run.steps() > 0)
    run.stage_seconds().for_each_ms([&](const char* name, double ms) { s["stage_ms_per_step"][name] = ms / run.steps(); });
  s["preconditioner"] = sim::preconditioner_name(config.scene);
  s["self_contact"] = config.scene.self_contact;
  s["broad_phase"] = config.scene.self_contact ? nlohmann::json(sim::broad_phase_name(config.scene)) : nlohmann::json();
  s["compression_ratio"] = config.scene.compression_ratio;
  // The pair Hessian the run's steps assembled (auto resolved by the solver: the exact projection
  // with robot mode's fingers); null without self-contact.
  const std::string hessians = run.contact_hessians();
  s["contact_hessian"] = hessians.empty() ? nlohmann::json() : nlohmann::json(hessians);
  s["contacts_max"] = run.contacts_max();
  s["intersecting_pairs_max"] = run.intersecting_max();
  s["untangle_runs"] = sc.untangle_runs();
  s["flood_halvings"] = sc.flood_halvings();
  s["failed"] = sc.failed();
  s["failure"] = sc.failure();
  s["backend"] = sc.backend();
  s["threads"] = omp_threads();  // OpenMP threads of the run's host loops (SceneOptions::threads, else every core)
  s["deterministic"] = config.scene.deterministic;
  s["initial"] = {{"min_z", ini.min_z}, {"max_z", ini.max_z}, {"extent_x", ini.extent_x}, {"extent_y", ini.extent_y}};
  s["final"] = {{"min_z", fin.min_z}, {"max_z", fin.max_z}, {"mean_z", fin.mean_z}, {"p95_z", fin.p95_z},
                {"extent_x", fin.extent_x}, {"extent_y", fin.extent_y}};
  s["garment_length"] = garment.length;
  s["garment_width"] = garment.width;
  // How far apart the trajectory leaves the grippers (a fling spreads the garment between them).
  if (!traj.left.empty() && !traj.right.empty()) {
    const double t_end = traj.end_time();
    s["gripper_separation_final"] = (traj.left.sample(t_end).position - traj.right.sample(t_end).position).norm();
  }
  s["settled_before_planning"] = settled ? config.task_params.start_delay : 0.0;  // s (generated tasks)
  nlohmann::json ev = nlohmann::json::array();
  for (const tasks::GripperEvent& e : run.controller().events())
    ev.push_back({{"t", e.t}, {"arm", tasks::arm_name(e.arm)}, {"grasp", e.grasp}, {"vertices", e.vertices.size()}});
  s["grasp_events"] = ev;
  if (robot) {
    nlohmann::json arms = nlohmann::json::object();
    const std::vector<tasks::GripperEvent>& events = run.controller().events();
    for (tasks::Arm a : {tasks::Arm::kLeft, tasks::Arm::kRight}) {
      const tasks::RobotArmState& st = robot->state(a);
      // A hand the trajectory closed that never got hold is the run's news, not only a null. Its
      // latest grasp is named: an earlier one may be a pre-shape the fingers rested from.
      const auto grasp = std::find_if(events.rbegin(), events.rend(),
                                      [&](const tasks::GripperEvent& e) { return e.arm == a && e.grasp; });
      if (grasp != events.rend() && st.held_at < 0)
        gd::log().warn("robot mode: the {} hand, closed at {:.3f} s, never got hold of the cloth (summary.json: "
                       "robot.arms.{}.held_at is null)",
                       tasks::arm_name(a), grasp->t, tasks::arm_name(a));
      arms[tasks::arm_name(a)] = {{"gripper_final", st.gripper}, {"squeeze_final_n", st.squeeze},
                                   {"table_lift_final", st.table_lift}, {"grip_force_final_n", st.grip_force},
                                   // when the hand first held the cloth and when it let go (null: never), and
                                   // its squeeze limit then
                                   {"held_at", st.held_at >= 0 ? nlohmann::json(st.held_at) : nlohmann::json()},
                                   {"lost_at", st.lost_at >= 0 ? nlohmann::json(st.lost_at) : nlohmann::json()},
                                   {"grip_force_at_loss_n", st.lost_at >= 0 ? nlohmann::json(st.force_at_loss)
                                                                            : nlohmann::json()},
                                   // when its first grasp stopped closing on little cloth or none, short of
                                   // a hold; and what the hand does with the cloth at the end
                                   {"missed_at", st.missed_at >= 0 ? nlohmann::json(st.missed_at) : nlohmann::json()},
                                   {"grip_final", tasks::grip_name(st.grip)},
                                   // where its pads cut through the cloth: at the end, at most, how
                                   // deep at most, since when and since when threaded (null: never)
                                   {"pad_cuts_final", st.pad_cuts},
                                   {"pad_cuts_max", st.pad_cuts_max},
                                   {"pad_cut_depth_max_mm", 1e3 * st.pad_cut_depth_max},
                                   {"pad_cuts_from", st.pad_cuts_from >= 0 ? nlohmann::json(st.pad_cuts_from)
                                                                           : nlohmann::json()},
                                   {"pad_threaded_from", st.pad_threaded_from >= 0
                                                             ? nlohmann::json(st.pad_threaded_from)
                                                             : nlohmann::json()}};
      if (st.pad_threaded_from >= 0)
        gd::log().warn("robot mode: the {} hand's pads stand through the cloth from {:.3f} s (up to {} cloth edges "
                       "through a pad or triangles a pad's edge passes through, {:.1f} mm deep): cloth threaded on "
                       "a pad goes where it goes (docs/robot.md, \"Pads that cut through the cloth\" and \"Surface "
                       "samples\"; timeseries.csv {}_pad_cuts; with --no-pad-samples the contact keeps only the "
                       "cloth's vertices out of the pads)",
                       tasks::arm_name(a), st.pad_threaded_from, st.pad_cuts_max, 1e3 * st.pad_cut_depth_max,
                       tasks::arm_name(a));
    }
    s["robot"] = {{"urdf", config.robot.urdf},
                  {"ik_samples", robot->ik_solved()},
                  {"ik_max_tilt_deg", robot->ik_max_tilt() * 180 / 3.14159265358979323846},
                  {"lift_max_tilt_deg", config.robot.lift_max_tilt * 180 / 3.14159265358979323846},
                  {"hands_half_turned", {robot->hand_half_turned(tasks::Arm::kLeft), robot->hand_half_turned(tasks::Arm::kRight)}},
                  {"joints_clamped", robot->joints_clamped()},
                  {"joint_clamp_max", robot->joint_clamp_max()},
                  {"link_colliders", robot->state(tasks::Arm::kLeft).link_colliders.size() +
                                         robot->state(tasks::Arm::kRight).link_colliders.size()},
                  {"link_meshes_not_found", robot->arm_model().skipped_meshes()},
                  {"rigid_hands", config.robot.rigid_hands},
                  {"pad_stiffness", config.robot.pad_stiffness},  // N/m; 0: pads stopped by the predictor
                  {"pad_samples", config.robot.pad_samples},      // the cloth's surface samples kept out of the pads
                  // m: the median edge of the cloth within 3 cm of a generated task's grasp points (null: a
                  // given trajectory, whose grasp points are not known beforehand)
                  {"grasp_edge_m", grasp_edge ? nlohmann::json(*grasp_edge) : nlohmann::json()},
                  // the pads' Coulomb coefficient on the cloth: the option's, else the material's
                  {"finger_friction", config.robot.finger_friction >= 0 ? config.robot.finger_friction
                                                                        : double(sc.material().friction)},
                  {"arms", arms}};
    if (placement)  // the garment moved to where the arms follow the task best (absent: placed as given)
      s["robot"]["placement"] = {{"given_position_m", {config.garment_position.x(), config.garment_position.y(),
                                                       config.garment_position.z()}},
                                 {"shift_m", placement->shift},
                                 {"tilt_deg", placement->reach.tilt * 180 / 3.14159265358979323846},
                                 {"height_m", placement->reach.height},
                                 {"placements_tried", placement->candidates},
                                 {"placements_within_reach", placement->reachable},
                                 {"trials", placement->trials}};
    if (reach)  // a generated task's default lift, fling height, page turn or fold margin fitted to the arms' reach (absent: none)
      s["robot"]["height_fitted"] = {{"task_param", reach->param},
                                     {"wanted_m", reach->reach.wanted},
                                     {"height_m", reach->reach.height},
                                     {"tilt_deg", reach->reach.tilt * 180 / 3.14159265358979323846},
                                     {"tilt_bound_deg", reach->reach.bound * 180 / 3.14159265358979323846},
                                     {"lowered", reach->lowered}};
  }
  {
    std::ofstream f(out + "/summary.json");
    if (!f) throw InputError(fmt::format("cannot write '{}/summary.json'", out));
    f << s.dump(2) << "\n";
  }
  if (capture && config.plots) plot_report(out);
  if (config.plots) {
    run_plot_script("plot_animation.py", out);  // OUT/animation.gif (.mp4; capture_animation.* too)
    run_plot_script("report_html.py", out);     // OUT/report.html: the report as one page
  }
  if (sc.failed()) gd::log().error("experiment: the simulation failed: {}", sc.failure());
  gd::log().info("experiment: {} steps in {:.1f} s ({:.0f} ms/step; {:.1f} s in all with set-up), max intersecting "
                 "pairs {}, untangling {} times",
                 run.steps(), run.stepping_seconds(), s["ms_per_step"].get<double>(), wall, run.intersecting_max(),
                 sc.untangle_runs());
  return result;
}

}  // namespace gd::experiment
