#include "service/job_queue.h"

#include "robot/arm_model.h"

#include <fcntl.h>
#include <spdlog/fmt/fmt.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "experiment/experiment.h"
#include "garments/generator.h"
#include "garments/mesher.h"
#include "garments/refine.h"
#include "sim/demand.h"
#include "sim/log.h"
#include "sim/material.h"
#include "sim/scene.h"
#include "tasks/generators.h"
#include "tasks/grippers.h"
#include "tasks/trajectory.h"

namespace gd::service {
namespace fs = std::filesystem;
using sim::InputError;

namespace {

constexpr const char* kInterruptedMessage = "server stopped while the job ran";
constexpr const char* kInterruptedQueuedMessage = "server stopped before the job ran";

/// Thrown from the progress callback to stop a running experiment when the server drains.
struct JobCancelled {
  bool by_client = false;  ///< CancelJob (else the server's drain)
};
constexpr const char* kCancelledMessage = "cancelled by a client (CancelJob)";

void fsync_path(const fs::path& p) {
  const int fd = ::open(p.c_str(), O_RDONLY);
  if (fd >= 0) {
    ::fsync(fd);
    ::close(fd);
  }
}

/// The regular files under dir, relative, sorted.
std::vector<std::string> list_files(const fs::path& dir) {
  std::vector<std::string> out;
  std::error_code ec;
  for (auto it = fs::recursive_directory_iterator(dir, ec); !ec && it != fs::recursive_directory_iterator();
       it.increment(ec))
    if (it->is_regular_file()) out.push_back(fs::relative(it->path(), dir).string());
  std::sort(out.begin(), out.end());
  return out;
}

Status check_number(const std::optional<double>& v, const char* name, bool allow_zero) {
  if (v && (!std::isfinite(*v) || *v < 0 || (!allow_zero && *v == 0)))
    return Status::InvalidArgument(fmt::format("{} must be a finite number {} (got {})", name, allow_zero ? ">= 0" : "> 0", *v));
  return Status::Ok();
}

}  // namespace

JobQueue::JobQueue(JobQueueOptions options, ReportStore& store, MeshLibrary& meshes)
    : options_(std::move(options)), store_(store), meshes_(meshes) {
  if (options_.capture_root.empty()) options_.capture_root = options_.data_dir + "/captures";
  fs::create_directories(fs::path(options_.data_dir) / "jobs");
  std::vector<std::string> unfinished;
  const int n = store_.interrupt_unfinished(kInterruptedMessage, kInterruptedQueuedMessage, &unfinished);
  if (n > 0) gd::log().warn("{} job(s) left unfinished by a previous server are now interrupted", n);
  // Their partial outputs (a process killed mid-job) are no report: nothing lists them.
  for (const std::string& id : unfinished) {
    std::error_code ec;
    const fs::path dir = fs::path(options_.data_dir) / "jobs" / id;
    if (fs::remove_all(dir, ec) > 0) gd::log().info("job {}: removed the partial output of the interrupted run", id);
  }
  for (int i = 0; i < std::max(1, options_.workers); ++i) workers_.emplace_back([this] { worker(); });
}

JobQueue::~JobQueue() { drain(0); }

int JobQueue::active() const {
  std::lock_guard<std::mutex> lock(mu_);
  return running_ + static_cast<int>(queue_.size());
}

bool JobQueue::uses_file(const std::string& path) const {
  std::lock_guard<std::mutex> lock(mu_);
  return std::any_of(configs_.begin(), configs_.end(), [&](const auto& kv) { return kv.second->garment == path; });
}

Status JobQueue::submit(const JobSpec& spec, std::string* job_id) {
  // --- validation (synchronous: the client hears about bad input now) ---
  auto cfg = std::make_shared<experiment::ExperimentConfig>();
  if (spec.garment.empty() == spec.mesh_id.empty())
    return Status::InvalidArgument("give exactly one of garment (a type from ListGarments) or mesh_id (from UploadMesh)");
  if (!spec.garment.empty()) {
    const auto types = garments::garment_types();
    if (std::find(types.begin(), types.end(), spec.garment) == types.end())
      return Status::InvalidArgument(fmt::format("unknown garment '{}'; use one of: {}", spec.garment, fmt::join(types, ", ")));
    cfg->garment = spec.garment;
  } else {
    MeshRecord m;
    GD_RETURN_IF_ERROR(meshes_.get(spec.mesh_id, &m));
    cfg->garment = m.path;
  }
  cfg->material = spec.material.empty() ? "cotton" : spec.material;
  if (!sim::MaterialLibrary::load_default().has(cfg->material))
    return Status::InvalidArgument(fmt::format("unknown material '{}'; ListMaterials lists them", cfg->material));
  if (spec.task.empty()) return Status::InvalidArgument("no task given; use grasp, fold or fling");
  cfg->task = spec.task;
  cfg->mode = spec.mode.empty() ? "pseudo" : spec.mode;
  std::string urdf_text;  // robot mode: a URDF sent with the request, written beside the job's output
  if (cfg->mode == "robot") {
    GD_RETURN_IF_ERROR(apply_robot_spec(spec.robot, !options_.robot_urdf.empty(), &cfg->robot));
    cfg->place_within_reach = spec.robot.place_within_reach.value_or(false);
    if (spec.robot.urdf_xml.empty()) {
      cfg->robot.urdf = options_.robot_urdf;
      cfg->robot.arm.package_paths = options_.robot_package_paths;
    } else {
      cfg->robot.arm.read_meshes = false;  // a client's URDF: the server opens no file it names
      try {
        (void)robot::ArmModel::from_string(spec.robot.urdf_xml, "robot.urdf", cfg->robot.arm);
      } catch (const InputError& e) {
        return Status::InvalidArgument(fmt::format("robot settings: {}", e.what()));
      }
      urdf_text = spec.robot.urdf_xml;
      cfg->robot.urdf = "robot.urdf";  // its path is set with the job's directory below
    }
  } else if (!spec.robot.empty()) {
    return Status::InvalidArgument(fmt::format("robot settings are for mode robot (this job's mode is {})", cfg->mode));
  }
  if (!spec.robot.initial_joints[0].empty() || !spec.robot.initial_joints[1].empty())
    return Status::InvalidArgument(
        "robot initial joints are for scenes; a job's arms start at its trajectory's first sample");
  const int vertices = spec.vertices == 0 ? 2000 : spec.vertices;
  if (vertices < 0) return Status::InvalidArgument(fmt::format("vertices must be > 0 (got {})", spec.vertices));
  if (vertices > options_.max_vertices)
    return Status::ResourceExhausted(fmt::format("vertices {} is over this server's limit of {} (--max-vertices)",
                                                 vertices, options_.max_vertices));
  cfg->vertices = vertices;
  GD_RETURN_IF_ERROR(check_number(spec.dt, "dt", false));
  GD_RETURN_IF_ERROR(check_number(spec.time_scale, "time_scale", false));
  GD_RETURN_IF_ERROR(check_number(spec.settle, "settle", true));
  try {
    for (const auto& [name, value] : spec.task_params) tasks::set_task_param(cfg->task_params, name, value);
  } catch (const InputError& e) {
    return Status::InvalidArgument(e.what());
  }
  try {  // checked now, applied when the job runs
    if (!spec.material_params.empty())
      (void)sim::with_catalogue_params(sim::MaterialLibrary::load_default().get(cfg->material), spec.material_params);
  } catch (const InputError& e) {
    return Status::InvalidArgument(fmt::format("material_params: {}", e.what()));
  }
  cfg->material_params = spec.material_params;
  if (spec.dt) cfg->scene.dt = *spec.dt;
  if (spec.time_scale) cfg->task_params.time_scale = *spec.time_scale;
  if (spec.settle) cfg->settle_after = *spec.settle;
  cfg->max_steps = options_.max_job_steps;
  cfg->steps_limit_name = "--max-job-steps";
  // What is known before the garment is built: the settling alone must fit (the whole run is
  // checked again once its trajectory is known, before the scene is built).
  if (options_.max_job_steps > 0 && cfg->settle_after / cfg->scene.dt > static_cast<double>(options_.max_job_steps))
    return Status::ResourceExhausted(fmt::format(
        "settle {:g} s at dt {:g} s is {:.3g} steps, over this server's limit of {} per job (--max-job-steps)",
        cfg->settle_after, cfg->scene.dt, cfg->settle_after / cfg->scene.dt, options_.max_job_steps));
  if (spec.self_contact) cfg->scene.self_contact = *spec.self_contact;
  cfg->scene.backend = options_.backend;
  cfg->scene.threads = options_.threads_per_job;
  cfg->scene.deterministic = options_.deterministic;
  cfg->icp = spec.icp;
  cfg->plots = options_.plots;
  if (!spec.garment_params.empty() && spec.garment.empty())
    return Status::InvalidArgument("garment_params size a generated garment; an uploaded mesh (mesh_id) takes none");
  cfg->garment_params = spec.garment_params;
  if (spec.refine_grasp_edge) cfg->refine_grasp_edge = *spec.refine_grasp_edge;
  if (spec.refine_grasp_radius) cfg->refine_grasp_radius = *spec.refine_grasp_radius;
  cfg->max_vertices = options_.max_vertices;
  cfg->vertices_limit_name = "this server's --max-vertices";
  if (spec.label.size() > 1024) return Status::InvalidArgument("label is longer than 1024 characters");

  std::optional<tasks::DualArmTrajectory> traj;
  if (!spec.trajectory.empty()) {
    try {
      if (spec.trajectory_format == "csv") {
        traj = tasks::parse_trajectory_csv(spec.trajectory, "trajectory");
      } else if (spec.trajectory_format == "json") {
        traj = tasks::trajectory_from_json(nlohmann::json::parse(spec.trajectory), "trajectory");
      } else {
        return Status::InvalidArgument(
            fmt::format("trajectory_format must be csv or json with a trajectory (got '{}')", spec.trajectory_format));
      }
    } catch (const nlohmann::json::exception& e) {
      return Status::InvalidArgument(fmt::format("trajectory is not valid JSON: {}", e.what()));
    } catch (const InputError& e) {
      return Status::InvalidArgument(e.what());
    }
  }
  if (!spec.capture.empty()) {
    std::error_code ec;
    const fs::path root = fs::weakly_canonical(options_.capture_root, ec);
    const fs::path dir = fs::weakly_canonical(root / spec.capture, ec);
    const auto rel = dir.lexically_relative(root);
    if (ec || rel.empty() || *rel.begin() == ".." || fs::path(spec.capture).is_absolute())
      return Status::InvalidArgument(fmt::format("capture '{}' is outside the server's capture root; give a directory "
                                                 "relative to the capture root", spec.capture));
    if (!fs::is_directory(dir))
      return Status::InvalidArgument(fmt::format("capture '{}' is not a directory under the server's capture root",
                                                 spec.capture));
    cfg->capture_dir = dir.string();
  }

  const std::string id = new_id("j-");
  cfg->out_dir = (fs::path(options_.data_dir) / "jobs" / id).string();
  if (traj) cfg->trajectory_file = cfg->out_dir + "/input_trajectory." + spec.trajectory_format;
  if (!urdf_text.empty()) cfg->robot.urdf = cfg->out_dir + "/robot.urdf";
  try {
    cfg->validate();
  } catch (const InputError& e) {
    return Status::InvalidArgument(e.what());
  }
  if (cfg->refine_grasp_edge > 0) {  // the refined garment must fit the vertex limit: built once now (milliseconds)
    try {
      (void)experiment::make_experiment_garment(*cfg);
    } catch (const garments::TooManyVertices& e) {
      return Status::ResourceExhausted(e.what());
    } catch (const InputError& e) {
      return Status::InvalidArgument(e.what());
    }
  }

  JobRecord rec;
  rec.job_id = id;
  rec.owner = spec.owner;
  rec.status = JobState::kQueued;
  rec.garment = spec.garment.empty() ? spec.mesh_id : spec.garment;
  rec.material = cfg->material;
  rec.task = cfg->task;
  rec.label = spec.label;
  rec.created_at = now_iso8601();
  rec.request_json = nlohmann::json{{"garment", rec.garment},     {"material", cfg->material}, {"task", cfg->task},
                                    {"mode", cfg->mode},          {"vertices", cfg->vertices}, {"dt", cfg->scene.dt},
                                    {"time_scale", cfg->task_params.time_scale},
                                    {"settle", cfg->settle_after}, {"self_contact", cfg->scene.self_contact},
                                    {"capture", spec.capture},    {"icp", cfg->icp},
                                    {"material_params", cfg->material_params},
                                    {"refine_grasp", cfg->refine_grasp_edge > 0 ? nlohmann::json{{"edge_m", cfg->refine_grasp_edge}, {"radius_m", cfg->refine_grasp_radius}} : nlohmann::json()},
                                    {"robot", cfg->mode != "robot" ? nlohmann::json()
                                                                   : nlohmann::json{{"urdf", urdf_text.empty() ? cfg->robot.urdf : "sent"},
                                                                                    {"grip_force", cfg->robot.grip_force},
                                                                                    {"finger_friction", cfg->robot.finger_friction},
                                                                                    {"pad_stiffness", cfg->robot.pad_stiffness},
                                                                                    {"lift_max_tilt_deg", cfg->robot.lift_max_tilt * 180 / 3.14159265358979323846},
                                                                                    {"place_within_reach", cfg->place_within_reach}}},
                                    {"trajectory", traj ? spec.trajectory_format : std::string()}}
                         .dump();
  {
    std::lock_guard<std::mutex> lock(mu_);
    if (draining_) return Status::Unavailable("the server is shutting down; submit the job to another server");
    if (static_cast<int>(queue_.size()) >= options_.max_queued)
      return Status::ResourceExhausted(fmt::format("{} jobs are queued already (the limit); wait for some to finish",
                                                   queue_.size()));
  }
  if (traj) {
    fs::create_directories(cfg->out_dir);
    std::ofstream f(cfg->trajectory_file, std::ios::binary);
    f << spec.trajectory;
    if (!f) return Status::Internal(fmt::format("cannot write '{}'", cfg->trajectory_file));
  }
  if (!urdf_text.empty()) {
    fs::create_directories(cfg->out_dir);
    std::ofstream f(cfg->robot.urdf, std::ios::binary);
    f << urdf_text;
    if (!f) return Status::Internal(fmt::format("cannot write '{}'", cfg->robot.urdf));
  }
  GD_RETURN_IF_ERROR(store_.insert_job(rec));
  {
    std::lock_guard<std::mutex> lock(mu_);
    live_[id] = Live{rec, 1};
    configs_[id] = cfg;
    queue_.push_back(id);
  }
  cv_.notify_all();
  gd::log().info("job {} queued: {} {} {} ({} vertices, {})", id, rec.garment, cfg->material, cfg->task, cfg->vertices,
                 cfg->mode);
  *job_id = id;
  return Status::Ok();
}

void JobQueue::update(const std::string& id, const std::function<void(JobRecord&)>& fn) {
  std::vector<std::weak_ptr<FrameSubscription>> ended;  // the job's frame streams, once it has ended
  {
    std::lock_guard<std::mutex> lock(mu_);
    Live& l = live_[id];
    fn(l.record);
    ++l.version;
    if (job_finished(l.record.status)) {
      auto it = frame_subs_.find(id);
      if (it != frame_subs_.end()) {
        ended.swap(it->second);
        frame_subs_.erase(it);
      }
    }
  }
  for (auto& w : ended)
    if (auto sub = w.lock()) sub->scene_closed();
  cv_.notify_all();
  std::vector<std::function<void()>> fs;
  {
    std::lock_guard<std::mutex> lock(listeners_mu_);
    for (const auto& [key, f] : listeners_) fs.push_back(f);
  }
  for (const auto& f : fs) f();
}

int JobQueue::add_listener(std::function<void()> f) {
  std::lock_guard<std::mutex> lock(listeners_mu_);
  listeners_[next_listener_] = std::move(f);
  return next_listener_++;
}

void JobQueue::remove_listener(int id) {
  std::lock_guard<std::mutex> lock(listeners_mu_);
  listeners_.erase(id);
}

void JobQueue::worker() {
  for (;;) {
    std::string id;
    {
      std::unique_lock<std::mutex> lock(mu_);
      cv_.wait(lock, [this] { return draining_ || !queue_.empty(); });
      if (draining_) return;
      id = queue_.front();
      queue_.pop_front();
      ++running_;
    }
    run_job(id);
    {
      std::lock_guard<std::mutex> lock(mu_);
      --running_;
    }
    cv_.notify_all();
  }
}

void JobQueue::run_job(const std::string& id) {
  std::shared_ptr<experiment::ExperimentConfig> cfg;
  {
    std::lock_guard<std::mutex> lock(mu_);
    cfg = configs_[id];
    configs_.erase(id);
  }
  update(id, [](JobRecord& r) { r.status = JobState::kRunning; });
  if (Status st = store_.set_status(id, JobState::kRunning); !st.ok()) gd::log().error("job {}: {}", id, st.message());
  gd::log().info("job {} running", id);

  // The final record is stored first and shown to watchers after, so whoever sees a finished
  // job can read its report.
  JobRecord final_rec;
  {
    std::lock_guard<std::mutex> lock(mu_);
    final_rec = live_[id].record;
  }
  auto finish = [&](JobState st, std::string message) {
    final_rec.status = st;
    final_rec.message = std::move(message);
    final_rec.finished_at = now_iso8601();
  };
  std::string summary;
  std::vector<std::string> files;
  auto end_cancelled = [&](bool by_client) {  // CancelJob (CANCELLED) or the drain (INTERRUPTED)
    std::lock_guard<std::mutex> lock(mu_);
    final_rec = live_[id].record;
    final_rec.status = by_client ? JobState::kCancelled : JobState::kInterrupted;
    final_rec.message = by_client ? kCancelledMessage : kInterruptedMessage;
    final_rec.finished_at = now_iso8601();
    files = list_files(cfg->out_dir);
  };
  auto last = std::chrono::steady_clock::now();
  // Frames for StreamFrames subscribers of this job (none: nothing is copied).
  std::shared_ptr<const SceneInfo> frame_info;
  int64_t frame_step = 0;
  const auto observe = [&](const sim::Scene& scene, const tasks::TaskController& controller) {
    publish_frame(id, cfg->mode, ++frame_step, scene, controller, &frame_info);
  };
  try {
    const garments::MeshingCancellation meshing([&] {  // CancelJob or the drain while the garment is meshed
      if (cancel_.load()) return true;
      std::lock_guard<std::mutex> lock(mu_);
      return cancelled_.count(id) > 0;
    });
    const experiment::ExperimentResult res =
        experiment::run_experiment(*cfg, [&](double t, double end, const sim::StepStats&) {
          if (cancel_.load()) throw JobCancelled{false};
          {
            std::lock_guard<std::mutex> lock(mu_);
            if (cancelled_.count(id)) throw JobCancelled{true};
          }
          const auto now = std::chrono::steady_clock::now();
          if (now - last < std::chrono::milliseconds(100) && t < end) return;
          last = now;
          update(id, [&](JobRecord& r) {
            r.sim_time = t;
            r.end_time = end;
            r.progress = end > 0 ? std::min(1.0, t / end) : 1.0;
          });
        }, observe);
    summary = res.summary.dump(2);
    const bool failed = res.summary.value("failed", false);
    files = list_files(cfg->out_dir);
    for (const std::string& f : files) fsync_path(fs::path(cfg->out_dir) / f);
    fsync_path(cfg->out_dir);
    {
      std::lock_guard<std::mutex> lock(mu_);
      final_rec = live_[id].record;
    }
    finish(failed ? JobState::kFailed : JobState::kSucceeded,
           failed ? "the simulation failed: " + res.summary.value("failure", std::string()) : "");
    final_rec.progress = 1;
    final_rec.sim_time = res.summary.value("sim_seconds", final_rec.sim_time);
    if (final_rec.end_time < final_rec.sim_time) final_rec.end_time = final_rec.sim_time;
  } catch (const JobCancelled& c) {
    end_cancelled(c.by_client);
  } catch (const garments::MeshingCancelled&) {
    end_cancelled(!cancel_.load());
  } catch (const InputError& e) {
    finish(JobState::kFailed, e.what());
  } catch (const std::exception& e) {
    finish(JobState::kFailed, fmt::format("internal error: {}", e.what()));
  }
  if (Status st = store_.complete(final_rec, summary, files); !st.ok())
    gd::log().error("job {}: storing the report failed: {}", id, st.message());
  update(id, [&](JobRecord& r) { r = final_rec; });
  {
    std::lock_guard<std::mutex> lock(mu_);
    cancelled_.erase(id);
  }
  gd::log().info("job {} {}{}", id, job_state_name(final_rec.status),
                 final_rec.message.empty() ? "" : ": " + final_rec.message);
}

Status JobQueue::cancel(const std::string& job_id, JobRecord* out, const std::string& caller) {
  GD_RETURN_IF_ERROR(info(job_id, out, caller));  // another caller's job: NOT_FOUND, untouched
  bool dropped = false;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = live_.find(job_id);
    if (it != live_.end() && !job_finished(it->second.record.status)) {
      auto q = std::find(queue_.begin(), queue_.end(), job_id);
      if (q != queue_.end()) {  // not started: drop it
        queue_.erase(q);
        configs_.erase(job_id);
        dropped = true;
      } else {  // running: its next step throws
        cancelled_.insert(job_id);
      }
    }
  }
  if (dropped) {
    update(job_id, [&](JobRecord& r) {
      r.status = JobState::kCancelled;
      r.message = kCancelledMessage;
      r.finished_at = now_iso8601();
    });
    GD_RETURN_IF_ERROR(store_.set_status(job_id, JobState::kCancelled, kCancelledMessage));
    gd::log().info("job {} cancelled before it ran", job_id);
  }
  GD_RETURN_IF_ERROR(info(job_id, out));
  if (job_finished(out->status) && !dropped && out->status != JobState::kCancelled)
    return Status::FailedPrecondition(fmt::format("job '{}' has already finished ({}); nothing to cancel", job_id,
                                                  job_state_name(out->status)));
  return Status::Ok();
}

namespace {
Status unknown_job(const std::string& job_id) {  // the store's message for an unknown id
  return Status::NotFound(fmt::format("no job '{}' on this server; ListReports lists the jobs", job_id));
}
}  // namespace

void JobQueue::publish_frame(const std::string& id, const std::string& mode, int64_t step, const sim::Scene& scene,
                             const tasks::TaskController& controller, std::shared_ptr<const SceneInfo>* info) {
  std::vector<std::shared_ptr<FrameSubscription>> due;
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = frame_subs_.find(id);
    if (it == frame_subs_.end()) return;
    for (auto w = it->second.begin(); w != it->second.end();) {
      if (auto sub = w->lock()) {
        if (step % sub->every() == 0) due.push_back(std::move(sub));
        ++w;
      } else {
        w = it->second.erase(w);  // its stream ended
      }
    }
  }
  if (due.empty()) return;
  if (!*info) *info = std::make_shared<const SceneInfo>(info_of(scene, controller, mode));
  SceneSnapshot snap = snapshot_of(scene, controller, true, false);
  snap.scene_id = id;
  snap.steps = step;
  snap.info = *info;
  const sim::StepStats& st = scene.last_stats();
  snap.newton_iterations = st.newton_iters;
  snap.pcg_iterations = st.pcg_iters;
  snap.active_contacts = st.contacts;
  snap.intersecting_pairs = st.intersecting_pairs;
  snap.wall_ms = 1e3 * st.seconds;
  for (const auto& sub : due) sub->push(snap);
}

Status JobQueue::subscribe_frames(const std::string& job_id, int every, std::shared_ptr<FrameSubscription>* out,
                                  const std::string& caller) {
  if (every < 1) return Status::InvalidArgument(fmt::format("every must be >= 1 (got {})", every));
  JobRecord rec;
  GD_RETURN_IF_ERROR(info(job_id, &rec, caller));  // unknown or another caller's: NOT_FOUND
  std::lock_guard<std::mutex> lock(mu_);
  auto it = live_.find(job_id);
  if (it != live_.end()) rec = it->second.record;
  if (it == live_.end() || job_finished(rec.status))
    return Status::FailedPrecondition(
        fmt::format("job '{}' has ended ({}); its report has the run's animation (GetReport: animation.npy, "
                    "animation.gif)",
                    job_id, job_state_name(rec.status)));
  auto sub = std::make_shared<FrameSubscription>(every, 1, options_.max_queued_frame_bytes);
  frame_subs_[job_id].push_back(sub);
  *out = std::move(sub);
  return Status::Ok();
}

Status JobQueue::info(const std::string& job_id, JobRecord* out, const std::string& caller) {
  {
    std::lock_guard<std::mutex> lock(mu_);
    auto it = live_.find(job_id);
    if (it != live_.end()) {
      if (!job_visible(it->second.record.owner, caller)) return unknown_job(job_id);
      *out = it->second.record;
      return Status::Ok();
    }
  }
  StoredReport r;
  GD_RETURN_IF_ERROR(store_.get(job_id, &r));
  if (!job_visible(r.job.owner, caller)) return unknown_job(job_id);
  *out = r.job;
  return Status::Ok();
}

Status JobQueue::wait(const std::string& job_id, uint64_t* version, JobRecord* out, int timeout_ms,
                      const std::string& caller) {
  std::unique_lock<std::mutex> lock(mu_);
  auto it = live_.find(job_id);
  if (it == live_.end()) {
    lock.unlock();
    GD_RETURN_IF_ERROR(info(job_id, out, caller));
    *version = 1;
    return Status::Ok();
  }
  if (!job_visible(it->second.record.owner, caller)) return unknown_job(job_id);
  cv_.wait_for(lock, std::chrono::milliseconds(timeout_ms), [&] { return it->second.version != *version; });
  *out = it->second.record;
  *version = it->second.version;
  return Status::Ok();
}

Status JobQueue::report(const std::string& job_id, bool include_files, size_t max_file_bytes, JobReport* out,
                        const std::string& caller) {
  JobRecord live;
  GD_RETURN_IF_ERROR(info(job_id, &live, caller));
  if (!job_finished(live.status))
    return Status::FailedPrecondition(fmt::format("job '{}' is {} ({:.0f}% done); wait for it to finish (WatchJob)",
                                                  job_id, job_state_name(live.status), 100 * live.progress));
  StoredReport r;
  GD_RETURN_IF_ERROR(store_.get(job_id, &r));
  out->job = r.job;
  out->summary_json = r.summary_json;
  out->file_names = r.files;
  out->files.clear();
  if (!include_files) return Status::Ok();
  const fs::path dir = fs::path(options_.data_dir) / "jobs" / job_id;
  size_t total = 0;
  for (const std::string& name : r.files) {
    if (name.rfind("frames/", 0) == 0) continue;
    std::error_code ec;
    const auto size = fs::file_size(dir / name, ec);
    if (ec) continue;  // removed by hand since
    if (total + size > max_file_bytes) {
      gd::log().warn("job {}: file {} left out of the report ({} bytes over the {} byte cap)", job_id, name,
                     total + size, max_file_bytes);
      continue;
    }
    std::ifstream f(dir / name, std::ios::binary);
    std::ostringstream ss;
    ss << f.rdbuf();
    total += size;
    out->files.emplace_back(name, ss.str());
  }
  return Status::Ok();
}

Status JobQueue::list(int limit, int offset, std::vector<JobRecord>* out, int* total, const std::string& caller) {
  if (limit < 0 || offset < 0) return Status::InvalidArgument("limit and offset must be >= 0");
  if (limit == 0) limit = 100;
  if (limit > 10000) return Status::InvalidArgument("limit must be at most 10000");
  GD_RETURN_IF_ERROR(store_.list(limit, offset, out, total, caller));
  std::lock_guard<std::mutex> lock(mu_);
  for (JobRecord& r : *out) {  // live progress of this process's jobs
    auto it = live_.find(r.job_id);
    if (it != live_.end()) {
      r.progress = it->second.record.progress;
      r.sim_time = it->second.record.sim_time;
      r.end_time = it->second.record.end_time;
      r.status = it->second.record.status;
      r.message = it->second.record.message;
      r.finished_at = it->second.record.finished_at;
    }
  }
  return Status::Ok();
}

void JobQueue::drain(double grace_seconds) {
  std::vector<std::string> dropped;
  {
    std::unique_lock<std::mutex> lock(mu_);
    if (!draining_) {
      draining_ = true;
      dropped.assign(queue_.begin(), queue_.end());
      queue_.clear();
      gd::log().info("jobs: draining ({} running, {} queued dropped)", running_, dropped.size());
    }
  }
  cv_.notify_all();
  for (const std::string& id : dropped) {
    update(id, [&](JobRecord& r) {
      r.status = JobState::kInterrupted;
      r.message = kInterruptedQueuedMessage;
      r.finished_at = now_iso8601();
    });
    store_.set_status(id, JobState::kInterrupted, kInterruptedQueuedMessage);
  }
  {
    std::unique_lock<std::mutex> lock(mu_);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(std::max(0.0, grace_seconds));
    if (!cv_.wait_until(lock, deadline, [this] { return running_ == 0; })) {
      gd::log().warn("jobs: {} still running after the {} s grace period; interrupting them", running_, grace_seconds);
      cancel_ = true;
    }
  }
  for (std::thread& t : workers_)
    if (t.joinable()) t.join();
}

}  // namespace gd::service
