#pragma once
/// \file
/// JobQueue: whole rollouts (experiment::run_experiment) run by background workers, with
/// progress kept in memory and the finished report stored in the ReportStore. No gRPC here.
///
/// Lifecycle: submit() validates everything it can (garment, material, task, mode, numbers,
/// trajectory text, capture directory inside the capture root) and returns the id at once with
/// the job QUEUED (row written to SQLite). A worker sets it RUNNING, runs the experiment with its
/// files under DATA_DIR/jobs/<job_id>/, and on completion writes the summary, the file names and
/// the final status (SUCCEEDED, or FAILED when the simulation failed or the input was refused) in
/// one transaction. A run longer than max_job_steps fails before its scene is built. cancel()
/// drops a queued job or stops a running one at its next step (CANCELLED). At construction,
/// rows a previous process left QUEUED/RUNNING become INTERRUPTED and their partial output
/// directories are removed. drain() stops taking jobs, lets running ones finish within a grace
/// period, and then interrupts them (INTERRUPTED, "server stopped while the job ran").

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <map>
#include <mutex>
#include <optional>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "service/mesh_library.h"
#include "service/report_store.h"
#include "service/robot_spec.h"
#include "service/scene_pool.h"
#include "service/status.h"
#include "sim/solver/options.h"

namespace gd::experiment {
struct ExperimentConfig;
}
namespace gd::sim {
class Scene;
}
namespace gd::tasks {
class TaskController;
}

namespace gd::service {

/// A job request in plain types (the proto's SubmitJobRequest).
struct JobSpec {
  std::string garment;              ///< a garment type, or
  std::string mesh_id;              ///< an uploaded mesh
  std::string material;             ///< default cotton
  std::string task;                 ///< grasp | fold | fling
  std::string mode;                 ///< pseudo (default) | fixed_point | robot
  RobotSpec robot;                  ///< mode robot only
  int vertices = 0;                 ///< 0: 2000
  std::string trajectory;           ///< optional CSV or JSON text
  std::string trajectory_format;    ///< csv | json (required with trajectory)
  std::string capture;              ///< optional, relative to the capture root
  std::optional<double> dt, time_scale, settle;
  std::optional<bool> self_contact;
  bool icp = false;
  std::string label;
  std::map<std::string, double> garment_params;  ///< sizes of a generated garment by name
  std::map<std::string, double> task_params;     ///< TaskParams by name
  std::map<std::string, double> material_params;  ///< material parameters replaced (sim::with_catalogue_params)
  /// m: the mesh refined to this edge near the grasp points, within refine_grasp_radius m
  /// (ExperimentConfig::refine_grasp_edge; unset: off, radius 0.05).
  std::optional<double> refine_grasp_edge, refine_grasp_radius;
  std::string owner;                ///< the submitting caller's principal (JobRecord::owner)
};

struct JobQueueOptions {
  std::string data_dir;             ///< jobs go to data_dir/jobs/<id>/
  std::string capture_root;         ///< captures are resolved under it (empty: data_dir/captures)
  int workers = 1;
  /// OpenMP threads of each job's solver (0: OpenMP's default, every core). The server gives each
  /// job its share of --threads (threads / job workers): a job's parallel regions on more threads
  /// than the cores left to it wait a scheduler slice at every barrier (a 200-vertex towel's Grasp
  /// took 4 s instead of 0.9 s on two threads while two other processes kept both cores busy).
  int threads_per_job = 0;
  int max_vertices = 50000;
  int max_queued = 1000;            ///< queued jobs at once
  /// Most simulation steps one job may take (its simulated time over dt; --max-job-steps): a
  /// longer job fails before its scene is built, naming the flag. 0: no limit.
  long max_job_steps = 2'000'000;
  bool plots = false;               ///< draw the PNG plots of capture runs (needs Python + matplotlib)
  sim::BackendKind backend = sim::BackendKind::kCpu;
  bool deterministic = false;  ///< SceneOptions::deterministic for every scene (--deterministic)
  /// Frames one StreamFrames subscription to a job queues for a slow reader (--max-queued-frames-mb).
  size_t max_queued_frame_bytes = size_t(16) << 20;
  /// Robot-mode jobs whose request sends no URDF run with this one (flag --robot-urdf; empty:
  /// they are refused).
  std::string robot_urdf;
  /// Where robot_urdf's `package://` mesh URIs are looked for (flag --robot-urdf-package-path;
  /// robot::ArmModelOptions::package_paths).
  std::vector<std::string> robot_package_paths;
};

/// A finished job's report with (optionally) its files' bytes.
struct JobReport {
  JobRecord job;
  std::string summary_json;
  std::vector<std::string> file_names;
  std::vector<std::pair<std::string, std::string>> files;  ///< name, bytes
};

class JobQueue {
 public:
  /// Marks leftover unfinished jobs interrupted and starts the workers.
  JobQueue(JobQueueOptions options, ReportStore& store, MeshLibrary& meshes);
  /// drain(0).
  ~JobQueue();
  JobQueue(const JobQueue&) = delete;
  JobQueue& operator=(const JobQueue&) = delete;

  const JobQueueOptions& options() const { return options_; }

  /// Validates and queues a job. UNAVAILABLE while draining.
  Status submit(const JobSpec& spec, std::string* job_id);
  // Every lookup names its caller (a principal, "" on a server without tokens): a job the caller
  // may not see (job_visible) is NOT_FOUND, with the same message as an unknown id.

  /// The job's record (live progress for this process's jobs). NOT_FOUND for unknown ids.
  Status info(const std::string& job_id, JobRecord* out, const std::string& caller = {});
  /// Waits up to timeout_ms for the job's record to change from `*version`, then returns the
  /// record and its version (version 0 on the first call returns at once).
  Status wait(const std::string& job_id, uint64_t* version, JobRecord* out, int timeout_ms,
              const std::string& caller = {});
  /// The report of a finished job; FAILED_PRECONDITION while it is queued or running. With
  /// include_files the files' bytes too (skipping frames/, at most max_file_bytes in total).
  Status report(const std::string& job_id, bool include_files, size_t max_file_bytes, JobReport* out,
                const std::string& caller = {});
  /// The jobs the caller may see, newest first (limit 0: 100).
  Status list(int limit, int offset, std::vector<JobRecord>* out, int* total, const std::string& caller = {});
  /// Jobs queued or running now.
  int active() const;
  /// Whether a queued job will read the file at `path` (an uploaded garment; the mesh lease).
  bool uses_file(const std::string& path) const;
  /// Cancels a job: a queued one is dropped at once, a running one stops at its next step; both
  /// end CANCELLED (the running one keeps the files it wrote). FAILED_PRECONDITION for a finished
  /// job, NOT_FOUND for an unknown one. `out` receives the record as it stands after the call.
  Status cancel(const std::string& job_id, JobRecord* out, const std::string& caller = {});

  /// Subscribes to the frames of a queued or running job's scene: every `every`-th step of its
  /// run (the settling before planning is not sent), the job id as scene id, the first frame with
  /// the scene's SceneInfo (SceneSnapshot::info). The subscription finishes when the job ends.
  /// FAILED_PRECONDITION for a finished job (its report has the run's animation), NOT_FOUND for
  /// an unknown one, INVALID_ARGUMENT for every < 1.
  Status subscribe_frames(const std::string& job_id, int every, std::shared_ptr<FrameSubscription>* out,
                          const std::string& caller = {});

  /// Calls `f` after every change of a job's record, on the thread that made it, with no lock
  /// held; f must not block. Returns an id for remove_listener.
  int add_listener(std::function<void()> f);
  /// Removes a listener (a call that had already begun may still run: f must stay safe to call,
  /// e.g. through a weak_ptr).
  void remove_listener(int id);

  /// Stops taking jobs, waits up to grace_seconds for the running ones, then interrupts them and
  /// the queued ones. Idempotent.
  void drain(double grace_seconds);

 private:
  struct Live {
    JobRecord record;
    uint64_t version = 1;
  };
  void worker();
  void run_job(const std::string& id);
  void update(const std::string& id, const std::function<void(JobRecord&)>& fn);
  /// After step `step` of job `id`'s run: a frame of its scene for the subscribers whose period
  /// divides `step` (`info`: the scene's SceneInfo, made at the first frame sent).
  void publish_frame(const std::string& id, const std::string& mode, int64_t step, const sim::Scene& scene,
                     const tasks::TaskController& controller, std::shared_ptr<const SceneInfo>* info);

  JobQueueOptions options_;
  ReportStore& store_;
  MeshLibrary& meshes_;
  mutable std::mutex mu_;
  std::condition_variable cv_;       ///< queue and record changes
  std::deque<std::string> queue_;
  std::map<std::string, Live> live_;
  std::map<std::string, std::shared_ptr<experiment::ExperimentConfig>> configs_;  ///< of queued jobs
  int running_ = 0;
  bool draining_ = false;
  std::atomic<bool> cancel_{false};
  std::set<std::string> cancelled_;  ///< running jobs a client cancelled (stop at their next step)
  /// Frame subscriptions by job (under mu_); closed and dropped when the job's record ends.
  std::map<std::string, std::vector<std::weak_ptr<FrameSubscription>>> frame_subs_;
  std::vector<std::thread> workers_;
  std::mutex listeners_mu_;  ///< guards listeners_ (not held while they run)
  std::map<int, std::function<void()>> listeners_;
  int next_listener_ = 0;
};

}  // namespace gd::service
