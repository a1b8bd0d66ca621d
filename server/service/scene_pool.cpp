#include "service/scene_pool.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <thread>

#include "experiment/experiment.h"
#include "garments/generator.h"
#include "garments/mesher.h"
#include "service/auth.h"
#include "sim/backend/cpu/omp_threads.h"
#include "sim/demand.h"
#include "sim/log.h"
#include "sim/material.h"
#include "sim/scene.h"
#include "robot/arm_model.h"
#include "tasks/grippers.h"
#include "tasks/robot_arms.h"
#include "tasks/trajectory.h"

namespace gd::service {

using sim::InputError;

// --- FrameSubscription ------------------------------------------------------------------------

bool FrameSubscription::pop(SceneSnapshot* out, int timeout_ms) {
  std::unique_lock<std::mutex> lock(mu_);
  cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms), [this] { return !frames_.empty() || open_scenes_ == 0; });
  if (frames_.empty()) return false;
  *out = std::move(frames_.front());
  frames_.pop_front();
  queued_bytes_ -= frame_bytes(*out);
  return true;
}

size_t FrameSubscription::frame_bytes(const SceneSnapshot& s) {
  return sizeof(SceneSnapshot) + s.scene_id.size() + s.failure.size() +
         (s.positions.size() + s.velocities.size()) * sizeof(Vec3);
}

int64_t FrameSubscription::dropped() {
  std::lock_guard<std::mutex> lock(mu_);
  return dropped_;
}

bool FrameSubscription::finished() {
  std::lock_guard<std::mutex> lock(mu_);
  return open_scenes_ == 0 && frames_.empty();
}

void FrameSubscription::push(SceneSnapshot s) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    const size_t bytes = frame_bytes(s);
    while (!frames_.empty() && queued_bytes_ + bytes > max_bytes_) {  // the oldest frames go first
      queued_bytes_ -= frame_bytes(frames_.front());
      frames_.pop_front();
      ++dropped_;
    }
    queued_bytes_ += bytes;
    frames_.push_back(std::move(s));
  }
  notify();
}

void FrameSubscription::scene_closed() {
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (open_scenes_ > 0) --open_scenes_;
  }
  notify();
}

void FrameSubscription::set_listener(std::function<void()> f) {
  std::lock_guard<std::mutex> lock(listener_mu_);
  listener_ = std::move(f);
}

void FrameSubscription::notify() {
  cv_.notify_all();
  std::function<void()> f;
  {
    std::lock_guard<std::mutex> lock(listener_mu_);
    f = listener_;
  }
  if (f) f();
}

// --- scenes -------------------------------------------------------------------------------------

Eigen::Isometry3d home_pose(tasks::Arm arm) {
  return tasks::make_pose(tasks::base_offset(arm) + Vec3(0, 0, 0.3), tasks::top_down_orientation());
}

Eigen::Isometry3d robot_home_pose(tasks::Arm arm) {
  return tasks::make_pose(tasks::base_offset(arm) + Vec3(0.25, 0, 0.25), tasks::top_down_orientation());
}

namespace {

/// What the scenes of one create() share: the placed garment, material and options.
struct Template {
  sim::Mesh mesh;                  ///< placed at default_garment_pose(), seed 0
  sim::Material material;
  sim::SceneOptions options;
  tasks::GripperOptions grippers;
  std::string mode;
  tasks::RobotOptions robot;                      ///< mode robot
  std::shared_ptr<const robot::ArmModel> arms;    ///< mode robot: the URDF's arms
  std::array<std::vector<double>, 2> initial_joints;  ///< mode robot (empty: inverse kinematics)
  double yaw_deg = 0, offset_m = 0;
  SceneInfo info;
};

/// Uniform in [-1, 1] from the generator's next 53 bits (the same on every standard library).
double symmetric_unit(std::mt19937_64& rng) { return 2.0 * double(rng() >> 11) * 0x1.0p-53 - 1.0; }

/// The placed mesh rigidly moved by a seed's yaw (about z through the centroid) and x/y offset.
sim::Mesh randomized_mesh(const Template& t, uint64_t seed) {
  sim::Mesh m = t.mesh;
  if (seed == 0 || (t.yaw_deg == 0 && t.offset_m == 0)) return m;
  std::mt19937_64 rng(seed);
  const double yaw = symmetric_unit(rng) * t.yaw_deg * M_PI / 180.0;
  const double dx = symmetric_unit(rng) * t.offset_m, dy = symmetric_unit(rng) * t.offset_m;
  Vec3 c = Vec3::Zero();
  for (const Vec3& p : m.x) c += p;
  c /= double(m.x.size());
  c.z() = 0;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(yaw, Vec3::UnitZ()).toRotationMatrix();
  for (Vec3& p : m.x) p = c + R * (p - c) + Vec3(dx, dy, 0);
  return m;
}

/// Both arms parked at home_pose() (robot: robot_home_pose(), or the given joints) with the
/// gripper open at t = 0.
tasks::DualArmTrajectory home_trajectory(bool robot, const std::array<std::vector<double>, 2>& joints = {}) {
  tasks::DualArmTrajectory traj;
  for (tasks::Arm a : {tasks::Arm::kLeft, tasks::Arm::kRight}) {
    const Eigen::Isometry3d h = robot ? robot_home_pose(a) : home_pose(a);
    tasks::ArmSample s;
    s.t = 0;
    s.joints = joints[static_cast<int>(a)];
    s.position = h.translation();
    s.orientation = Eigen::Quaterniond(h.linear());
    s.gripper = tasks::kGripperOpen;
    traj.arm(a) = tasks::ArmTrajectory({s}, fmt::format("{} arm home pose", tasks::arm_name(a)));
  }
  return traj;
}

const sim::MaterialLibrary& materials() {
  static const sim::MaterialLibrary lib = sim::MaterialLibrary::load_default();
  return lib;
}

bool finite(const Vec3& v) { return v.allFinite(); }

}  // namespace

namespace {

/// Steady-clock time, ns (scene leases).
int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

SceneSnapshot snapshot_of(const sim::Scene& scene, const tasks::TaskController& controller, bool positions,
                          bool velocities) {
  SceneSnapshot s;
  s.failed = scene.failed();
  s.failure = scene.failure();
  s.time = scene.time();
  if (positions) s.positions = scene.positions();
  if (velocities) s.velocities = scene.velocities();
  const auto* robot = dynamic_cast<const tasks::RobotController*>(&controller);
  const auto* grippers = dynamic_cast<const tasks::GripperController*>(&controller);
  GD_DEMAND(robot || grippers, "a scene's controller is a GripperController or a RobotController");
  for (int a = 0; a < 2; ++a) {
    const auto arm = static_cast<tasks::Arm>(a);
    if (robot) {
      const tasks::RobotArmState& st = robot->state(arm);
      s.arms[a].closed = st.grip != tasks::Grip::kOpen;  // the command asks for a grip (RobotController::grip_asked)
      s.arms[a].joints = st.joints;
      s.arms[a].gripper = st.gripper;
      s.arms[a].squeeze = st.squeeze;
      s.arms[a].grip = st.grip;
      s.arms[a].pad_cuts = st.pad_cuts;
      s.arms[a].pad_cut_depth = st.pad_cut_depth;
      s.arms[a].pose = robot->ee_world(arm);
      s.arms[a].links = robot->chain_world(arm);
    } else {
      const tasks::ArmState& st = grippers->state(arm);
      s.arms[a].closed = st.closed;
      s.arms[a].held_vertices = static_cast<int>(st.held.size());
      const tasks::ArmSample ee = grippers->ee(arm, scene.time());
      s.arms[a].pose = tasks::make_pose(ee.position, ee.orientation);
    }
  }
  if (robot) {
    const Vec3 half = robot->options().arm.pad.half_extents;
    for (const Eigen::Isometry3d& p : robot->pad_poses(scene.time())) {
      ColliderSnapshot c;
      c.pose = p;
      c.half_extents = half;
      s.colliders.push_back(c);
    }
  }
  return s;
}

SceneInfo info_of(const sim::Scene& scene, const tasks::TaskController& controller, const std::string& mode) {
  SceneInfo info;
  info.vertex_count = static_cast<int>(scene.vertex_count());
  info.triangles = scene.mesh().tris;
  info.rest_positions = scene.positions();
  info.dt = scene.options().dt;
  info.backend = scene.backend();
  info.mode = mode;
  if (scene.options().table) info.table_height = scene.options().table_height;
  if (const auto* rc = dynamic_cast<const tasks::RobotController*>(&controller)) {
    const robot::ArmModel& arms = rc->arm_model();
    info.joint_names = arms.arm_joint_names();
    for (const robot::JointLimits& l : arms.arm_limits()) {
      info.joint_lower.push_back(l.lower);
      info.joint_upper.push_back(l.upper);
    }
    info.gripper_max = arms.gripper_max();
  }
  return info;
}

struct ScenePool::Entry {
  std::mutex mu;
  std::atomic<int64_t> last_used_ns{steady_ns()};  ///< when a call last named it (lease)
  std::string id;
  std::string owner;  ///< the creating caller's principal
  std::shared_ptr<const Template> tmpl;
  uint64_t seed = 0;
  std::unique_ptr<sim::Scene> scene;
  std::unique_ptr<tasks::TaskController> controller;
  tasks::GripperController* grippers = nullptr;  ///< the controller in pseudo / fixed point mode
  tasks::RobotController* robot = nullptr;       ///< the controller in robot mode
  int64_t steps = 0;
  std::vector<int> target_groups;
  std::string error;        ///< an unexpected error while stepping (the scene counts as failed)
  bool destroyed = false;
  int newton = 0, pcg = 0, contacts = 0, intersecting = 0;
  double wall_ms = 0;
  std::vector<std::weak_ptr<FrameSubscription>> subscribers;

  /// (Re)builds the scene and controller at the seed's initial pose. Throws InputError.
  void build(uint64_t s) {
    seed = s;
    scene = sim::Scene::create(randomized_mesh(*tmpl, s), tmpl->material, tmpl->options);
    if (tmpl->arms) {
      auto r = std::make_unique<tasks::RobotController>(home_trajectory(true, tmpl->initial_joints), tmpl->robot,
                                                        tmpl->arms);
      robot = r.get();
      grippers = nullptr;
      controller = std::move(r);
    } else {
      auto g = std::make_unique<tasks::GripperController>(home_trajectory(false), tmpl->grippers);
      grippers = g.get();
      robot = nullptr;
      controller = std::move(g);
    }
    steps = 0;
    target_groups.clear();
    error.clear();
    newton = pcg = contacts = intersecting = 0;
    wall_ms = 0;
  }
  bool failed() const { return scene->failed() || !error.empty(); }

  SceneSnapshot snapshot(bool positions, bool velocities) const {
    SceneSnapshot s = snapshot_of(*scene, *controller, positions, velocities);
    s.scene_id = id;
    s.failed = failed();
    if (!error.empty()) s.failure = error;
    s.steps = steps;
    s.newton_iterations = newton;
    s.pcg_iterations = pcg;
    s.active_contacts = contacts;
    s.intersecting_pairs = intersecting;
    s.wall_ms = wall_ms;
    return s;
  }

  /// Queues a frame for the subscribers whose period divides the step count.
  void publish() {
    if (subscribers.empty()) return;
    std::optional<SceneSnapshot> snap;
    for (auto it = subscribers.begin(); it != subscribers.end();) {
      std::shared_ptr<FrameSubscription> sub = it->lock();
      if (!sub) {
        it = subscribers.erase(it);
        continue;
      }
      if (steps % sub->every() == 0) {
        if (!snap) snap = snapshot(true, false);
        sub->push(*snap);
      }
      ++it;
    }
  }

  void close_subscribers() {
    for (auto& w : subscribers)
      if (auto sub = w.lock()) sub->scene_closed();
    subscribers.clear();
  }
};

ScenePool::ScenePool(PoolOptions options)
    : options_([&] {
        if (options.threads <= 0) options.threads = std::max(1u, std::thread::hardware_concurrency());
        if (options.max_scenes < 0 || options.max_vertices < 0 || options.max_substeps < 0)
          throw InputError("scene pool limits must be >= 0");
        return options;
      }()),
      robot_model_(options_.robot_urdf.empty() ? nullptr : [&] {
        robot::ArmModelOptions arm;
        arm.package_paths = options_.robot_package_paths;
        return std::make_shared<const robot::ArmModel>(robot::ArmModel::load(options_.robot_urdf, arm));
      }()),
      pool_(options_.threads) {
  if (!robot_model_) return;
  gd::log().info("robot mode's default arms: {} ({} joints) from {}; {} collision shapes", robot_model_->name(),
                 robot_model_->arm_dofs(), options_.robot_urdf, robot_model_->link_shapes().size());
  for (const std::string& uri : robot_model_->skipped_meshes())
    gd::log().warn("robot mode: link mesh {} not found (--robot-urdf-package-path); its link has no collider", uri);
}

ScenePool::~ScenePool() {
  std::lock_guard<std::mutex> lock(mu_);
  for (auto& [id, e] : scenes_) {
    std::lock_guard<std::mutex> l(e->mu);
    e->close_subscribers();
  }
}

int ScenePool::size() const {
  std::lock_guard<std::mutex> lock(mu_);
  return static_cast<int>(scenes_.size());
}

Status ScenePool::lookup(const std::vector<std::string>& ids, const std::string& owner,
                         std::vector<std::shared_ptr<Entry>>* out) const {
  if (ids.empty()) return Status::InvalidArgument("no scene ids given; pass the ids that CreateScenes returned");
  std::set<std::string> seen;
  out->clear();
  std::lock_guard<std::mutex> lock(mu_);
  for (const std::string& id : ids) {
    if (!seen.insert(id).second)
      return Status::InvalidArgument(fmt::format("scene '{}' is named twice; name each scene once per call", id));
    auto it = scenes_.find(id);
    if (it == scenes_.end() || it->second->owner != owner) {  // another owner's scene: as if unknown
      const auto gone = expired_.find(id);
      if (it == scenes_.end() && gone != expired_.end() && gone->second.owner == owner)
        return Status::NotFound(fmt::format(
            "scene '{}' was destroyed after {:.0f} s without a call (this server's scene lease is {:g} s, "
            "--scene-lease-s); create scenes again with CreateScenes", id, gone->second.idle_seconds,
            options_.scene_lease_seconds));
      return Status::NotFound(fmt::format("no scene '{}' on this server (destroyed, never created, or created "
                                          "before a restart); create scenes with CreateScenes", id));
    }
    it->second->last_used_ns = steady_ns();
    out->push_back(it->second);
  }
  return Status::Ok();
}

namespace {

/// Locks the entries in id order (a global order, so concurrent calls cannot deadlock).
std::vector<std::unique_lock<std::mutex>> lock_all(const std::vector<std::shared_ptr<ScenePool::Entry>>& entries) {
  std::vector<ScenePool::Entry*> order;
  for (const auto& e : entries) order.push_back(e.get());
  std::sort(order.begin(), order.end(), [](auto* a, auto* b) { return a->id < b->id; });
  std::vector<std::unique_lock<std::mutex>> locks;
  for (ScenePool::Entry* e : order) locks.emplace_back(e->mu);
  return locks;
}

Status check_alive(const std::vector<std::shared_ptr<ScenePool::Entry>>& entries) {
  for (const auto& e : entries)
    if (e->destroyed) return Status::NotFound(fmt::format("scene '{}' was destroyed", e->id));
  return Status::Ok();
}

}  // namespace

Status ScenePool::robot_arms(const RobotSpec& spec, std::shared_ptr<const robot::ArmModel>* arms,
                             tasks::RobotOptions* options) const {
  if (spec.lift_max_tilt_deg)
    return Status::InvalidArgument(
        "robot lift_max_tilt_deg is for jobs (it bounds a generated task's lift); a scene's arms follow the joint or "
        "pose commands they are sent");
  if (spec.place_within_reach)
    return Status::InvalidArgument(
        "robot place_within_reach is for jobs (it places the garment for a generated task); a scene's garment lies "
        "where it is created");
  GD_RETURN_IF_ERROR(apply_robot_spec(spec, robot_model_ != nullptr, options));
  if (spec.urdf_xml.empty()) {
    *arms = robot_model_;
    options->urdf = options_.robot_urdf;
    options->arm.package_paths = options_.robot_package_paths;
  } else {
    try {
      robot::ArmModelOptions arm;
      arm.read_meshes = false;  // a client's URDF: the server opens no file it names
      *arms = std::make_shared<const robot::ArmModel>(robot::ArmModel::from_string(spec.urdf_xml, "robot.urdf", arm));
    } catch (const InputError& e) {
      return Status::InvalidArgument(fmt::format("robot settings: {}", e.what()));
    }
    options->urdf = "robot.urdf (sent with the request)";
  }
  try {
    options->validate(false);
  } catch (const InputError& e) {
    return Status::InvalidArgument(e.what());
  }
  for (int a = 0; a < 2; ++a) {
    const std::vector<double>& q = spec.initial_joints[a];
    const char* arm = a == 0 ? "left" : "right";
    if (q.empty()) continue;
    if (static_cast<int>(q.size()) != (*arms)->arm_dofs())
      return Status::InvalidArgument(fmt::format("robot {}_initial_joints has {} values; the URDF's arm has {} ({})", arm,
                                                 q.size(), (*arms)->arm_dofs(), fmt::join((*arms)->arm_joint_names(), ", ")));
    for (size_t k = 0; k < q.size(); ++k)
      if (!std::isfinite(q[k]))
        return Status::InvalidArgument(fmt::format("robot {}_initial_joints: {} is not finite", arm, (*arms)->arm_joint_names()[k]));
  }
  return Status::Ok();
}

Status ScenePool::create(const SceneSpec& spec, CreatedScenes* out) {
  // Cheap checks first: nothing is built for a bad request.
  const int count = spec.count == 0 ? 1 : spec.count;
  if (count < 0) return Status::InvalidArgument(fmt::format("count must be >= 1 (got {})", spec.count));
  const int vertices = spec.vertices == 0 ? 2000 : spec.vertices;
  if (vertices < 0) return Status::InvalidArgument(fmt::format("vertices must be > 0 (got {})", spec.vertices));
  if (vertices > options_.max_vertices)
    return Status::ResourceExhausted(fmt::format("vertices {} is over this server's limit of {} per scene "
                                                 "(ask for fewer, or start the server with a larger --max-vertices)",
                                                 vertices, options_.max_vertices));
  const std::string mode = spec.mode.empty() ? "pseudo" : spec.mode;
  if (mode != "pseudo" && mode != "fixed_point" && mode != "robot")
    return Status::InvalidArgument(fmt::format("unknown mode '{}'; use pseudo, fixed_point or robot", mode));
  std::shared_ptr<const robot::ArmModel> arms;
  tasks::RobotOptions robot_options;
  if (mode == "robot") {
    GD_RETURN_IF_ERROR(robot_arms(spec.robot, &arms, &robot_options));
  } else if (!spec.robot.empty()) {
    return Status::InvalidArgument(fmt::format("robot settings are for mode robot (this request's mode is {})", mode));
  }
  if (spec.mesh_path.empty()) {
    if (spec.garment.empty())
      return Status::InvalidArgument("no garment given: set garment (a type from ListGarments) or mesh_id (from UploadMesh)");
    const auto types = garments::garment_types();
    if (std::find(types.begin(), types.end(), spec.garment) == types.end())
      return Status::InvalidArgument(fmt::format("unknown garment '{}'; use one of: {}", spec.garment,
                                                 fmt::join(types, ", ")));
  }
  if (!spec.mesh_path.empty() && !spec.garment_params.empty())
    return Status::InvalidArgument("garment_params size a generated garment; an uploaded mesh (mesh_id) takes none");
  const std::string material = spec.material.empty() ? "cotton" : spec.material;
  auto bad_number = [](const std::optional<double>& v) { return v && !std::isfinite(*v); };
  if (bad_number(spec.dt) || (spec.dt && *spec.dt <= 0))
    return Status::InvalidArgument(fmt::format("settings.dt must be a finite number > 0 s (got {})", *spec.dt));
  if (spec.dt && *spec.dt > 0.1)
    return Status::InvalidArgument(fmt::format("settings.dt {} s is too large; use at most 0.1 s", *spec.dt));
  if (spec.dt && *spec.dt < sim::kMinDt)
    return Status::InvalidArgument(
        fmt::format("settings.dt {} s is too small; use at least {} s", *spec.dt, sim::kMinDt));
  if (bad_number(spec.jaw_radius) || (spec.jaw_radius && *spec.jaw_radius < 0))
    return Status::InvalidArgument("settings.jaw_radius must be a finite number >= 0 m");
  if (spec.jaw_radius && *spec.jaw_radius > tasks::kMaxJawRadius)
    return Status::InvalidArgument(fmt::format("settings.jaw_radius {} m is too large; use at most {} m",
                                               *spec.jaw_radius, tasks::kMaxJawRadius));
  if (bad_number(spec.grab_time) || (spec.grab_time && *spec.grab_time < 0))
    return Status::InvalidArgument("settings.grab_time must be a finite number >= 0 s");
  if (!std::isfinite(spec.yaw_deg) || spec.yaw_deg < 0 || spec.yaw_deg > 180)
    return Status::InvalidArgument(fmt::format("randomization.yaw_deg must be in [0, 180] (got {})", spec.yaw_deg));
  if (!std::isfinite(spec.offset_m) || spec.offset_m < 0 || spec.offset_m > 1)
    return Status::InvalidArgument(fmt::format("randomization.offset_m must be in [0, 1] m (got {})", spec.offset_m));

  // Reserve the slots, so concurrent creates cannot overshoot the limit together.
  {
    std::lock_guard<std::mutex> lock(mu_);
    const int have = static_cast<int>(scenes_.size()) + reserved_;
    if (count > options_.max_scenes - have)
      return Status::ResourceExhausted(fmt::format(
          "{} more scenes would exceed this server's limit of {} (alive or being created: {}); destroy scenes or "
          "start the server with a larger --max-scenes",
          count, options_.max_scenes, have));
    reserved_ += count;
  }
  struct Release {
    ScenePool* p;
    int n;
    ~Release() {
      std::lock_guard<std::mutex> lock(p->mu_);
      p->reserved_ -= n;
    }
  } release{this, count};

  try {
    auto t = std::make_shared<Template>();
    experiment::ExperimentConfig cfg;
    cfg.garment = spec.mesh_path.empty() ? spec.garment : spec.mesh_path;
    cfg.vertices = vertices;
    cfg.garment_params = spec.garment_params;
    const garments::MeshingCancellation meshing(spec.cancelled);  // a caller gone mid-meshing stops it
    const garments::Garment garment = experiment::make_experiment_garment(cfg);
    if (static_cast<int>(garment.mesh.x.size()) > options_.max_vertices)
      return Status::ResourceExhausted(fmt::format("the garment has {} vertices, over this server's limit of {} per "
                                                   "scene (start the server with a larger --max-vertices)",
                                                   garment.mesh.x.size(), options_.max_vertices));
    t->mesh = garment.mesh;
    const Eigen::Isometry3d place = tasks::default_garment_pose();
    for (Vec3& p : t->mesh.x) p = place * p;
    t->material = spec.material_params.empty() ? materials().get(material)
                                                : sim::with_catalogue_params(materials().get(material), spec.material_params);
    t->options = experiment::ExperimentConfig::default_scene_options();
    if (spec.dt) t->options.dt = *spec.dt;
    else t->options.dt = 0.01;
    if (spec.self_contact) t->options.self_contact = *spec.self_contact;
    t->options.backend = options_.backend;
    t->options.deterministic = options_.deterministic;
    if (mode == "robot") {
      t->options.pad_stiffness = robot_options.pad_stiffness;  // the hands' lag spring
      t->options.pad_samples = robot_options.pad_samples;      // the cloth's surface samples held out of the pads
    }
    t->options.validate();
    t->grippers.mode = mode == "fixed_point" ? tasks::GraspMode::kFixedPoint : tasks::GraspMode::kPseudoGrasp;
    t->grippers.action = tasks::TaskKind::kGrasp;
    if (spec.jaw_radius) t->grippers.jaw_radius = *spec.jaw_radius;
    if (spec.grab_time) t->grippers.grab_time = *spec.grab_time;
    t->grippers.validate();
    t->mode = mode;
    t->arms = arms;
    t->robot = robot_options;
    t->initial_joints = spec.robot.initial_joints;
    t->yaw_deg = spec.yaw_deg;
    t->offset_m = spec.offset_m;
    t->info.vertex_count = static_cast<int>(t->mesh.x.size());
    t->info.triangles = t->mesh.tris;
    t->info.rest_positions = t->mesh.x;
    t->info.dt = t->options.dt;
    t->info.mode = mode;
    t->info.left_shoulder_vertex = garment.landmarks.left_shoulder_vertex;
    t->info.right_shoulder_vertex = garment.landmarks.right_shoulder_vertex;
    if (t->options.table) t->info.table_height = t->options.table_height;
    if (arms) {
      t->info.joint_names = arms->arm_joint_names();
      for (const robot::JointLimits& l : arms->arm_limits()) {
        t->info.joint_lower.push_back(l.lower);
        t->info.joint_upper.push_back(l.upper);
      }
      t->info.gripper_max = arms->gripper_max();
    }

    std::vector<std::shared_ptr<Entry>> made(count);
    std::vector<std::string> errors(count);
    pool_.run(count, [&](int i) {
      try {
        set_omp_threads(std::max(1, threads() / count));
        auto e = std::make_shared<Entry>();
        e->tmpl = t;
        e->build(spec.seed);
        made[i] = std::move(e);
      } catch (const std::exception& ex) {
        errors[i] = ex.what();
      }
    });
    for (const std::string& err : errors)
      if (!err.empty()) return Status::InvalidArgument(err);
    t->info.backend = made[0]->scene->backend();

    out->ids.clear();
    out->states.clear();
    {
      std::lock_guard<std::mutex> lock(mu_);
      for (auto& e : made) {
        do e->id = "s-" + random_hex(16);
        while (scenes_.count(e->id));
        e->owner = spec.owner;
        scenes_[e->id] = e;
        out->ids.push_back(e->id);
      }
    }
    for (auto& e : made) {
      std::lock_guard<std::mutex> l(e->mu);
      out->states.push_back(e->snapshot(true, false));
    }
    out->info = t->info;
    return Status::Ok();
  } catch (const garments::MeshingCancelled&) {
    return Status(Code::kCancelled, "the call was cancelled or passed its deadline while its garment was meshed; "
                                    "no scene was created");
  } catch (const InputError& e) {
    return Status::InvalidArgument(e.what());
  } catch (const std::exception& e) {
    return Status::Internal(fmt::format("creating scenes failed: {}", e.what()));
  }
}

Status ScenePool::reset(const std::vector<std::string>& ids, const std::vector<uint64_t>& seeds,
                        std::vector<SceneSnapshot>* out, const std::string& owner) {
  if (!seeds.empty() && seeds.size() != 1 && seeds.size() != ids.size())
    return Status::InvalidArgument(fmt::format("give no seed, one seed, or one per scene ({}); got {}", ids.size(),
                                               seeds.size()));
  std::vector<std::shared_ptr<Entry>> entries;
  GD_RETURN_IF_ERROR(lookup(ids, owner, &entries));
  auto locks = lock_all(entries);
  GD_RETURN_IF_ERROR(check_alive(entries));
  std::vector<std::string> errors(entries.size());
  pool_.run(static_cast<int>(entries.size()), [&](int i) {
    Entry& e = *entries[i];
    const uint64_t seed = seeds.empty() ? e.seed : seeds.size() == 1 ? seeds[0] : seeds[i];
    try {
      e.build(seed);
    } catch (const std::exception& ex) {
      errors[i] = ex.what();
    }
  });
  out->clear();
  for (size_t i = 0; i < entries.size(); ++i) {
    if (!errors[i].empty()) return Status::Internal(fmt::format("reset of '{}' failed: {}", entries[i]->id, errors[i]));
    out->push_back(entries[i]->snapshot(true, false));
  }
  return Status::Ok();
}

namespace {

/// Checks one action against its scene's vertex count; normalises nothing.
Status check_action(const SceneAction& a, int vertex_count) {
  bool untimed[2] = {false, false};  // an untimed command (the call's end) was given: it must be the last
  for (const ArmCommand& c : a.arms) {
    const int i = static_cast<int>(c.arm);
    if (i < 0 || i > 1)
      return Status::InvalidArgument(fmt::format("scene '{}': arm must be ARM_LEFT or ARM_RIGHT", a.scene_id));
    if (untimed[i])
      return Status::InvalidArgument(fmt::format(
          "scene '{}': the {} arm has a command after its untimed one; give every earlier sample a time, "
          "or one command per arm", a.scene_id, tasks::arm_name(c.arm)));
    if (!c.time) untimed[i] = true;
    if (c.time && !std::isfinite(*c.time))  // their order is checked against the scene's trajectory in step()
      return Status::InvalidArgument(fmt::format("scene '{}': the {} arm's sample time is not finite", a.scene_id,
                                                 tasks::arm_name(c.arm)));
    if (!finite(c.position))
      return Status::InvalidArgument(fmt::format("scene '{}': the {} arm's position is not finite", a.scene_id,
                                                 tasks::arm_name(c.arm)));
    const Eigen::Vector4d q = c.orientation.coeffs();
    if (!q.allFinite() || q.norm() < 1e-6)
      return Status::InvalidArgument(fmt::format(
          "scene '{}': the {} arm's orientation must be a finite non-zero quaternion (unset: identity)", a.scene_id,
          tasks::arm_name(c.arm)));
    for (double q : c.joints)
      if (!std::isfinite(q))
        return Status::InvalidArgument(fmt::format("scene '{}': the {} arm's joints must be finite", a.scene_id,
                                                   tasks::arm_name(c.arm)));
    if (c.joints.size() > 64)
      return Status::InvalidArgument(fmt::format("scene '{}': the {} arm's command gives {} joints; an arm has a few",
                                                 a.scene_id, tasks::arm_name(c.arm), c.joints.size()));
    if (!std::isfinite(c.gripper) || c.gripper < 0 || c.gripper > 1)
      return Status::InvalidArgument(fmt::format("scene '{}': the {} arm's gripper opening must be in [0, 1] m "
                                                 "(0 = closed, 0.035 = open); got {}",
                                                 a.scene_id, tasks::arm_name(c.arm), c.gripper));
  }
  if (a.target_indices.size() != a.target_positions.size())
    return Status::InvalidArgument(fmt::format("scene '{}': {} target indices but {} target positions", a.scene_id,
                                               a.target_indices.size(), a.target_positions.size()));
  std::set<int> seen;
  for (size_t k = 0; k < a.target_indices.size(); ++k) {
    const int v = a.target_indices[k];
    if (v < 0 || v >= vertex_count)
      return Status::InvalidArgument(
          fmt::format("scene '{}': target vertex {} is out of range [0, {})", a.scene_id, v, vertex_count));
    if (!seen.insert(v).second)
      return Status::InvalidArgument(fmt::format("scene '{}': target vertex {} is named twice", a.scene_id, v));
    if (!finite(a.target_positions[k]))
      return Status::InvalidArgument(
          fmt::format("scene '{}': the target position of vertex {} is not finite", a.scene_id, v));
  }
  return Status::Ok();
}

}  // namespace

namespace {

/// An upper bound of one scene's share of a StepScenes / GetState reply, bytes: its id, stats,
/// arms and colliders, 12 bytes per vertex for each of positions and velocities included, and
/// its SceneInfo (rest positions and triangles) when asked for.
size_t snapshot_reply_bytes(const SceneInfo& info, bool positions, bool velocities, bool with_info) {
  const size_t array = 12 * static_cast<size_t>(info.vertex_count) + 32;  // float32 (N, 3), dtype, shape, tags
  const size_t info_bytes = with_info ? 1024 + array + 12 * info.triangles.size() + 32 : 0;
  return 1024 + (positions ? array : 0) + (velocities ? array : 0) + info_bytes;
}

/// Refuses a call whose reply would pass `limit` bytes (0: none), before any work: gRPC would
/// refuse to send it only after the scenes had stepped.
Status check_reply_size(const std::vector<std::shared_ptr<ScenePool::Entry>>& entries, bool positions,
                        bool velocities, size_t limit, bool with_info = false) {
  if (limit == 0) return Status::Ok();
  size_t bytes = 0, largest = 0;
  for (const auto& e : entries) {
    const size_t b = snapshot_reply_bytes(e->tmpl->info, positions, velocities, with_info);
    bytes += b;
    largest = std::max(largest, b);
  }
  if (bytes <= limit) return Status::Ok();
  return Status::ResourceExhausted(fmt::format(
      "the reply for {} scenes would take about {:.1f} MiB, over this server's {:.1f} MiB per message "
      "(--max-message-mb): ask for about {} scenes per call{}",
      entries.size(), bytes / 1048576.0, limit / 1048576.0, std::max<size_t>(1, limit / largest),
      velocities ? ", or leave the velocities out" : ""));
}

}  // namespace

Status ScenePool::step(const StepRequest& req, std::vector<SceneSnapshot>* out) {
  if (req.substeps < 0) return Status::InvalidArgument(fmt::format("substeps must be >= 1 (got {})", req.substeps));
  const int substeps = req.substeps == 0 ? 1 : req.substeps;
  if (substeps > options_.max_substeps)
    return Status::ResourceExhausted(fmt::format("substeps {} is over this server's limit of {} per call; "
                                                 "step in several calls",
                                                 substeps, options_.max_substeps));
  std::vector<std::string> ids = req.scene_ids;
  if (ids.empty())
    for (const SceneAction& a : req.actions) ids.push_back(a.scene_id);
  std::vector<std::shared_ptr<Entry>> entries;
  GD_RETURN_IF_ERROR(lookup(ids, req.owner, &entries));
  GD_RETURN_IF_ERROR(check_reply_size(entries, req.include_positions, req.include_velocities,
                                      options_.max_reply_bytes));
  std::map<std::string, size_t> index;
  for (size_t i = 0; i < ids.size(); ++i) index[ids[i]] = i;
  std::vector<const SceneAction*> actions(ids.size(), nullptr);
  for (const SceneAction& a : req.actions) {
    auto it = index.find(a.scene_id);
    if (it == index.end())
      return Status::InvalidArgument(
          fmt::format("an action names scene '{}', which is not among the scene_ids of this call", a.scene_id));
    if (actions[it->second])
      return Status::InvalidArgument(fmt::format("scene '{}' has two actions; give one per scene", a.scene_id));
    actions[it->second] = &a;
    GD_RETURN_IF_ERROR(check_action(a, entries[it->second]->tmpl->info.vertex_count));
  }

  auto locks = lock_all(entries);
  GD_RETURN_IF_ERROR(check_alive(entries));
  for (const auto& e : entries)
    if (e->failed())
      return Status::FailedPrecondition(fmt::format("scene '{}' has failed ({}); reset it (ResetScenes) or destroy it",
                                                    e->id, e->scene->failure().empty() ? e->error : e->scene->failure()));

  // Each arm's samples must follow its last one, and robot mode's poses must be within reach
  // (checked before anything changes: the samples are made here and appended below).
  std::vector<std::vector<std::pair<tasks::Arm, tasks::ArmSample>>> samples(entries.size());
  for (size_t i = 0; i < entries.size(); ++i) {
    const SceneAction* a = actions[i];
    if (!a) continue;
    Entry& e = *entries[i];
    const double t_end = e.scene->time() + substeps * e.scene->options().dt;
    const tasks::DualArmTrajectory& traj = e.robot ? e.robot->trajectory() : e.grippers->trajectory();
    double after[2];
    std::vector<double> joints[2];  // robot mode: each arm's latest joints (inverse kinematics' seed)
    for (int k = 0; k < 2; ++k) {
      const tasks::ArmTrajectory& arm = traj.arm(static_cast<tasks::Arm>(k));
      after[k] = arm.empty() ? -std::numeric_limits<double>::infinity() : arm.samples().back().t;
      if (!arm.empty()) joints[k] = arm.samples().back().joints;
    }
    for (const ArmCommand& c : a->arms) {
      double& prev = after[static_cast<int>(c.arm)];
      const double t = c.time ? *c.time : t_end;
      if (!(t > prev))
        return Status::InvalidArgument(fmt::format(
            "scene '{}': the {} arm's sample at t={} s is not after its previous sample (t={} s); send samples in "
            "increasing time, each after the last one sent{}", e.id, tasks::arm_name(c.arm), t, prev,
            c.time ? "" : " (an untimed command is at the end of this call's steps)"));
      prev = t;
      if (!c.joints.empty() && !e.robot)
        return Status::InvalidArgument(fmt::format(
            "scene '{}': the {} arm's command gives joints, which only robot-mode scenes take (this scene's mode is "
            "{}); give the end-effector pose", e.id, tasks::arm_name(c.arm), e.tmpl->mode));
      tasks::ArmSample s;
      s.t = t;
      s.position = c.position;
      s.orientation = c.orientation.normalized();
      s.gripper = c.gripper;
      s.joints = c.joints;
      if (e.robot) {
        try {
          s = e.robot->resolve(c.arm, s, joints[static_cast<int>(c.arm)]);
        } catch (const InputError& ex) {
          return Status::InvalidArgument(fmt::format("scene '{}': {}", e.id, ex.what()));
        }
        joints[static_cast<int>(c.arm)] = s.joints;
      }
      samples[i].emplace_back(c.arm, std::move(s));
    }
  }
  // Kinematic targets first (the only action the scene itself may still refuse); undone on error.
  std::vector<std::pair<Entry*, int>> added;
  for (size_t i = 0; i < entries.size(); ++i) {
    const SceneAction* a = actions[i];
    if (!a) continue;
    Entry& e = *entries[i];
    try {
      if (a->release_targets) {
        for (int g : e.target_groups) e.scene->release(g);
        e.target_groups.clear();
      }
      if (!a->target_indices.empty()) {
        const int g = e.scene->set_targets(a->target_indices, a->target_positions);
        e.target_groups.push_back(g);
        added.emplace_back(&e, g);
      }
    } catch (const InputError& ex) {
      for (auto& [en, g] : added) {
        en->scene->release(g);
        en->target_groups.erase(std::find(en->target_groups.begin(), en->target_groups.end(), g));
      }
      return Status::InvalidArgument(fmt::format("scene '{}': {}", e.id, ex.what()));
    }
  }
  // Arm commands: samples at their times, an untimed one at the end time of this call's steps
  // (validated above and before the targets).
  for (size_t i = 0; i < entries.size(); ++i) {
    Entry& e = *entries[i];
    for (const auto& [arm, s] : samples[i]) {
      try {
        if (e.robot) e.robot->append(arm, s);  // joints resolved above: no inverse kinematics again
        else e.grippers->append(arm, s);
      } catch (const InputError& ex) {
        return Status::InvalidArgument(fmt::format("scene '{}': {}", e.id, ex.what()));
      }
    }
  }

  const int n = static_cast<int>(entries.size());
  const int solver_threads = n >= threads() ? 1 : std::max(1, threads() / n);
  std::atomic<bool> stopped{false};
  std::atomic<int> done_substeps{0};
  // Each scene's substeps run in slices of about kSliceSeconds (at least one step): between
  // slices the scene goes to the back of the pool's queue, so a slow scene holds a worker one
  // slice at a time and the scenes of other calls get their turns (docs/service.md, "A slow
  // scene in a batch").
  std::vector<int> left(n, substeps);
  std::vector<double> seconds(n, 0.0);
  for (const auto& e : entries) e->newton = e->pcg = e->contacts = e->intersecting = 0;
  pool_.run_slices(n, [&](int i) {
    Entry& e = *entries[i];
    set_omp_threads(solver_threads);
    const auto t0 = std::chrono::steady_clock::now();
    auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(); };
    bool more = false;
    try {
      while (left[i] > 0) {
        if (stopped || (req.cancelled && req.cancelled())) {  // the caller is gone: stop at a step boundary
          stopped = true;
          break;
        }
        ++done_substeps;
        const double t_next = e.scene->time() + e.scene->options().dt;
        if (!tasks::run_until(*e.scene, *e.controller, t_next)) break;
        --left[i];
        ++e.steps;
        const sim::StepStats& st = e.scene->last_stats();
        e.newton += st.newton_iters;
        e.pcg += st.pcg_iters;
        e.contacts = st.contacts;
        e.intersecting = std::max(e.intersecting, st.intersecting_pairs);
        e.publish();
        if (left[i] > 0 && elapsed() >= kSliceSeconds) {  // the rest in a later slice
          more = true;
          break;
        }
      }
    } catch (const std::exception& ex) {
      e.error = fmt::format("step failed: {}", ex.what());
      more = false;
    }
    seconds[i] += elapsed();
    if (more) return true;
    e.wall_ms = 1e3 * seconds[i];
    if (e.failed()) {
      gd::log().warn("scene {} failed at step {}: {}", e.id, e.steps, e.error.empty() ? e.scene->failure() : e.error);
      e.publish();
    }
    return false;
  });
  if (stopped)
    return Status(Code::kCancelled,
                  fmt::format("the call was cancelled or passed its deadline; its scenes stopped at a step boundary "
                              "after {} of {} scene-steps (GetState reads where they are)",
                              done_substeps.load(), substeps * n));
  out->clear();
  for (const auto& e : entries) {
    e->last_used_ns = steady_ns();  // a long call counts as use until it ends
    out->push_back(e->snapshot(req.include_positions, req.include_velocities));
  }
  return Status::Ok();
}

Status ScenePool::state(const std::vector<std::string>& ids, bool include_velocities, std::vector<SceneSnapshot>* out,
                        const std::string& owner, std::vector<SceneInfo>* infos) {
  std::vector<std::shared_ptr<Entry>> entries;
  GD_RETURN_IF_ERROR(lookup(ids, owner, &entries));
  GD_RETURN_IF_ERROR(check_reply_size(entries, true, include_velocities, options_.max_reply_bytes, infos != nullptr));
  out->clear();
  if (infos) infos->clear();
  for (const auto& e : entries) {
    std::lock_guard<std::mutex> lock(e->mu);
    if (e->destroyed) return Status::NotFound(fmt::format("scene '{}' was destroyed", e->id));
    out->push_back(e->snapshot(true, include_velocities));
    if (infos) infos->push_back(e->tmpl->info);
  }
  return Status::Ok();
}

Status ScenePool::check(const std::vector<std::string>& ids, const std::string& owner) const {
  std::vector<std::shared_ptr<Entry>> entries;
  return lookup(ids, owner, &entries);
}

std::vector<std::string> ScenePool::existing(const std::vector<std::string>& ids, const std::string& owner) const {
  std::lock_guard<std::mutex> lock(mu_);
  std::vector<std::string> out;
  for (const std::string& id : ids) {
    auto it = scenes_.find(id);
    if (it != scenes_.end() && it->second->owner == owner) out.push_back(id);
  }
  return out;
}

Status ScenePool::destroy(const std::vector<std::string>& ids, int* destroyed, const std::string& owner) {
  std::vector<std::shared_ptr<Entry>> entries;
  GD_RETURN_IF_ERROR(lookup(ids, owner, &entries));
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (const auto& e : entries) scenes_.erase(e->id);
  }
  for (const auto& e : entries) {
    std::lock_guard<std::mutex> lock(e->mu);
    e->destroyed = true;
    e->close_subscribers();
    e->scene.reset();
    e->controller.reset();
    e->grippers = nullptr;
    e->robot = nullptr;
  }
  *destroyed = static_cast<int>(entries.size());
  return Status::Ok();
}

int ScenePool::expire_idle() {
  if (!(options_.scene_lease_seconds > 0)) return 0;
  const int64_t now = steady_ns();
  const auto lease_ns = static_cast<int64_t>(options_.scene_lease_seconds * 1e9);
  std::vector<std::pair<std::shared_ptr<Entry>, double>> gone;
  {
    std::lock_guard<std::mutex> lock(mu_);
    for (auto it = scenes_.begin(); it != scenes_.end();) {
      Entry& e = *it->second;
      if (now - e.last_used_ns.load() <= lease_ns) {
        ++it;
        continue;
      }
      std::unique_lock<std::mutex> busy(e.mu, std::try_to_lock);
      if (!busy.owns_lock()) {  // a call is stepping it right now
        ++it;
        continue;
      }
      const bool watched = std::any_of(e.subscribers.begin(), e.subscribers.end(), [](auto& w) { return !w.expired(); });
      if (watched) {  // a stream subscribes: in use
        e.last_used_ns = now;
        ++it;
        continue;
      }
      const double idle = (now - e.last_used_ns.load()) * 1e-9;
      expired_[e.id] = Expired{e.owner, idle};
      expired_order_.push_back(e.id);
      if (expired_order_.size() > kExpiredRemembered) {
        expired_.erase(expired_order_.front());
        expired_order_.pop_front();
      }
      gone.emplace_back(it->second, idle);
      it = scenes_.erase(it);
    }
  }
  for (auto& [e, idle] : gone) {
    std::lock_guard<std::mutex> lock(e->mu);
    gd::log().info("scene {} destroyed after {:.0f} s without a call (scene lease {:g} s)", e->id, idle,
                   options_.scene_lease_seconds);
    e->destroyed = true;
    e->close_subscribers();
    e->scene.reset();
    e->controller.reset();
    e->grippers = nullptr;
    e->robot = nullptr;
  }
  return static_cast<int>(gone.size());
}

Status ScenePool::subscribe(const std::vector<std::string>& ids, int every, std::shared_ptr<FrameSubscription>* out,
                            const std::string& owner) {
  if (every < 0) return Status::InvalidArgument(fmt::format("every must be >= 1 (got {})", every));
  std::vector<std::shared_ptr<Entry>> entries;
  GD_RETURN_IF_ERROR(lookup(ids, owner, &entries));
  auto sub = std::make_shared<FrameSubscription>(every == 0 ? 1 : every, entries.size(), options().max_queued_frame_bytes);
  for (const auto& e : entries) {
    std::lock_guard<std::mutex> lock(e->mu);
    if (e->destroyed) sub->scene_closed();
    else e->subscribers.push_back(sub);
  }
  *out = std::move(sub);
  return Status::Ok();
}

}  // namespace gd::service
