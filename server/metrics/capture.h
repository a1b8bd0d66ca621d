#pragma once
/// \file
/// RGBench captures (Hu et al., "Real Garment Benchmark (RGBench)", AAAI 2026; data CC-BY-4.0):
/// one directory per recorded manipulation, laid out as
///
///     <capture>/segment_pcds/pointcloud_<unix_ts>_segmented.pcd   (camera frame, metres)
///     <capture>/calibration/world_to_camera_transform.json       (bare 4x4 nested list)
///     <capture>/joints/{left,right}_arm_joint_states_and_end_pose.csv
///     <capture>/capture.json                                      (optional, ours; see below)
///
/// plus the per-capture timing (camera delay, evaluation window) from RGBench's
/// configs/experiment_library.yaml. Frames are listed at load time and read lazily. The
/// evaluation loop of RGBench's scripts/run_benchmark.py is in run_evaluation(). See
/// docs/metrics.md.
///
/// capture.json (all keys optional): {"garment": "blue_dress", "action": "fling", "sample": "01",
/// "robot": "piper", "camera_delay": 0.05988, "evaluate": {"start_record_time": 0,
/// "end_record_time": 4, "start_calculate_time": 0, "end_calculate_time": 3.14}}.

#include <Eigen/Core>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "metrics/cloud_io.h"
#include "metrics/cloud_metrics.h"

namespace gd::metrics {

/// RGBench's `evaluate` block, in seconds of (normalised) sim time. Frames are compared only
/// while start_record_time <= sim_time <= end_record_time; the summary (mean/std) uses only
/// rows with start_calculate_time <= sim_time <= end_calculate_time.
struct EvalWindow {
  double start_record_time = 0;
  double end_record_time = std::numeric_limits<double>::infinity();
  double start_calculate_time = 0;
  double end_calculate_time = std::numeric_limits<double>::infinity();
};

/// True when start_record_time <= t <= end_record_time.
bool in_record_window(const EvalWindow& w, double sim_time);
/// True when start_calculate_time <= t <= end_calculate_time.
bool in_calculate_window(const EvalWindow& w, double sim_time);

/// One entry of RGBench's experiment_library.yaml
/// (experiments -> garment -> action -> robot -> sample -> {...}).
struct ExperimentEntry {
  std::string garment, action, robot, sample;  ///< e.g. blue_dress, fling, piper, "01"
  std::string data_subfolder;                  ///< e.g. blue_dress/blue_dress_fling_2025-07-27-21-35-28
  double camera_delay = 0;                     ///< s
  EvalWindow window;
};

/// Every entry of an experiment_library.yaml, in file order. Throws InputError naming the file
/// when it is missing or malformed.
std::vector<ExperimentEntry> load_experiment_library(const std::string& path);

/// The entry whose data_subfolder equals `key` or ends with "/" + `key` (so a capture
/// directory's name or its garment/name path both match); nullopt if none.
std::optional<ExperimentEntry> find_experiment_by_subfolder(const std::string& library_path,
                                                            const std::string& key);
/// The entry experiments.<garment>.<action>.<robot>.<sample>; `sample` may be "1" or "01".
std::optional<ExperimentEntry> find_experiment(const std::string& library_path,
                                               const std::string& garment,
                                               const std::string& action,
                                               const std::string& sample,
                                               const std::string& robot = "piper");

/// One real frame: its file and its absolute Unix timestamp (from the file name).
struct CaptureFrame {
  double timestamp = 0;
  std::string path;
};

/// Where the timing of a capture should come from, besides its capture.json. Explicit values
/// here override capture.json, which overrides the experiment library.
struct CaptureOptions {
  std::string experiment_library;  ///< path of experiment_library.yaml; empty = not used
  std::optional<std::string> garment, action, sample;  ///< library key (else: match the dir name)
  std::string robot = "piper";
  std::optional<double> camera_delay;
  std::optional<EvalWindow> window;
};

/// A capture directory as listed by load_capture (no point cloud is read yet).
struct Capture {
  std::string dir;                   ///< as given
  std::vector<CaptureFrame> frames;  ///< every segment_pcds/*_segmented.pcd, by timestamp
  Eigen::Matrix4d world_to_camera = Eigen::Matrix4d::Identity();
  Eigen::Matrix4d camera_to_world = Eigen::Matrix4d::Identity();  ///< inverse of the above
  bool has_calibration = false;  ///< false: the file was missing and identity is used
  std::string left_joints_csv, right_joints_csv;  ///< paths (parsed by server/tasks)
  bool has_left_joints = false, has_right_joints = false;
  std::string garment, action, robot = "piper", sample;  ///< empty when unknown
  /// Empty for a real capture; for one a simulator made (capture.json "synthetic"), what made it,
  /// e.g. "GarmentDynamics, tshirt grasp at 680 vertices". Reports say so beside the paper's
  /// rows, which are measured against real captures.
  std::string synthetic;
  double camera_delay = 0;        ///< s (RGBench camera.system_delay_time)
  bool has_camera_delay = false;  ///< false: no source gave one; 0 is used
  EvalWindow window;
  bool has_window = false;  ///< false: no source gave one; the whole run is used
};

/// Parses the timestamp of "pointcloud_<ts>_segmented.pcd"; nullopt for other names.
std::optional<double> parse_frame_timestamp(const std::string& file_name);
/// "pointcloud_<ts>_segmented.pcd" with <ts> printed with 6 decimals.
std::string frame_file_name(double timestamp);

/// Lists a capture directory. Throws InputError if `dir` is not a directory, has no
/// segment_pcds/ with at least one frame, or has a malformed calibration or capture.json;
/// a missing calibration gives identity and a warning.
Capture load_capture(const std::string& dir, const CaptureOptions& options = {});

/// Reads frame i (camera frame, as stored; NaN points dropped).
Cloud frame_in_camera(const Capture& c, size_t i);
/// Reads frame i and maps it to the world frame with camera_to_world (RGBench's
/// load_target_pcds).
Cloud frame_in_world(const Capture& c, size_t i);

/// Writes `cloud_in_camera` as <dir>/segment_pcds/pointcloud_<ts>_segmented.pcd (binary PCD),
/// creating directories; returns the path.
std::string write_capture_frame(const std::string& dir, double timestamp,
                                const Cloud& cloud_in_camera);
/// Writes <dir>/calibration/world_to_camera_transform.json as a bare 4x4 nested list.
void write_calibration(const std::string& dir, const Eigen::Matrix4d& world_to_camera);
/// Writes <dir>/capture.json from the capture's garment/action/sample/robot, camera delay and
/// window (only the fields marked present).
void write_capture_json(const std::string& dir, const Capture& meta);

// ---------------------------------------------------------------------------------------------
// The evaluation loop of RGBench's scripts/run_benchmark.py.

/// RGBench's sim_prepare_time: fling_prepare_time + fling_wait_time (5 s + 5 s in its
/// main.yaml) for "fling", else 0.
double sim_prepare_time(const std::string& action);

/// One real frame in the evaluation schedule.
struct ScheduledFrame {
  size_t frame = 0;          ///< index into Capture::frames
  double target_time = 0;    ///< timestamp - master_start (>= 0)
  double compensated = 0;    ///< target_time + camera_delay + sim_prepare_time: step the sim here
};

/// Frames with timestamp >= master_start_time (the earliest first `time` of the two joints
/// CSVs), in time order, with their compensated sim times.
std::vector<ScheduledFrame> evaluation_schedule(const Capture& c, double master_start_time,
                                                double prepare_time);

/// The simulator's answer after stepping to a compensated time.
struct SimSample {
  Cloud vertices;       ///< all cloth vertices, world frame, index order
  double sim_time = 0;  ///< the simulator's current time (may overshoot the target by <= 1 dt)
};

/// One row of metrics.csv.
struct FrameRow {
  Metrics m;
  double sim_time = 0;     ///< simulator time - sim_prepare_time
  double target_time = 0;  ///< real frame time - master_start_time
  size_t frame = 0;        ///< index into Capture::frames (not written to metrics.csv)
};

/// A pair of clouds kept for the report's frame plots.
struct FramePair {
  size_t row = 0;  ///< index into the returned rows
  double sim_time = 0;
  Cloud sim, real;  ///< world frame
};

struct EvalOptions {
  double master_start_time = 0;  ///< absolute Unix s of sim time 0
  double prepare_time = 0;       ///< sim_prepare_time(action)
  int keep_frames = 4;           ///< how many evenly spaced (sim, real) pairs to keep for plots
  /// How many evenly spaced (sim, real) pairs to keep for the report's animation, each cloud
  /// resampled to exactly animation_points points (evenly by index; repeated when it has fewer).
  int animation_frames = 0;
  int animation_points = 3000;
  /// Overrides capture.world_to_camera (e.g. after refine_world_to_camera).
  std::optional<Eigen::Matrix4d> world_to_camera;
};

struct EvalResult {
  std::vector<FrameRow> rows;
  std::vector<FramePair> kept;
  std::vector<FramePair> animation;  ///< EvalOptions::animation_frames pairs, resampled
};

/// `n` points of `c` evenly by index (point floor(i |c| / n)), repeating points when |c| < n;
/// empty when c is.
Cloud resample_cloud(const Cloud& c, size_t n);

/// RGBench's loop: for each scheduled frame in order, `step_to(compensated)` advances the
/// simulator (never backwards) and returns its vertices and time; sim_time = time -
/// prepare_time; if start_record_time <= sim_time <= end_record_time the real frame is loaded,
/// put in the world frame and compared. A sample with no vertices is skipped with a warning.
EvalResult run_evaluation(const Capture& c, const EvalOptions& options,
                          const std::function<SimSample(double compensated_time)>& step_to);

}  // namespace gd::metrics
