#pragma once
/// \file
/// gd::Client: the C++ client of the GarmentDynamics gRPC service (proto/garmentdynamics/v1).
///
/// Plain C++ in and out: arrays are std::vector (positions are N*3 float32, x y z per vertex,
/// metres, world frame), no gRPC or protobuf type appears here, so including this header costs
/// nothing and a program using it only links gd::client.
///
///     gd::Client client("localhost:50051");
///     gd::SceneSpec spec;
///     spec.garment = "towel";
///     spec.vertices = 500;
///     spec.count = 16;
///     auto created = client.create_scenes(spec);             // 16 scenes, ids in created.ids
///     auto states = client.step(created.ids, {}, {.substeps = 10});   // one batched step
///     client.destroy(created.ids);
///
/// Every call has a deadline (ClientOptions); every failure, local or remote, throws
/// gd::ClientError with the gRPC status code and the server's message. A Client is safe to use
/// from several threads at once (each call is independent; scenes live on the server).

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace gd {

/// The gRPC status codes, with the same numbers (grpc::StatusCode), so that code of ours need not
/// include gRPC to inspect an error.
enum class StatusCode : int {
  kOk = 0,
  kCancelled = 1,
  kUnknown = 2,
  kInvalidArgument = 3,
  kDeadlineExceeded = 4,
  kNotFound = 5,
  kAlreadyExists = 6,
  kPermissionDenied = 7,
  kResourceExhausted = 8,
  kFailedPrecondition = 9,
  kAborted = 10,
  kOutOfRange = 11,
  kUnimplemented = 12,
  kInternal = 13,
  kUnavailable = 14,
  kDataLoss = 15,
  kUnauthenticated = 16,
};

/// "INVALID_ARGUMENT", "NOT_FOUND", ... (the names gRPC uses); "UNKNOWN_CODE" for others.
const char* status_code_name(StatusCode code);

/// Thrown by every Client method that fails: an RPC the server refused (its status code and
/// message), an unreachable server (UNAVAILABLE), a passed deadline (DEADLINE_EXCEEDED), a
/// request that the client itself can tell is malformed (INVALID_ARGUMENT, before sending), or
/// a response it cannot decode (INTERNAL).
class ClientError : public std::runtime_error {
 public:
  /// `rpc` is the method name ("StepScenes"); what() reads "StepScenes: NOT_FOUND: <message>".
  ClientError(StatusCode code, std::string message, std::string rpc);
  StatusCode code() const { return code_; }
  /// The server's message (or the client's, for local errors), without the prefix of what().
  const std::string& message() const { return message_; }
  const std::string& rpc() const { return rpc_; }

 private:
  StatusCode code_;
  std::string message_;
  std::string rpc_;
};

/// Connection settings.
struct ClientOptions {
  /// Deadline of each unary call (create, step, reports, ...). A batched step of many large
  /// scenes can take seconds: raise it for big batches.
  std::chrono::milliseconds deadline{60'000};
  /// Deadline of the streaming calls (stream, watch_job), which last as long as a rollout.
  std::chrono::milliseconds stream_deadline{3'600'000};
  /// Largest message accepted or sent, bytes (positions of many big scenes are large).
  int max_message_bytes = 256 << 20;
  /// Bearer token sent with every call (a server with --auth-token-file needs one; empty: none).
  /// Send it over TLS beyond loopback: in plaintext anyone on the path can read it.
  std::string token;
  /// TLS: connect over TLS when `tls` is set or root certificates are given (PEM text, e.g. a
  /// self-signed server certificate; empty with tls: the system's roots).
  bool tls = false;
  std::string tls_root_certificates;
  /// PEM client certificate chain and key, for a server that requires them (--tls-client-ca).
  std::string tls_client_certificate, tls_client_key;
};

// ------------------------------------------------------------------------------------------------
// Scenes
// ------------------------------------------------------------------------------------------------

enum class Arm : int { kUnspecified = 0, kLeft = 1, kRight = 2 };

/// A pose in the world frame: position in metres, orientation a unit quaternion, w first.
struct Pose {
  std::array<double, 3> position{0, 0, 0};
  std::array<double, 4> orientation{1, 0, 0, 0};
};

/// One arm's command: the end-effector pose and gripper opening reached at the end of the step
/// (interpolated over its substeps). The gripper grasps when its opening falls below 0.01 m.
/// With `time`, a sample of the arm's trajectory at that scene time instead: an action may name
/// an arm several times (increasing times, each after the arm's last sample, an untimed command
/// last), so one call of many substeps follows a sampled motion; samples past the call's end are
/// kept for later calls.
struct ArmCommand {
  Arm arm = Arm::kLeft;
  Pose pose;
  double gripper = 0.035;  ///< opening, m: 0 closed, 0.035 fully open
  std::optional<double> time;  ///< scene time of this sample, s (unset: the end of the call's steps)
  /// Robot mode: the arm's joint angles (SceneInfo::joint_names' order, rad); `pose` is then
  /// unused. Empty in robot mode: the pose (tool frame) by inverse kinematics on the server.
  std::vector<double> joints;
};

/// What one scene does during a step. Arms not named hold their last command.
struct SceneAction {
  std::string scene_id;
  std::vector<ArmCommand> arms;
  /// Kinematic targets (optional): vertex indices and their target positions (3 per index),
  /// reached over the step and then held until released.
  std::vector<int32_t> target_indices;
  std::vector<float> target_positions;
  bool release_targets = false;  ///< release every kinematic target set earlier
};

/// Scene options; unset fields take the server's defaults (those of `gd run`).
struct SceneSettings {
  std::optional<double> dt;            ///< s per step
  std::optional<bool> self_contact;
  std::optional<double> jaw_radius;    ///< m, pseudo grasp
  std::optional<double> grab_time;     ///< s, fixed-point mode
};

/// Robot mode's arms (docs/robot.md): two arms from a URDF whose gripper fingers hold the cloth
/// by contact and friction.
struct RobotSettings {
  std::string urdf;                    ///< the URDF file's contents; empty: the server's --robot-urdf
  std::optional<double> grip_force;    ///< N: squeeze at which closing fingers stop (default: the URDF's limit)
  std::optional<double> finger_friction;  ///< fabric-finger coefficient (default: the material's)
  /// Scenes: each arm's joints at t = 0 and after a reset (empty: the tool 0.25 m in front of the
  /// arm's base and 0.25 m up, through inverse kinematics).
  std::vector<double> left_initial_joints, right_initial_joints;
  /// Jobs: a generated grasp's lift (fling's height) left to its default is lowered until no hand
  /// tilts more than this from pointing down (degrees; default 30, `gd run --lift-max-tilt`).
  std::optional<double> lift_max_tilt_deg;
  /// Jobs, generated tasks: the garment moved along the table to where the arms lift it highest
  /// (`gd run --place-within-reach`; docs/robot.md, "Placed within reach").
  std::optional<bool> place_within_reach;
  /// N/m: a hand the cloth stops short goes on in the solve, pulled along its step by this
  /// stiffness (default 3e5; 0: its pads wait; docs/robot.md, "Pads in the solve").
  std::optional<double> pad_stiffness;
};

/// What to create: a generated garment (`garment`) or an uploaded mesh (`mesh_id`), one of them.
struct SceneSpec {
  std::string garment;                 ///< a type from list_garments() (towel, tshirt, ...)
  std::string mesh_id;                 ///< an id from upload_mesh()
  std::string material = "cotton";
  int vertices = 2000;                 ///< target vertex count of a generated garment
  std::string mode = "pseudo";         ///< pseudo | fixed_point | robot
  RobotSettings robot;                 ///< mode robot only
  uint64_t seed = 0;                   ///< initial pose randomisation (0: none)
  int count = 1;                       ///< identical scenes to create
  SceneSettings settings;
  double yaw_deg = 0;                  ///< randomisation: yaw uniform in [-yaw_deg, yaw_deg]
  double offset_m = 0;                 ///< randomisation: x, y offset uniform in [-offset_m, offset_m]
  /// Sizes of a generated garment by name (e.g. {"hood_length", 0.25}); docs/garments.md lists them.
  std::map<std::string, double> garment_params;
  /// Parameters of `material` replaced, by the material file's names in catalogue units ("stretch_g_s2",
  /// "bending_g_mm2_s2_rad", "areal_density_g_m2", "poisson", ...; docs/materials.md).
  std::map<std::string, double> material_params;
};

/// What the scenes of one create_scenes call share.
struct SceneInfo {
  int vertex_count = 0;
  std::vector<int32_t> triangles;      ///< T*3 vertex indices
  std::vector<float> rest_positions;   ///< N*3: the garment at seed 0, world frame
  double dt = 0;
  std::string backend;                 ///< cpu | cuda
  std::string mode;
  int left_shoulder_vertex = -1;       ///< landmarks, -1 when unknown
  int right_shoulder_vertex = -1;
  /// Robot mode: each arm's joints in ArmCommand::joints' order, their limits, the largest opening (m).
  std::vector<std::string> joint_names;
  std::vector<double> joint_lower, joint_upper;
  double gripper_max = 0;
  std::optional<double> table_height;  ///< m, the table top (unset: no table)
};

struct ArmState {
  Arm arm = Arm::kUnspecified;
  bool closed = false;                 ///< the gripper is commanded closed
  int held_vertices = 0;               ///< pseudo and fixed-point modes
  std::vector<double> joints;          ///< robot mode: the arm's joints, rad
  double gripper = 0;                  ///< robot mode: the fingers' opening, m
  double squeeze = 0;                  ///< robot mode: the cloth's push on the fingers, N
  /// Robot mode: what the hand does with the cloth ("open", "closing", "held", "missed": the
  /// fingers stopped on little cloth or none, "lost": held, then the cloth left the pads); empty
  /// in the other modes.
  std::string grip;
  /// The tool at the state's time, world frame (pseudo: the commanded pose; robot: the end
  /// effector by forward kinematics).
  Pose pose;
  /// Robot mode: the arm's chain (base, link origins, end effector), world frame, K*3 (m).
  std::vector<float> links;
};

/// A kinematic collider at the state's time (robot mode's finger pads).
struct ColliderState {
  std::string shape;                   ///< box | capsule | plane | mesh
  Pose pose;                           ///< world pose of its local frame
  std::array<double, 3> half_extents{0, 0, 0};  ///< box, m
  double radius = 0, half_length = 0;  ///< capsule, m
};

/// Solver statistics of a scene's last step call.
struct StepStats {
  int newton_iterations = 0;
  int pcg_iterations = 0;
  int active_contacts = 0;
  int intersecting_pairs = 0;          ///< most intersecting triangle pairs after any of the call's steps
  double wall_ms = 0;                  ///< wall time of this scene's substeps on the server
};

/// The state of one scene.
struct SceneState {
  std::string id;
  bool failed = false;                 ///< non-finite state: reset or destroy the scene
  std::string failure;                 ///< why it failed
  double time = 0;                     ///< s of scene time
  int64_t steps = 0;                   ///< steps since the last reset
  std::vector<float> positions;        ///< N*3 (empty when omitted)
  std::vector<float> velocities;       ///< N*3, when asked for
  std::vector<ArmState> arms;
  std::vector<ColliderState> colliders;
  StepStats stats;
  /// Frames of a subscribing stream only (StreamOptions::steps = 0): how many frames the server
  /// has dropped so far because this client read slower than its scenes stepped (it queues at
  /// most --max-queued-frames-mb per stream, oldest frames dropped first).
  int64_t dropped_frames = 0;
};

struct CreatedScenes {
  std::vector<std::string> ids;
  SceneInfo info;
  std::vector<SceneState> states;      ///< initial states, in ids order
};

struct StepOptions {
  int substeps = 1;                    ///< steps per scene
  bool include_velocities = false;
  bool omit_positions = false;         ///< states without positions (status and timing only)
};

struct StreamOptions {
  int every = 1;                       ///< a frame every k-th step of a scene
  int steps = 0;                       ///< > 0: the stream steps the scenes itself this many steps
  int max_frames = 0;                  ///< 0: until the steps are done or the scenes go
};

// ------------------------------------------------------------------------------------------------
// Jobs
// ------------------------------------------------------------------------------------------------

/// A whole rollout run by the server (what `gd run` does locally). Unset optionals take the
/// server's defaults.
struct JobSpec {
  std::string garment;                 ///< a type from list_garments(), or
  std::string mesh_id;                 ///< an id from upload_mesh()
  std::string material = "cotton";
  std::string task = "fold";           ///< grasp | fold | fling
  std::string mode = "pseudo";         ///< pseudo | fixed_point | robot
  RobotSettings robot;                 ///< mode robot only
  int vertices = 2000;
  std::string trajectory;              ///< optional: trajectory CSV or JSON text (docs/tasks.md)
  std::string trajectory_format;       ///< csv | json (required with trajectory)
  std::string capture;                 ///< optional: a capture directory under the server's capture root
  std::optional<double> dt;
  std::optional<double> time_scale;
  std::optional<double> settle;
  std::optional<bool> self_contact;
  bool icp = false;
  std::string label;                   ///< free text kept with the report
  std::map<std::string, double> garment_params;  ///< sizes of a generated garment by name
  /// Parameters of the generated task by TaskParams name (e.g. {"fold_duration", 5}); docs/tasks.md.
  std::map<std::string, double> task_params;
  /// Parameters of the material replaced, in catalogue units (as SceneSpec::material_params).
  std::map<std::string, double> material_params;
  /// m: the mesh refined to this edge (at least 0.001) within refine_grasp_radius m (default
  /// 0.05) of the task's grasp points (`gd run --refine-grasp`); unset: off. The refined garment
  /// counts against the server's vertex limit.
  std::optional<double> refine_grasp_edge;
  std::optional<double> refine_grasp_radius;
};

enum class JobStatus : int {
  kUnspecified = 0,
  kQueued = 1,
  kRunning = 2,
  kSucceeded = 3,
  kFailed = 4,
  kInterrupted = 5,
  kCancelled = 6,
};

/// "queued", "running", "succeeded", "failed", "interrupted", "cancelled" ("unspecified" otherwise).
const char* job_status_name(JobStatus status);
/// True for succeeded, failed and interrupted.
bool job_finished(JobStatus status);

struct JobInfo {
  std::string id;
  JobStatus status = JobStatus::kUnspecified;
  double progress = 0;                 ///< 0..1
  double sim_time = 0;
  double end_time = 0;
  std::string message;                 ///< failure reason, if any
  std::string garment;
  std::string material;
  std::string task;
  std::string label;
  std::string created_at;              ///< ISO 8601 UTC
  std::string finished_at;
};

struct ReportFile {
  std::string name;                    ///< e.g. "summary.json", "metrics.csv", "final.obj"
  std::string data;                    ///< the file's bytes
};

struct Report {
  JobInfo job;
  std::string summary_json;            ///< summary.json of the run (docs/metrics.md)
  std::vector<ReportFile> files;       ///< filled when asked for
  std::vector<std::string> file_names; ///< always: the names of the stored files
};

struct ReportList {
  std::vector<JobInfo> jobs;           ///< newest first
  int total = 0;
};

// ------------------------------------------------------------------------------------------------
// Assets and server
// ------------------------------------------------------------------------------------------------

struct UploadedMesh {
  std::string id;
  std::string name;
  int vertices = 0;
  int triangles = 0;
};

struct GarmentCatalog {
  std::vector<std::string> garments;   ///< generated types
  std::vector<UploadedMesh> meshes;
};

struct MaterialInfo {
  std::string name;
  double density = 0;                  ///< kg/m^2
  double thickness = 0;                ///< m
};

struct ServerInfo {
  std::string version;
  std::string backend;
  int threads = 0;
  int max_scenes = 0;
  int max_vertices = 0;
  int scenes = 0;                      ///< alive now
  int jobs_running = 0;
};

/// grpc.health.v1 serving status.
enum class HealthStatus : int { kUnknown = 0, kServing = 1, kNotServing = 2, kServiceUnknown = 3 };

// ------------------------------------------------------------------------------------------------

/// A connection to one server. Methods mirror the RPCs of garmentdynamics.v1.GarmentDynamics
/// and throw ClientError on any failure.
class Client {
 public:
  /// `target` is "host:port" (or any gRPC target, e.g. "unix:/path"); insecure channel. Does
  /// not connect yet: the first call (or wait_until_ready) does.
  explicit Client(const std::string& target, ClientOptions options = {});
  ~Client();
  Client(Client&&) noexcept;
  Client& operator=(Client&&) noexcept;
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  const std::string& target() const;
  const ClientOptions& options() const;
  /// Changes the deadline of the following unary calls.
  void set_deadline(std::chrono::milliseconds deadline);

  /// Waits until the channel is connected; false when `timeout` passes first.
  bool wait_until_ready(std::chrono::milliseconds timeout);

  // --- scenes ---
  CreatedScenes create_scenes(const SceneSpec& spec);
  /// Back to the initial state; `seeds` empty (each scene's creation seed), one for all, or one
  /// per scene.
  std::vector<SceneState> reset(const std::vector<std::string>& ids, const std::vector<uint64_t>& seeds = {});
  /// One batched step of `ids` (actions may name a subset); states in ids order.
  std::vector<SceneState> step(const std::vector<std::string>& ids, const std::vector<SceneAction>& actions = {},
                               const StepOptions& options = {});
  std::vector<SceneState> get_state(const std::vector<std::string>& ids, bool include_velocities = false);
  /// What each scene was created with (triangles, rest positions, joints, ...), also for scenes
  /// this client did not create (a viewer's); in ids order.
  std::vector<SceneInfo> describe(const std::vector<std::string>& ids);
  /// Streams frames (one scene per frame) to `on_frame` until the stream ends; `on_frame`
  /// returns false to stop early (the call is then cancelled, which is not an error). Returns
  /// the number of frames received.
  int64_t stream(const std::vector<std::string>& ids, const StreamOptions& options,
                 const std::function<bool(const SceneState&)>& on_frame);
  /// Streams a queued or running job's scene as the job steps it (every `options.every`-th step;
  /// options.steps must be 0) until the job ends or `on_frame` returns false. The frames carry
  /// the job id as SceneState::id. `info`, when given, receives the job's scene (triangles,
  /// table, joints) before the first frame reaches `on_frame`. A finished job throws
  /// FAILED_PRECONDITION (get_report has its animation).
  int64_t stream_job(const std::string& job_id, const StreamOptions& options,
                     const std::function<bool(const SceneState&)>& on_frame, SceneInfo* info = nullptr);
  /// Returns the number of scenes destroyed.
  int destroy(const std::vector<std::string>& ids);

  // --- jobs ---
  /// Returns the job id.
  std::string submit_job(const JobSpec& spec);
  /// Calls `on_update` for each progress message until the job ends; returns the last JobInfo.
  JobInfo watch_job(const std::string& job_id, const std::function<void(const JobInfo&)>& on_update = {});
  Report get_report(const std::string& job_id, bool include_files = false);
  /// Cancels a job (CancelJob): a queued one ends CANCELLED at once, a running one at its next
  /// step (the JobInfo returned may still say running). Throws ClientError FAILED_PRECONDITION
  /// for a job that has already finished otherwise.
  JobInfo cancel_job(const std::string& job_id);
  ReportList list_reports(int limit = 100, int offset = 0);

  // --- assets and server ---
  GarmentCatalog list_garments();
  std::vector<MaterialInfo> list_materials();
  /// Uploads a Wavefront OBJ text (not a path); returns its id and size.
  UploadedMesh upload_mesh(const std::string& name, const std::string& obj_text);
  ServerInfo server_info();
  /// grpc.health.v1.Health/Check of `service` ("" = the whole server).
  HealthStatus health(const std::string& service = "");

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gd
