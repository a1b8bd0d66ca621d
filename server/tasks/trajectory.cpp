#include "tasks/trajectory.h"

#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "sim/demand.h"

namespace gd::tasks {

using sim::InputError;
using nlohmann::json;

namespace {

constexpr double kQuatNormTol = 1e-3;

std::string trim(const std::string& s) {
  size_t b = 0, e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1]))) --e;
  return s.substr(b, e - b);
}

std::vector<std::string> split_csv(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  for (char c : line) {
    if (c == ',') {
      out.push_back(trim(cur));
      cur.clear();
    } else {
      cur += c;
    }
  }
  out.push_back(trim(cur));
  return out;
}

/// A whole field as a number; anything else (empty, trailing junk) is an error. "nan"/"inf"
/// parse, and check_sample rejects them with the column's meaning.
double parse_number(const std::string& field, const std::string& where, const std::string& column) {
  if (field.empty()) throw InputError(fmt::format("{}: column '{}' is empty", where, column));
  const char* begin = field.c_str();
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(begin, &end);
  if (end == begin || *end != '\0')
    throw InputError(fmt::format("{}: column '{}' is not a number: '{}'", where, column, field));
  if (errno == ERANGE && std::isinf(v))
    throw InputError(fmt::format("{}: column '{}' is out of range: '{}'", where, column, field));
  return v;
}

std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(fmt::format("cannot open trajectory file '{}'", path));
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw InputError(fmt::format("cannot write trajectory file '{}'", path));
  out << text;
  if (!out) throw InputError(fmt::format("error while writing trajectory file '{}'", path));
}

/// Lines of a text with their 1-based numbers; '\r' of CRLF files removed.
std::vector<std::pair<int, std::string>> lines_of(const std::string& text) {
  std::vector<std::pair<int, std::string>> out;
  std::istringstream in(text);
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    out.emplace_back(n, line);
  }
  return out;
}

/// Column name -> index from a header line; duplicate names are an error.
std::map<std::string, size_t> header_index(const std::vector<std::string>& names, const std::string& where) {
  std::map<std::string, size_t> idx;
  for (size_t k = 0; k < names.size(); ++k) {
    if (names[k].empty()) throw InputError(fmt::format("{}: header column {} has no name", where, k + 1));
    if (!idx.emplace(names[k], k).second)
      throw InputError(fmt::format("{}: header names column '{}' twice", where, names[k]));
  }
  return idx;
}

void require_columns(const std::map<std::string, size_t>& idx, const std::vector<std::string>& required,
                     const std::string& where) {
  std::vector<std::string> missing;
  for (const auto& c : required)
    if (!idx.count(c)) missing.push_back(c);
  if (!missing.empty())
    throw InputError(fmt::format("{}: missing column(s) {} in the header (expected columns: {})", where,
                                 fmt::join(missing, ", "), fmt::join(required, ",")));
}

/// Formats a double so that reading it back gives the same value.
std::string num(double v) { return fmt::format("{}", v); }

/// Builds an ArmTrajectory from rows whose labels name their origin (file:line).
ArmTrajectory build_arm(const std::vector<ArmSample>& samples, const std::vector<std::string>& labels) {
  for (size_t k = 0; k < samples.size(); ++k) {
    check_sample(samples[k], labels[k]);
    if (k > 0 && !(samples[k].t > samples[k - 1].t))
      throw InputError(fmt::format("{}: time {} does not increase (previous sample of this arm, {}, has time {})",
                                   labels[k], num(samples[k].t), labels[k - 1], num(samples[k - 1].t)));
  }
  return ArmTrajectory(samples);
}

}  // namespace

// --- samples and interpolation ------------------------------------------------------------------

void check_sample(const ArmSample& s, const std::string& where) {
  if (!std::isfinite(s.t)) throw InputError(fmt::format("{}: time is not finite", where));
  if (!s.position.allFinite()) throw InputError(fmt::format("{}: position is not finite", where));
  if (!s.orientation.coeffs().allFinite()) throw InputError(fmt::format("{}: orientation is not finite", where));
  const double n = s.orientation.norm();
  if (std::abs(n - 1.0) > kQuatNormTol)
    throw InputError(fmt::format("{}: orientation quaternion (w,x,y,z) = ({}, {}, {}, {}) has norm {:.6g}, not 1", where,
                                 s.orientation.w(), s.orientation.x(), s.orientation.y(), s.orientation.z(), n));
  if (!std::isfinite(s.gripper)) throw InputError(fmt::format("{}: gripper opening is not finite", where));
  if (s.gripper < 0) throw InputError(fmt::format("{}: gripper opening {} m is negative", where, s.gripper));
}

ArmTrajectory::ArmTrajectory(std::vector<ArmSample> samples, const std::string& what) : samples_(std::move(samples)) {
  for (size_t k = 0; k < samples_.size(); ++k) {
    const std::string where = fmt::format("{} sample {} (t={})", what, k, num(samples_[k].t));
    check_sample(samples_[k], where);
    if (k > 0 && !(samples_[k].t > samples_[k - 1].t))
      throw InputError(fmt::format("{}: times must increase strictly (previous sample has t={})", where,
                                   num(samples_[k - 1].t)));
    samples_[k].orientation.normalize();
  }
}

void ArmTrajectory::append(ArmSample s, const std::string& what) {
  const std::string where = fmt::format("{} sample {} (t={})", what, samples_.size(), num(s.t));
  check_sample(s, where);
  if (!samples_.empty() && !(s.t > samples_.back().t))
    throw InputError(fmt::format("{}: times must increase strictly (previous sample has t={})", where,
                                 num(samples_.back().t)));
  s.orientation.normalize();
  samples_.push_back(s);
}

double ArmTrajectory::start_time() const {
  if (samples_.empty()) throw InputError("trajectory has no samples");
  return samples_.front().t;
}

double ArmTrajectory::end_time() const {
  if (samples_.empty()) throw InputError("trajectory has no samples");
  return samples_.back().t;
}

ArmSample ArmTrajectory::sample(double t) const {
  if (samples_.empty()) throw InputError("cannot sample a trajectory without samples");
  if (!std::isfinite(t)) throw InputError("trajectory sampled at a non-finite time");
  ArmSample out;
  if (t <= samples_.front().t) {
    out = samples_.front();
  } else if (t >= samples_.back().t) {
    out = samples_.back();
  } else {
    const auto it = std::upper_bound(samples_.begin(), samples_.end(), t,
                                     [](double v, const ArmSample& s) { return v < s.t; });
    const ArmSample& b = *it;
    const ArmSample& a = *(it - 1);
    const double u = (t - a.t) / (b.t - a.t);
    out.position = a.position + u * (b.position - a.position);
    out.orientation = a.orientation.slerp(u, b.orientation).normalized();
    out.gripper = a.gripper + u * (b.gripper - a.gripper);
    if (!a.joints.empty() && a.joints.size() == b.joints.size()) {
      out.joints.resize(a.joints.size());
      for (size_t k = 0; k < a.joints.size(); ++k) out.joints[k] = a.joints[k] + u * (b.joints[k] - a.joints[k]);
    }
  }
  out.t = t;
  return out;
}

Eigen::Isometry3d ArmTrajectory::pose(double t) const {
  const ArmSample s = sample(t);
  return make_pose(s.position, s.orientation);
}

double DualArmTrajectory::end_time() const {
  double e = 0;
  bool any = false;
  for (const ArmTrajectory* a : {&left, &right})
    if (!a->empty()) {
      e = any ? std::max(e, a->end_time()) : a->end_time();
      any = true;
    }
  return e;
}

// --- our CSV ------------------------------------------------------------------------------------

namespace {
const std::vector<std::string> kCsvColumns{"time", "arm", "x", "y", "z", "qw", "qx", "qy", "qz", "gripper"};
}

DualArmTrajectory parse_trajectory_csv(const std::string& text, const std::string& source) {
  DualArmTrajectory out;
  std::map<std::string, size_t> idx;
  bool have_header = false;
  std::vector<ArmSample> rows[2];
  std::vector<std::string> labels[2];
  for (const auto& [n, raw] : lines_of(text)) {
    const std::string line = trim(raw);
    const std::string where = fmt::format("{}:{}", source, n);
    if (line.empty()) continue;
    if (line[0] == '#') {
      std::string body = trim(line.substr(1));
      const std::string key = "master_start_time";
      if (body.rfind(key, 0) == 0) {
        body = trim(body.substr(key.size()));
        if (body.empty() || (body[0] != '=' && body[0] != ':'))
          throw InputError(fmt::format("{}: write the comment as '# master_start_time = <seconds>'", where));
        out.master_start_time = parse_number(trim(body.substr(1)), where, "master_start_time");
        if (!std::isfinite(out.master_start_time))
          throw InputError(fmt::format("{}: master_start_time is not finite", where));
      }
      continue;
    }
    const std::vector<std::string> fields = split_csv(line);
    if (!have_header) {
      idx = header_index(fields, where);
      require_columns(idx, kCsvColumns, where);
      for (const auto& [name, k] : idx)
        if (std::find(kCsvColumns.begin(), kCsvColumns.end(), name) == kCsvColumns.end())
          throw InputError(fmt::format("{}: unknown column '{}' (expected columns: {})", where, name,
                                       fmt::join(kCsvColumns, ",")));
      have_header = true;
      continue;
    }
    if (fields.size() != idx.size())
      throw InputError(fmt::format("{}: expected {} fields, found {}", where, idx.size(), fields.size()));
    auto get = [&](const char* c) { return parse_number(fields[idx.at(c)], where, c); };
    const std::string arm = fields[idx.at("arm")];
    int a;
    if (arm == "left") {
      a = 0;
    } else if (arm == "right") {
      a = 1;
    } else {
      throw InputError(fmt::format("{}: column 'arm' must be 'left' or 'right', not '{}'", where, arm));
    }
    ArmSample s;
    s.t = get("time");
    s.position = Vec3(get("x"), get("y"), get("z"));
    s.orientation = quat_from_wxyz(get("qw"), get("qx"), get("qy"), get("qz"));
    s.gripper = get("gripper");
    rows[a].push_back(s);
    labels[a].push_back(where + fmt::format(" ({} arm)", arm));
  }
  if (!have_header)
    throw InputError(fmt::format("{}: no header line (expected: {})", source, fmt::join(kCsvColumns, ",")));
  if (rows[0].empty() && rows[1].empty()) throw InputError(fmt::format("{}: no samples after the header", source));
  out.left = build_arm(rows[0], labels[0]);
  out.right = build_arm(rows[1], labels[1]);
  return out;
}

std::string format_trajectory_csv(const DualArmTrajectory& traj) {
  std::string s = fmt::format("# master_start_time = {}\n{}\n", num(traj.master_start_time), fmt::join(kCsvColumns, ","));
  for (Arm a : {Arm::kLeft, Arm::kRight})
    for (const ArmSample& p : traj.arm(a).samples())
      s += fmt::format("{},{},{},{},{},{},{},{},{},{}\n", num(p.t), arm_name(a), num(p.position.x()),
                       num(p.position.y()), num(p.position.z()), num(p.orientation.w()), num(p.orientation.x()),
                       num(p.orientation.y()), num(p.orientation.z()), num(p.gripper));
  return s;
}

DualArmTrajectory read_trajectory_csv(const std::string& path) { return parse_trajectory_csv(read_text(path), path); }

void write_trajectory_csv(const std::string& path, const DualArmTrajectory& traj) {
  write_text(path, format_trajectory_csv(traj));
}

// --- our JSON -----------------------------------------------------------------------------------

namespace {

double json_number(const json& j, const char* key, const std::string& where) {
  if (!j.contains(key)) throw InputError(fmt::format("{}: missing field '{}'", where, key));
  if (!j[key].is_number()) throw InputError(fmt::format("{}: field '{}' must be a number", where, key));
  return j[key].get<double>();
}

std::vector<double> json_array(const json& j, const char* key, size_t n, const std::string& where) {
  if (!j.contains(key)) throw InputError(fmt::format("{}: missing field '{}'", where, key));
  const json& v = j[key];
  if (!v.is_array() || v.size() != n)
    throw InputError(fmt::format("{}: field '{}' must be an array of {} numbers", where, key, n));
  std::vector<double> out;
  for (const json& e : v) {
    if (!e.is_number()) throw InputError(fmt::format("{}: field '{}' must be an array of {} numbers", where, key, n));
    out.push_back(e.get<double>());
  }
  return out;
}

}  // namespace

DualArmTrajectory trajectory_from_json(const json& j, const std::string& source) {
  if (!j.is_object()) throw InputError(fmt::format("{}: a trajectory must be a JSON object", source));
  if (j.contains("format") && j["format"] != "gd-trajectory")
    throw InputError(fmt::format("{}: field 'format' must be \"gd-trajectory\"", source));
  if (j.contains("version") && j["version"] != 1)
    throw InputError(fmt::format("{}: unsupported version {} (this reader knows version 1)", source, j["version"].dump()));
  static const std::vector<std::string> keys{"format", "version", "frame", "master_start_time", "left", "right"};
  for (const auto& [k, v] : j.items())
    if (std::find(keys.begin(), keys.end(), k) == keys.end())
      throw InputError(fmt::format("{}: unknown field '{}' (expected: {})", source, k, fmt::join(keys, ", ")));
  if (j.contains("frame") && j["frame"] != "world")
    throw InputError(fmt::format("{}: field 'frame' must be \"world\" (positions are in the world frame)", source));
  DualArmTrajectory out;
  if (j.contains("master_start_time")) {
    out.master_start_time = json_number(j, "master_start_time", source);
    if (!std::isfinite(out.master_start_time))
      throw InputError(fmt::format("{}: master_start_time is not finite", source));
  }
  if (!j.contains("left") && !j.contains("right"))
    throw InputError(fmt::format("{}: needs a 'left' and/or 'right' array of samples", source));
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    const char* name = arm_name(a);
    if (!j.contains(name)) continue;
    const json& arr = j[name];
    if (!arr.is_array()) throw InputError(fmt::format("{}: field '{}' must be an array of samples", source, name));
    std::vector<ArmSample> rows;
    std::vector<std::string> labels;
    for (size_t k = 0; k < arr.size(); ++k) {
      const std::string where = fmt::format("{}: {}[{}]", source, name, k);
      const json& e = arr[k];
      if (!e.is_object()) throw InputError(fmt::format("{}: a sample must be an object", where));
      for (const auto& [key, v] : e.items())
        if (key != "t" && key != "position" && key != "quat_wxyz" && key != "gripper" && key != "joints")
          throw InputError(
              fmt::format("{}: unknown field '{}' (expected t, position, quat_wxyz, gripper, joints)", where, key));
      ArmSample s;
      s.t = json_number(e, "t", where);
      const auto p = json_array(e, "position", 3, where);
      s.position = Vec3(p[0], p[1], p[2]);
      const auto q = json_array(e, "quat_wxyz", 4, where);
      s.orientation = quat_from_wxyz(q[0], q[1], q[2], q[3]);
      s.gripper = json_number(e, "gripper", where);
      if (e.contains("joints")) {  // robot mode's joint angles (optional)
        const json& jv = e["joints"];
        if (!jv.is_array() || jv.empty())
          throw InputError(fmt::format("{}: field 'joints' must be a non-empty array of numbers", where));
        s.joints = json_array(e, "joints", jv.size(), where);
      }
      rows.push_back(s);
      labels.push_back(where);
    }
    out.arm(a) = build_arm(rows, labels);
  }
  return out;
}

json trajectory_to_json(const DualArmTrajectory& traj) {
  json j;
  j["format"] = "gd-trajectory";
  j["version"] = 1;
  j["frame"] = "world";
  j["master_start_time"] = traj.master_start_time;
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    json arr = json::array();
    for (const ArmSample& s : traj.arm(a).samples()) {
      const auto q = quat_to_wxyz(s.orientation);
      json e = {{"t", s.t},
                {"position", {s.position.x(), s.position.y(), s.position.z()}},
                {"quat_wxyz", {q[0], q[1], q[2], q[3]}},
                {"gripper", s.gripper}};
      if (!s.joints.empty()) e["joints"] = s.joints;
      arr.push_back(std::move(e));
    }
    j[arm_name(a)] = std::move(arr);
  }
  return j;
}

DualArmTrajectory read_trajectory_json(const std::string& path) {
  json j;
  try {
    j = json::parse(read_text(path));
  } catch (const json::parse_error& e) {
    throw InputError(fmt::format("{}: not valid JSON: {}", path, e.what()));
  }
  return trajectory_from_json(j, path);
}

void write_trajectory_json(const std::string& path, const DualArmTrajectory& traj) {
  write_text(path, trajectory_to_json(traj).dump(1) + "\n");
}

DualArmTrajectory read_trajectory(const std::string& path) {
  const std::string ext = std::filesystem::path(path).extension().string();
  if (ext == ".csv") return read_trajectory_csv(path);
  if (ext == ".json") return read_trajectory_json(path);
  throw InputError(fmt::format("trajectory file '{}': unknown extension '{}' (use .csv or .json)", path, ext));
}

// --- RGBench joints CSVs --------------------------------------------------------------------------

namespace {

const std::vector<std::string> kRgbenchRequired{"time",  "pos_gripper", "pos_x", "pos_y", "pos_z",
                                                "orn_w", "orn_x",       "orn_y", "orn_z"};

/// One arm's file: samples with absolute times, world positions.
std::pair<std::vector<ArmSample>, std::vector<std::string>> read_rgbench_arm(const std::string& path, Arm arm) {
  std::vector<ArmSample> rows;
  std::vector<std::string> labels;
  std::map<std::string, size_t> idx;
  bool have_header = false, have_joints = false;
  for (const auto& [n, raw] : lines_of(read_text(path))) {
    const std::string line = trim(raw);
    const std::string where = fmt::format("{}:{}", path, n);
    if (line.empty()) continue;
    const std::vector<std::string> fields = split_csv(line);
    if (!have_header) {
      idx = header_index(fields, where);
      require_columns(idx, kRgbenchRequired, where);
      have_header = true;
      have_joints = true;
      for (const char* c : {"pos_1", "pos_2", "pos_3", "pos_4", "pos_5", "pos_6"}) have_joints = have_joints && idx.count(c);
      continue;
    }
    if (fields.size() != idx.size())
      throw InputError(fmt::format("{}: expected {} fields like the header, found {}", where, idx.size(), fields.size()));
    auto get = [&](const char* c) { return parse_number(fields[idx.at(c)], where, c); };
    ArmSample s;
    s.t = get("time");
    s.position = Vec3(get("pos_x"), get("pos_y"), get("pos_z")) + base_offset(arm);
    s.orientation = quat_from_wxyz(get("orn_w"), get("orn_x"), get("orn_y"), get("orn_z"));
    s.gripper = get("pos_gripper");
    if (have_joints)
      for (const char* c : {"pos_1", "pos_2", "pos_3", "pos_4", "pos_5", "pos_6"}) s.joints.push_back(get(c));
    rows.push_back(s);
    labels.push_back(where);
  }
  if (!have_header) throw InputError(fmt::format("{}: empty file (expected the header {})", path, kRgbenchJointsHeader));
  if (rows.empty()) throw InputError(fmt::format("{}: no samples after the header", path));
  // Files written without kinematics (write_rgbench_joints for samples without joints) hold
  // zeros in every pos_1..pos_6: no joints were recorded; a real arm never stays at exactly 0.
  const bool all_zero = std::all_of(rows.begin(), rows.end(), [](const ArmSample& s) {
    return std::all_of(s.joints.begin(), s.joints.end(), [](double q) { return q == 0.0; });
  });
  if (all_zero)
    for (ArmSample& s : rows) s.joints.clear();
  return {rows, labels};
}

}  // namespace

DualArmTrajectory read_rgbench_joints(const std::string& left_csv, const std::string& right_csv) {
  auto [left, left_labels] = read_rgbench_arm(left_csv, Arm::kLeft);
  auto [right, right_labels] = read_rgbench_arm(right_csv, Arm::kRight);
  // Validate on absolute times first so that messages show the file's values.
  build_arm(left, left_labels);
  build_arm(right, right_labels);
  DualArmTrajectory out;
  out.master_start_time = std::min(left.front().t, right.front().t);
  for (auto* rows : {&left, &right})
    for (ArmSample& s : *rows) s.t -= out.master_start_time;
  out.left = build_arm(left, left_labels);
  out.right = build_arm(right, right_labels);
  return out;
}

DualArmTrajectory read_rgbench_joints_dir(const std::string& dir) {
  const std::filesystem::path d(dir);
  return read_rgbench_joints((d / kRgbenchLeftJointsCsv).string(), (d / kRgbenchRightJointsCsv).string());
}

void write_rgbench_joints(const std::string& dir, const DualArmTrajectory& traj) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw InputError(fmt::format("cannot create directory '{}': {}", dir, ec.message()));
  for (Arm a : {Arm::kLeft, Arm::kRight}) {
    const ArmTrajectory& arm = traj.arm(a);
    if (arm.empty())
      throw InputError(fmt::format("write_rgbench_joints: the {} arm has no samples (RGBench needs both files)", arm_name(a)));
    std::string s = std::string(kRgbenchJointsHeader) + "\n";
    for (const ArmSample& p : arm.samples()) {
      const Vec3 x = p.position - base_offset(a);
      // Absolute Unix times need ~16 significant digits for microseconds: print them exactly.
      std::string joints;
      for (size_t k = 0; k < 6; ++k) joints += (k < p.joints.size() && p.joints.size() == 6 ? num(p.joints[k]) : "0") + ",";
      s += fmt::format("{},{}{},{},{},{},{},{},{},{}\n", num(traj.master_start_time + p.t), joints, num(p.gripper),
                       num(x.x()), num(x.y()), num(x.z()), num(p.orientation.w()), num(p.orientation.x()),
                       num(p.orientation.y()), num(p.orientation.z()));
    }
    const char* name = a == Arm::kLeft ? kRgbenchLeftJointsCsv : kRgbenchRightJointsCsv;
    write_text((std::filesystem::path(dir) / name).string(), s);
  }
}

}  // namespace gd::tasks
