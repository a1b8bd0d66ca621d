#pragma once
/// \file
/// ScenePool: the service's stateful scenes, in plain C++ (no gRPC), usable on its own, e.g. by
/// a benchmark that steps the same scenes in-process:
///
///   gd::service::PoolOptions o;  o.threads = 2;
///   gd::service::ScenePool pool(o);
///   gd::service::SceneSpec spec;  spec.garment = "towel";  spec.vertices = 150;  spec.count = 16;
///   gd::service::CreatedScenes created;
///   if (auto st = pool.create(spec, &created); !st.ok()) ...;
///   gd::service::StepRequest req;  req.scene_ids = created.ids;  req.substeps = 10;
///   std::vector<gd::service::SceneSnapshot> states;
///   pool.step(req, &states);            // the 16 scenes are stepped in parallel on the pool
///
/// A scene is a garment (generated, or an OBJ file) placed on the table at
/// tasks::default_garment_pose(), rigidly randomised per seed (yaw about z, x/y offset), a
/// material, SceneOptions = ExperimentConfig::default_scene_options() with the spec's dt and
/// self-contact, and a tasks::GripperController (pseudo grasp or RGBench's fixed point) whose
/// trajectory starts with both arms parked at home_pose() with the gripper open at t = 0, or in
/// robot mode a tasks::RobotController (URDF arms whose fingers hold the cloth; docs/robot.md)
/// starting at robot_home_pose(). A step's arm command appends a sample at the step's end time
/// (robot mode: its joints, or its pose through inverse kinematics); arms not named hold their
/// last command.
///
/// Every method validates its input and returns a Status (never throws): unknown ids ->
/// kNotFound, bad values/NaN -> kInvalidArgument, over a limit -> kResourceExhausted, stepping a
/// failed scene -> kFailedPrecondition. A scene whose state turns non-finite during a step is
/// marked failed in its snapshot and the other scenes of the call carry on.
///
/// Thread safety: all methods may be called concurrently. Calls on the same scene are serialised
/// by a per-scene mutex; calls on different scenes run independently. The scenes of one step()
/// call are distributed over the pool's workers; each scene's solver uses one OpenMP thread when
/// the call has at least as many scenes as workers, else workers / scenes threads.

#include <Eigen/Geometry>
#include <array>
#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "service/robot_spec.h"
#include "service/status.h"
#include "service/thread_pool.h"
#include "sim/solver/options.h"
#include "sim/types.h"
#include "tasks/frames.h"

namespace gd::robot {
class ArmModel;
}
namespace gd::tasks {
struct RobotOptions;
class TaskController;
}
namespace gd::sim {
class Scene;
}

namespace gd::service {

using sim::Vec3;

/// Limits and resources of a pool.
struct PoolOptions {
  int threads = 0;             ///< worker threads (0: hardware concurrency)
  int max_scenes = 256;        ///< scenes alive at once (flag --max-scenes)
  int max_vertices = 50000;    ///< vertices per scene (flag --max-vertices)
  int max_substeps = 1000;     ///< substeps per step call
  /// Largest reply a step or state call may make, bytes (the server's --max-message-mb; 0: no
  /// limit): a call whose reply would not fit is refused before any scene changes.
  size_t max_reply_bytes = 0;
  /// Most bytes of frames one subscription queues for a client that reads slower than its scenes
  /// step (flag --max-queued-frames-mb); past it the oldest frames are dropped (FrameSubscription).
  size_t max_queued_frame_bytes = size_t(16) << 20;
  /// Scenes that no call has named for this long are destroyed by expire_idle() (flag
  /// --scene-lease-s; 0: never): a client that dies or forgets DestroyScenes does not hold its
  /// slots and memory for good.
  double scene_lease_seconds = 0;
  sim::BackendKind backend = sim::BackendKind::kCpu;
  bool deterministic = false;  ///< SceneOptions::deterministic for every scene (--deterministic)
  /// The arms of robot-mode scenes whose request sends no URDF (flag --robot-urdf; empty: such
  /// requests are refused). Loaded when the pool is built: a bad file stops the server there.
  std::string robot_urdf;
  /// Where robot_urdf's `package://` mesh URIs are looked for (flag --robot-urdf-package-path;
  /// robot::ArmModelOptions::package_paths).
  std::vector<std::string> robot_package_paths;
};


/// What CreateScenes asks for. Unset optionals take the defaults noted.
struct SceneSpec {
  std::string garment;           ///< a garment type (garments::garment_types()), or
  std::string mesh_path;         ///< an OBJ file (an uploaded mesh); takes precedence when set
  std::string material = "cotton";
  int vertices = 2000;           ///< target vertex count of a generated garment
  std::string mode = "pseudo";   ///< pseudo | fixed_point | robot
  RobotSpec robot;               ///< mode robot only
  uint64_t seed = 0;             ///< randomisation seed of the initial pose (0: none)
  int count = 1;                 ///< scenes to create
  std::optional<double> dt;      ///< s (default 0.01)
  std::optional<bool> self_contact;  ///< default true
  std::optional<double> jaw_radius;  ///< m (default 0.02)
  std::optional<double> grab_time;   ///< s, fixed point (default 0)
  double yaw_deg = 0;            ///< randomisation: yaw uniform in [-yaw_deg, yaw_deg]
  double offset_m = 0;           ///< randomisation: x/y offsets uniform in [-offset_m, offset_m]
  std::map<std::string, double> garment_params;  ///< sizes of a generated garment by name
  std::map<std::string, double> material_params;  ///< material parameters replaced (sim::with_catalogue_params)
  std::string owner;             ///< the caller's principal (see ScenePool: ownership)
  /// Asked while the garment is meshed: true stops it (CANCELLED, nothing created). May be empty.
  std::function<bool()> cancelled;
};

/// One arm's command for the end of a step.
struct ArmCommand {
  tasks::Arm arm = tasks::Arm::kLeft;
  Vec3 position = Vec3::Zero();
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();  ///< need not be normalised
  double gripper = 0.035;        ///< opening, m
  /// Scene time of this sample, s; unset: the end of the call's steps. Several samples of one
  /// arm come in increasing time, each after the arm's last sample (an untimed one last).
  std::optional<double> time;
  /// Robot mode only: the arm's joint angles (SceneInfo::joint_names' order); position and
  /// orientation are then unused. Empty in robot mode: the pose by inverse kinematics.
  std::vector<double> joints;
};

/// What to do to one scene in a step.
struct SceneAction {
  std::string scene_id;
  std::vector<ArmCommand> arms;
  std::vector<int> target_indices;   ///< kinematic targets (may be empty)
  std::vector<Vec3> target_positions;
  bool release_targets = false;      ///< release every kinematic target set earlier (before new ones)
};

struct StepRequest {
  std::vector<std::string> scene_ids;  ///< empty: the scenes named by the actions
  std::vector<SceneAction> actions;
  int substeps = 1;
  bool include_positions = true;
  bool include_velocities = false;
  /// Asked between substeps (the call's deadline passed or the client left): the scenes stop at
  /// a step boundary and step() returns CANCELLED. Empty: never.
  std::function<bool()> cancelled;
  std::string owner;                   ///< the caller's principal (see ScenePool: ownership)
};

/// One arm's state in a snapshot.
struct ArmSnapshot {
  bool closed = false;               ///< the gripper is commanded closed
  int held_vertices = 0;             ///< pseudo / fixed point modes
  std::vector<double> joints;        ///< robot mode: the arm's joints, rad
  double gripper = 0;                ///< robot mode: the fingers' opening, m
  double squeeze = 0;                ///< robot mode: the cloth's push on the fingers, N
  std::optional<tasks::Grip> grip;   ///< robot mode: what the hand does with the cloth
  int pad_cuts = 0;                  ///< robot mode: where the pads cut the cloth (RobotArmState::pad_cuts)
  double pad_cut_depth = 0;          ///< robot mode: how deep, m (RobotArmState::pad_cut_depth)
  /// The tool at the snapshot's time, world frame: the commanded trajectory's pose (pseudo,
  /// fixed point) or the end effector by forward kinematics (robot).
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  /// Robot mode: the arm's chain, world frame (base, link origins, end effector), for viewers.
  std::vector<Vec3> links;
};

/// A kinematic collider at the snapshot's time (robot mode's finger pads), for viewers.
struct ColliderSnapshot {
  std::string shape = "box";         ///< box | capsule | plane | mesh
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< world pose of its local frame
  Vec3 half_extents = Vec3::Zero();  ///< box, m
  double radius = 0, half_length = 0;  ///< capsule, m
};

/// The state of one scene.
struct SceneInfo;

struct SceneSnapshot {
  std::string scene_id;
  bool failed = false;
  std::string failure;
  double time = 0;
  int64_t steps = 0;                   ///< since the last reset
  std::vector<Vec3> positions;         ///< when asked for
  std::vector<Vec3> velocities;        ///< when asked for
  std::array<ArmSnapshot, 2> arms;     ///< [left, right]
  std::vector<ColliderSnapshot> colliders;
  int newton_iterations = 0;           ///< of the last step call (summed over its substeps)
  int pcg_iterations = 0;
  int active_contacts = 0;
  int intersecting_pairs = 0;          ///< most after any step of the last step call
  double wall_ms = 0;
  /// A job's frames (JobQueue::subscribe_frames): the job's scene, which StreamFrames sends with
  /// its first message. Null for the pool's scenes (GetState gives their SceneInfo).
  std::shared_ptr<const SceneInfo> info;
};

/// What the scenes of one create() share.
struct SceneInfo {
  int vertex_count = 0;
  std::vector<Eigen::Vector3i> triangles;
  std::vector<Vec3> rest_positions;    ///< the placed garment at seed 0, world frame
  double dt = 0;
  std::string backend;                 ///< "cpu" | "cuda"
  std::string mode;
  int left_shoulder_vertex = -1;
  int right_shoulder_vertex = -1;
  /// Robot mode: the arm joints ArmCommand::joints takes, their limits, the largest opening (m).
  std::vector<std::string> joint_names;
  std::vector<double> joint_lower, joint_upper;
  double gripper_max = 0;
  std::optional<double> table_height;  ///< m, the table top; unset: no table
};

struct CreatedScenes {
  std::vector<std::string> ids;
  SceneInfo info;
  std::vector<SceneSnapshot> states;   ///< initial states, with positions
};

/// Receives the frames of subscribed scenes (StreamFrames without its own steps): a frame is
/// queued whenever a scene's step count reaches a multiple of `every`. Closed when all its
/// scenes are destroyed or the pool goes away. The queue holds at most `max_bytes` of frames
/// (frame_bytes; always the newest frame): a subscriber that reads slower than its scenes step
/// loses the oldest frames, counted by dropped(), instead of growing the server without bound.
class FrameSubscription {
 public:
  FrameSubscription(int every, size_t scenes, size_t max_bytes)
      : every_(every), open_scenes_(scenes), max_bytes_(max_bytes) {}
  /// What a frame counts against the queue's bytes: its vectors plus a fixed overhead.
  static size_t frame_bytes(const SceneSnapshot& s);
  /// Frames dropped so far because the queue was full.
  int64_t dropped();
  /// Waits up to `timeout_ms` for a frame (0: does not wait). Returns true and fills `out` when
  /// one came.
  bool pop(SceneSnapshot* out, int timeout_ms);
  /// True when every subscribed scene is gone and no frame is left.
  bool finished();
  /// Calls `f` after every frame queued and every scene closed, on the thread that did it (a scene
  /// worker), with no lock held; f must not block. An empty f removes the listener (a call that
  /// had already begun may still run: f must stay safe to call, e.g. through a weak_ptr).
  void set_listener(std::function<void()> f);

  // Called by the pool.
  int every() const { return every_; }
  void push(SceneSnapshot s);
  void scene_closed();

 private:
  void notify();

  std::mutex mu_;
  std::condition_variable cv_;
  std::mutex listener_mu_;  ///< guards listener_ (not held while it runs)
  std::function<void()> listener_;
  std::deque<SceneSnapshot> frames_;
  int every_;
  size_t open_scenes_;
  size_t max_bytes_;
  size_t queued_bytes_ = 0;
  int64_t dropped_ = 0;
};

/// The default home pose of an arm: 0.3 m above its base, gripper pointing down.
Eigen::Isometry3d home_pose(tasks::Arm arm);
/// Robot mode's home pose of an arm's tool, reached by inverse kinematics (the Piper cannot reach
/// straight above its base): 0.25 m in front of its base and 0.25 m up, pointing down as far as
/// the wrist allows.
Eigen::Isometry3d robot_home_pose(tasks::Arm arm);

/// The state of `scene` driven by `controller` (a tasks::GripperController or RobotController):
/// time, failure, both arms and robot mode's finger pads; positions and velocities when asked.
/// The caller fills scene_id, steps and the step statistics.
SceneSnapshot snapshot_of(const sim::Scene& scene, const tasks::TaskController& controller, bool positions,
                          bool velocities);
/// The SceneInfo of a scene built outside the pool (a job's): its mesh with the scene's positions
/// now as rest_positions, dt, backend, the table, and in robot mode the arms' joints; `mode` as
/// the request named it. No shoulder vertices (-1).
SceneInfo info_of(const sim::Scene& scene, const tasks::TaskController& controller, const std::string& mode);

/// Ownership: every scene belongs to the principal that created it (SceneSpec::owner; with
/// --auth-token-file the fingerprint of the caller's token, else ""). Every call names its caller
/// (`owner`); a scene of another owner is NOT_FOUND with the same message as an unknown id, so
/// ids reveal nothing across tenants. Scene ids are "s-" and 32 hex digits from the system's
/// CSPRNG (random_hex): unguessable.
class ScenePool {
 public:
  /// Starts the worker threads. Throws sim::InputError for nonsensical options (negative limits).
  explicit ScenePool(PoolOptions options);
  ~ScenePool();
  ScenePool(const ScenePool&) = delete;
  ScenePool& operator=(const ScenePool&) = delete;

  const PoolOptions& options() const { return options_; }
  int threads() const { return pool_.size(); }
  /// Scenes alive now.
  int size() const;

  /// Builds spec.count identical scenes (randomised by spec.seed).
  Status create(const SceneSpec& spec, CreatedScenes* out);
  /// Rebuilds scenes in their initial state, randomised by `seeds`: empty = each scene's creation
  /// seed, one = for all, else one per scene. Positions are bit-identical for the same seed.
  Status reset(const std::vector<std::string>& ids, const std::vector<uint64_t>& seeds,
               std::vector<SceneSnapshot>* out, const std::string& owner = {});
  /// Applies the actions and advances the scenes req.substeps steps each, in parallel. Input is
  /// checked before any scene changes.
  Status step(const StepRequest& req, std::vector<SceneSnapshot>* out);
  /// Current states; with `infos`, also each scene's SceneInfo (the same order).
  Status state(const std::vector<std::string>& ids, bool include_velocities, std::vector<SceneSnapshot>* out,
               const std::string& owner = {}, std::vector<SceneInfo>* infos = nullptr);
  /// OK when every id names a live scene, each once (else lookup's NOT_FOUND / INVALID_ARGUMENT).
  Status check(const std::vector<std::string>& ids, const std::string& owner = {}) const;
  /// The ids among `ids` that name live scenes, in order.
  std::vector<std::string> existing(const std::vector<std::string>& ids, const std::string& owner = {}) const;
  /// Destroys scenes (all ids must exist). `destroyed` receives how many.
  Status destroy(const std::vector<std::string>& ids, int* destroyed, const std::string& owner = {});
  /// Subscribes to the frames of scenes (see FrameSubscription). Unsubscribe by dropping the pointer.
  Status subscribe(const std::vector<std::string>& ids, int every, std::shared_ptr<FrameSubscription>* out,
                   const std::string& owner = {});
  /// Destroys the scenes that no call has named for options().scene_lease_seconds (none while a
  /// call holds them or a stream subscribes to them), logging each; later calls naming one get
  /// NOT_FOUND saying it expired. Returns how many. The server calls it periodically.
  int expire_idle();

  struct Entry;  ///< one scene (private to the implementation)

 private:
  Status lookup(const std::vector<std::string>& ids, const std::string& owner,
                std::vector<std::shared_ptr<Entry>>* out) const;
  /// Robot mode's arms and options for a request (its URDF, else the server's).
  Status robot_arms(const RobotSpec& spec, std::shared_ptr<const robot::ArmModel>* arms,
                    tasks::RobotOptions* options) const;

  PoolOptions options_;
  std::shared_ptr<const robot::ArmModel> robot_model_;  ///< options_.robot_urdf's arms, if any
  ThreadPool pool_;
  /// A step call runs each scene's substeps in slices of about this long (at least one step)
  /// and queues the scene again behind other calls' scenes between slices.
  static constexpr double kSliceSeconds = 0.01;

  mutable std::mutex mu_;
  std::map<std::string, std::shared_ptr<Entry>> scenes_;
  /// Scenes destroyed by expire_idle (id -> owner, idle seconds), the oldest forgotten past
  /// kExpiredRemembered, so that a caller learns why its scene is gone.
  struct Expired {
    std::string owner;
    double idle_seconds = 0;
  };
  std::map<std::string, Expired> expired_;
  std::deque<std::string> expired_order_;
  static constexpr size_t kExpiredRemembered = 100000;
  int reserved_ = 0;      ///< slots held by creates in progress
};

}  // namespace gd::service
