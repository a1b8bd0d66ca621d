#include "metrics/capture.h"

#include <spdlog/fmt/fmt.h>
#include <yaml-cpp/yaml.h>

#include <Eigen/LU>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "sim/demand.h"
#include "sim/log.h"

namespace gd::metrics {
namespace {

namespace fs = std::filesystem;
using sim::InputError;

constexpr const char* kFramePrefix = "pointcloud_";
constexpr const char* kFrameSuffix = "_segmented.pcd";
constexpr const char* kCalibrationFile = "calibration/world_to_camera_transform.json";

/// "01" -> "1", "1" -> "1", "a" -> "a": sample keys compare as numbers when they are numbers.
std::string normalize_sample(const std::string& s) {
  if (s.empty() || !std::all_of(s.begin(), s.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return s;
  const size_t nz = s.find_first_not_of('0');
  return nz == std::string::npos ? "0" : s.substr(nz);
}

double yaml_double(const YAML::Node& n, const char* key, const std::string& where, double fallback,
                   bool required) {
  const YAML::Node v = n[key];
  if (!v) {
    if (required)
      throw InputError(fmt::format("experiment library entry {} lacks '{}'", where, key));
    return fallback;
  }
  try {
    return v.as<double>();
  } catch (const YAML::Exception&) {
    throw InputError(fmt::format("experiment library entry {}: '{}' is not a number", where, key));
  }
}

/// The directory's own name, ignoring a trailing separator.
std::string dir_name(const std::string& dir) {
  fs::path p = fs::path(dir).lexically_normal();
  if (p.filename().empty()) p = p.parent_path();
  return p.filename().string();
}

EvalWindow window_from_json(const nlohmann::json& j, const std::string& where) {
  EvalWindow w;
  auto get = [&](const char* key, double& out) {
    if (!j.contains(key)) return;
    if (!j[key].is_number())
      throw InputError(fmt::format("{}: evaluate.{} must be a number", where, key));
    out = j[key].get<double>();
  };
  get("start_record_time", w.start_record_time);
  get("end_record_time", w.end_record_time);
  get("start_calculate_time", w.start_calculate_time);
  get("end_calculate_time", w.end_calculate_time);
  return w;
}

void check_window(const EvalWindow& w, const std::string& where) {
  if (!(w.start_record_time <= w.end_record_time) ||
      !(w.start_calculate_time <= w.end_calculate_time))
    throw InputError(fmt::format(
        "{}: evaluation window has start after end (record [{}, {}], calculate [{}, {}])", where,
        w.start_record_time, w.end_record_time, w.start_calculate_time, w.end_calculate_time));
}

Eigen::Matrix4d read_calibration(const std::string& path) {
  std::ifstream f(path);
  if (!f) throw InputError(fmt::format("cannot open calibration file '{}'", path));
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(f);
  } catch (const nlohmann::json::exception& e) {
    throw InputError(fmt::format("calibration file '{}' is not valid JSON: {}", path, e.what()));
  }
  Eigen::Matrix4d T;
  const bool shape_ok = j.is_array() && j.size() == 4 &&
                        std::all_of(j.begin(), j.end(), [](const nlohmann::json& r) {
                          return r.is_array() && r.size() == 4 &&
                                 std::all_of(r.begin(), r.end(),
                                             [](const nlohmann::json& v) { return v.is_number(); });
                        });
  if (!shape_ok)
    throw InputError(fmt::format(
        "calibration file '{}' must hold a bare 4x4 nested list of numbers (row-major "
        "world-to-camera transform)",
        path));
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) T(r, c) = j[r][c].get<double>();
  if (!T.allFinite() || std::abs(T.determinant()) < 1e-12)
    throw InputError(fmt::format("calibration file '{}' holds a singular or non-finite matrix", path));
  return T;
}

}  // namespace

bool in_record_window(const EvalWindow& w, double t) {
  return w.start_record_time <= t && t <= w.end_record_time;
}
bool in_calculate_window(const EvalWindow& w, double t) {
  return w.start_calculate_time <= t && t <= w.end_calculate_time;
}

std::vector<ExperimentEntry> load_experiment_library(const std::string& path) {
  YAML::Node root;
  try {
    root = YAML::LoadFile(path);
  } catch (const YAML::BadFile&) {
    throw InputError(fmt::format("cannot open experiment library '{}'", path));
  } catch (const YAML::Exception& e) {
    throw InputError(fmt::format("experiment library '{}' is not valid YAML: {}", path, e.what()));
  }
  const YAML::Node exps = root["experiments"];
  if (!exps || !exps.IsMap())
    throw InputError(fmt::format("experiment library '{}' has no 'experiments' map", path));
  std::vector<ExperimentEntry> out;
  for (const auto& g : exps) {
    if (!g.second.IsMap()) continue;
    for (const auto& a : g.second) {
      if (!a.second.IsMap()) continue;
      for (const auto& r : a.second) {
        if (!r.second.IsMap()) continue;
        for (const auto& s : r.second) {
          const YAML::Node e = s.second;
          if (!e.IsMap()) continue;
          ExperimentEntry x;
          x.garment = g.first.as<std::string>();
          x.action = a.first.as<std::string>();
          x.robot = r.first.as<std::string>();
          x.sample = s.first.as<std::string>();
          const std::string where =
              fmt::format("{}.{}.{}.{} in '{}'", x.garment, x.action, x.robot, x.sample, path);
          x.camera_delay = yaml_double(e, "camera_delay", where, 0, true);
          if (e["data_subfolder"]) x.data_subfolder = e["data_subfolder"].as<std::string>();
          if (const YAML::Node ev = e["evaluate"]) {
            x.window.start_record_time = yaml_double(ev, "start_record_time", where, 0, false);
            x.window.end_record_time =
                yaml_double(ev, "end_record_time", where, x.window.end_record_time, false);
            x.window.start_calculate_time = yaml_double(ev, "start_calculate_time", where, 0, false);
            x.window.end_calculate_time =
                yaml_double(ev, "end_calculate_time", where, x.window.end_calculate_time, false);
          }
          out.push_back(std::move(x));
        }
      }
    }
  }
  return out;
}

std::optional<ExperimentEntry> find_experiment_by_subfolder(const std::string& library_path,
                                                            const std::string& key) {
  if (key.empty()) return std::nullopt;
  for (auto& e : load_experiment_library(library_path)) {
    const std::string& s = e.data_subfolder;
    if (s == key || (s.size() > key.size() && s.ends_with(key) && s[s.size() - key.size() - 1] == '/'))
      return e;
  }
  return std::nullopt;
}

std::optional<ExperimentEntry> find_experiment(const std::string& library_path,
                                               const std::string& garment,
                                               const std::string& action,
                                               const std::string& sample,
                                               const std::string& robot) {
  for (auto& e : load_experiment_library(library_path))
    if (e.garment == garment && e.action == action && e.robot == robot &&
        normalize_sample(e.sample) == normalize_sample(sample))
      return e;
  return std::nullopt;
}

std::optional<double> parse_frame_timestamp(const std::string& name) {
  const std::string pre = kFramePrefix, suf = kFrameSuffix;
  if (!name.ends_with(suf)) return std::nullopt;
  // RGBench strips the two affixes with str.replace and parses the rest with float().
  std::string core = name.substr(0, name.size() - suf.size());
  if (core.starts_with(pre)) core = core.substr(pre.size());
  if (core.empty()) return std::nullopt;
  char* end = nullptr;
  const double t = std::strtod(core.c_str(), &end);
  if (end != core.c_str() + core.size() || !std::isfinite(t)) return std::nullopt;
  return t;
}

std::string frame_file_name(double timestamp) {
  return fmt::format("{}{:.6f}{}", kFramePrefix, timestamp, kFrameSuffix);
}

Capture load_capture(const std::string& dir, const CaptureOptions& opt) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw InputError(fmt::format("capture directory '{}' does not exist", dir));
  Capture c;
  c.dir = dir;
  const fs::path root(dir);

  // Frames.
  const fs::path pcds = root / "segment_pcds";
  if (!fs::is_directory(pcds, ec))
    throw InputError(fmt::format("capture '{}' has no segment_pcds/ directory (RGBench layout: "
                                 "segment_pcds/pointcloud_<unix_ts>_segmented.pcd)",
                                 dir));
  size_t unparsed = 0;
  for (const auto& de : fs::directory_iterator(pcds)) {
    const std::string name = de.path().filename().string();
    if (!name.ends_with(kFrameSuffix)) continue;
    const auto ts = parse_frame_timestamp(name);
    if (!ts) {
      ++unparsed;
      gd::log().warn("capture '{}': cannot parse a timestamp from '{}'; frame skipped", dir, name);
      continue;
    }
    c.frames.push_back({*ts, de.path().string()});
  }
  std::sort(c.frames.begin(), c.frames.end(),
            [](const CaptureFrame& a, const CaptureFrame& b) { return a.timestamp < b.timestamp; });
  if (c.frames.empty())
    throw InputError(fmt::format("capture '{}': segment_pcds/ holds no "
                                 "pointcloud_<unix_ts>_segmented.pcd frame{}",
                                 dir, unparsed ? fmt::format(" ({} unparsable names)", unparsed) : ""));

  // Calibration.
  const fs::path calib = root / kCalibrationFile;
  if (fs::exists(calib, ec)) {
    c.world_to_camera = read_calibration(calib.string());
    c.has_calibration = true;
  } else {
    gd::log().warn("capture '{}': no {}; using identity (clouds taken as world frame)", dir,
                   kCalibrationFile);
  }
  c.camera_to_world = c.world_to_camera.inverse();

  // Joints.
  c.left_joints_csv = (root / "joints" / "left_arm_joint_states_and_end_pose.csv").string();
  c.right_joints_csv = (root / "joints" / "right_arm_joint_states_and_end_pose.csv").string();
  c.has_left_joints = fs::is_regular_file(c.left_joints_csv, ec);
  c.has_right_joints = fs::is_regular_file(c.right_joints_csv, ec);

  // capture.json (ours).
  std::optional<nlohmann::json> side;
  const fs::path side_path = root / "capture.json";
  if (fs::exists(side_path, ec)) {
    std::ifstream f(side_path);
    try {
      side = nlohmann::json::parse(f);
    } catch (const nlohmann::json::exception& e) {
      throw InputError(fmt::format("'{}' is not valid JSON: {}", side_path.string(), e.what()));
    }
    if (!side->is_object())
      throw InputError(fmt::format("'{}' must hold a JSON object", side_path.string()));
  }
  auto side_str = [&](const char* key) -> std::optional<std::string> {
    if (!side || !side->contains(key)) return std::nullopt;
    const auto& v = (*side)[key];
    if (v.is_string()) return v.get<std::string>();
    if (v.is_number_integer()) return std::to_string(v.get<long long>());
    throw InputError(fmt::format("'{}': '{}' must be a string", side_path.string(), key));
  };

  // Identity of the capture: options > capture.json.
  c.garment = opt.garment.value_or(side_str("garment").value_or(""));
  c.action = opt.action.value_or(side_str("action").value_or(""));
  c.sample = opt.sample.value_or(side_str("sample").value_or(""));
  c.robot = side_str("robot").value_or(opt.robot);
  c.synthetic = side_str("synthetic").value_or("");

  // Timing, lowest precedence first: experiment library, capture.json, explicit options.
  if (!opt.experiment_library.empty()) {
    std::optional<ExperimentEntry> e;
    if (!c.garment.empty() && !c.action.empty() && !c.sample.empty())
      e = find_experiment(opt.experiment_library, c.garment, c.action, c.sample, c.robot);
    if (!e) e = find_experiment_by_subfolder(opt.experiment_library, dir_name(dir));
    if (e) {
      c.camera_delay = e->camera_delay;
      c.has_camera_delay = true;
      c.window = e->window;
      c.has_window = true;
      if (c.garment.empty()) c.garment = e->garment;
      if (c.action.empty()) c.action = e->action;
      if (c.sample.empty()) c.sample = e->sample;
      gd::log().info("capture '{}': experiment library entry {}.{}.{}.{} (camera_delay {})", dir,
                     e->garment, e->action, e->robot, e->sample, e->camera_delay);
    } else {
      gd::log().warn("capture '{}': no entry in '{}' matches (garment/action/sample '{}/{}/{}' or "
                     "data_subfolder '{}')",
                     dir, opt.experiment_library, c.garment, c.action, c.sample, dir_name(dir));
    }
  }
  if (side) {
    if (side->contains("camera_delay")) {
      if (!(*side)["camera_delay"].is_number())
        throw InputError(fmt::format("'{}': camera_delay must be a number (s)", side_path.string()));
      c.camera_delay = (*side)["camera_delay"].get<double>();
      c.has_camera_delay = true;
    }
    if (side->contains("evaluate")) {
      const auto& ev = (*side)["evaluate"];
      if (!ev.is_object())
        throw InputError(fmt::format("'{}': evaluate must be an object", side_path.string()));
      // Keys absent from capture.json keep the library's value (or the default).
      nlohmann::json merged = {{"start_record_time", c.window.start_record_time},
                               {"start_calculate_time", c.window.start_calculate_time}};
      if (std::isfinite(c.window.end_record_time)) merged["end_record_time"] = c.window.end_record_time;
      if (std::isfinite(c.window.end_calculate_time))
        merged["end_calculate_time"] = c.window.end_calculate_time;
      merged.update(ev);
      c.window = window_from_json(merged, side_path.string());
      c.has_window = true;
    }
  }
  if (opt.camera_delay) {
    c.camera_delay = *opt.camera_delay;
    c.has_camera_delay = true;
  }
  if (opt.window) {
    c.window = *opt.window;
    c.has_window = true;
  }
  if (!std::isfinite(c.camera_delay) || c.camera_delay < 0)
    throw InputError(fmt::format("capture '{}': camera_delay {} must be a finite value >= 0 s", dir,
                                 c.camera_delay));
  check_window(c.window, fmt::format("capture '{}'", dir));
  if (!c.has_camera_delay)
    gd::log().warn("capture '{}': no camera_delay from the experiment library, capture.json or "
                   "options; using 0",
                   dir);
  gd::log().info("capture '{}': {} frames ({:.6f} .. {:.6f}), calibration {}, joints L/R {}/{}",
                 dir, c.frames.size(), c.frames.front().timestamp, c.frames.back().timestamp,
                 c.has_calibration ? "yes" : "identity", c.has_left_joints, c.has_right_joints);
  return c;
}

Cloud frame_in_camera(const Capture& c, size_t i) {
  if (i >= c.frames.size())
    throw InputError(fmt::format("capture '{}' has {} frames; frame {} requested", c.dir,
                                 c.frames.size(), i));
  return load_cloud(c.frames[i].path);
}

Cloud frame_in_world(const Capture& c, size_t i) {
  return transform_cloud(frame_in_camera(c, i), c.camera_to_world);
}

std::string write_capture_frame(const std::string& dir, double timestamp,
                                const Cloud& cloud_in_camera) {
  const fs::path d = fs::path(dir) / "segment_pcds";
  fs::create_directories(d);
  const std::string path = (d / frame_file_name(timestamp)).string();
  save_pcd(path, cloud_in_camera, PcdEncoding::kBinary);
  return path;
}

void write_calibration(const std::string& dir, const Eigen::Matrix4d& T) {
  const fs::path d = fs::path(dir) / "calibration";
  fs::create_directories(d);
  nlohmann::json j = nlohmann::json::array();
  for (int r = 0; r < 4; ++r) j.push_back({T(r, 0), T(r, 1), T(r, 2), T(r, 3)});
  std::ofstream f(d / "world_to_camera_transform.json");
  f << j.dump() << "\n";
  if (!f)
    throw InputError(fmt::format("cannot write '{}'", (d / "world_to_camera_transform.json").string()));
}

void write_capture_json(const std::string& dir, const Capture& meta) {
  nlohmann::json j = nlohmann::json::object();
  if (!meta.garment.empty()) j["garment"] = meta.garment;
  if (!meta.action.empty()) j["action"] = meta.action;
  if (!meta.sample.empty()) j["sample"] = meta.sample;
  if (!meta.robot.empty()) j["robot"] = meta.robot;
  if (!meta.synthetic.empty()) j["synthetic"] = meta.synthetic;
  if (meta.has_camera_delay) j["camera_delay"] = meta.camera_delay;
  if (meta.has_window) {
    nlohmann::json ev = {{"start_record_time", meta.window.start_record_time},
                         {"start_calculate_time", meta.window.start_calculate_time}};
    if (std::isfinite(meta.window.end_record_time)) ev["end_record_time"] = meta.window.end_record_time;
    if (std::isfinite(meta.window.end_calculate_time))
      ev["end_calculate_time"] = meta.window.end_calculate_time;
    j["evaluate"] = ev;
  }
  fs::create_directories(dir);
  std::ofstream f(fs::path(dir) / "capture.json");
  f << j.dump(2) << "\n";
  if (!f) throw InputError(fmt::format("cannot write '{}/capture.json'", dir));
}

double sim_prepare_time(const std::string& action) { return action == "fling" ? 10.0 : 0.0; }

std::vector<ScheduledFrame> evaluation_schedule(const Capture& c, double master_start,
                                                double prepare_time) {
  std::vector<ScheduledFrame> out;
  for (size_t i = 0; i < c.frames.size(); ++i) {
    const double t = c.frames[i].timestamp - master_start;
    if (t < 0) continue;  // RGBench drops frames before the robot data start
    out.push_back({i, t, t + c.camera_delay + prepare_time});
  }
  return out;
}

namespace {

/// `k` entries of `expected` (indices into a schedule of `n` frames) evenly spaced from the first
/// to the last, as a mask over the schedule; the middle one for k = 1.
std::vector<bool> evenly_spaced(const std::vector<size_t>& expected, size_t n, int k) {
  std::vector<bool> mask(n, false);
  if (expected.empty() || k <= 0) return mask;
  if (k == 1 || expected.size() == 1) {
    mask[expected[expected.size() / 2]] = true;
    return mask;
  }
  for (int i = 0; i < k; ++i)
    mask[expected[size_t(std::lround(double(i) * double(expected.size() - 1) / (k - 1)))]] = true;
  return mask;
}

}  // namespace

Cloud resample_cloud(const Cloud& c, size_t n) {
  Cloud out;
  if (c.empty()) return out;
  out.reserve(n);
  for (size_t i = 0; i < n; ++i) out.push_back(c[i * c.size() / n]);
  return out;
}

EvalResult run_evaluation(const Capture& c, const EvalOptions& opt,
                          const std::function<SimSample(double)>& step_to) {
  const Eigen::Matrix4d cam_to_world =
      opt.world_to_camera ? Eigen::Matrix4d(opt.world_to_camera->inverse()) : c.camera_to_world;
  const auto schedule = evaluation_schedule(c, opt.master_start_time, opt.prepare_time);
  if (schedule.empty())
    gd::log().warn("capture '{}': no frame at or after master start time {:.6f}", c.dir,
                   opt.master_start_time);

  // Frames to keep for plots: evenly spaced among those expected in the record window.
  std::vector<size_t> expected;
  for (size_t j = 0; j < schedule.size(); ++j)
    if (in_record_window(c.window, schedule[j].compensated - opt.prepare_time)) expected.push_back(j);
  const std::vector<bool> keep = evenly_spaced(expected, schedule.size(), opt.keep_frames);
  const std::vector<bool> animate = evenly_spaced(expected, schedule.size(), opt.animation_frames);

  EvalResult res;
  for (size_t j = 0; j < schedule.size(); ++j) {
    const ScheduledFrame& s = schedule[j];
    SimSample sample = step_to(s.compensated);
    if (sample.vertices.empty()) {
      gd::log().warn("frame {} (t {:.4f} s): the simulator returned no vertices; skipped", s.frame,
                     s.target_time);
      continue;
    }
    const double sim_time = sample.sim_time - opt.prepare_time;
    if (!in_record_window(c.window, sim_time)) continue;
    Cloud real = transform_cloud(frame_in_camera(c, s.frame), cam_to_world);
    if (real.empty()) {
      gd::log().warn("frame '{}' has no points; skipped", c.frames[s.frame].path);
      continue;
    }
    FrameRow row;
    row.m = compute_metrics(sample.vertices, real);
    row.sim_time = sim_time;
    row.target_time = s.target_time;
    row.frame = s.frame;
    if (animate[j])
      res.animation.push_back({res.rows.size(), sim_time, resample_cloud(sample.vertices, opt.animation_points),
                               resample_cloud(real, opt.animation_points)});
    if (keep[j]) res.kept.push_back({res.rows.size(), sim_time, std::move(sample.vertices), std::move(real)});
    res.rows.push_back(row);
  }
  gd::log().info("capture '{}': {} of {} scheduled frames compared", c.dir, res.rows.size(),
                 schedule.size());
  return res;
}

}  // namespace gd::metrics
