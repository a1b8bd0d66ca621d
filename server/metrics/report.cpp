#include "metrics/report.h"

#include <spdlog/fmt/fmt.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <sstream>

#include "sim/demand.h"
#include "sim/log.h"

namespace gd::metrics {
namespace {

namespace fs = std::filesystem;
using sim::InputError;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

/// A number as pandas' to_csv writes a float: shortest round-trip digits, integral values
/// with ".0", NaN as the empty field.
std::string csv_number(double v) {
  if (std::isnan(v)) return "";
  if (std::isinf(v)) return v > 0 ? "inf" : "-inf";
  std::string s = fmt::format("{}", v);
  if (s.find_first_of(".e") == std::string::npos) s += ".0";
  return s;
}

nlohmann::json json_number(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(); }

std::vector<std::string> split_csv_line(const std::string& line) {
  std::vector<std::string> out;
  std::string cur;
  for (char ch : line) {
    if (ch == ',') {
      out.push_back(cur);
      cur.clear();
    } else if (ch != '\r') {
      cur += ch;
    }
  }
  out.push_back(cur);
  return out;
}

std::ofstream open_out(const std::string& path) {
  std::ofstream f(path);
  if (!f) throw InputError(fmt::format("cannot write '{}' (does its directory exist?)", path));
  return f;
}

nlohmann::json window_json(const EvalWindow& w) {
  return {{"start_record_time", json_number(w.start_record_time)},
          {"end_record_time", json_number(w.end_record_time)},
          {"start_calculate_time", json_number(w.start_calculate_time)},
          {"end_calculate_time", json_number(w.end_calculate_time)}};
}

nlohmann::json metrics_json_nullable(const Metrics& m) {
  nlohmann::json j = nlohmann::json::object();
  for (const MetricName& n : kMetricNames) j[n.key] = json_number(m.*n.field);
  return j;
}

}  // namespace

Summary summarize(const std::vector<FrameRow>& rows, const EvalWindow& w) {
  Summary s;
  s.rows = rows.size();
  std::vector<const FrameRow*> in;
  for (const FrameRow& r : rows)
    if (in_calculate_window(w, r.sim_time)) in.push_back(&r);
  s.frames = in.size();
  for (const MetricName& n : kMetricNames) {
    if (in.empty()) {
      s.mean.*n.field = kNaN;
      s.std_dev.*n.field = kNaN;
      continue;
    }
    double sum = 0;
    for (const FrameRow* r : in) sum += r->m.*n.field;
    const double mean = sum / double(in.size());
    double ss = 0;
    for (const FrameRow* r : in) ss += (r->m.*n.field - mean) * (r->m.*n.field - mean);
    s.mean.*n.field = mean;
    s.std_dev.*n.field = in.size() > 1 ? std::sqrt(ss / double(in.size() - 1)) : kNaN;
  }
  return s;
}

void write_metrics_csv(const std::string& path, const std::vector<FrameRow>& rows,
                       const EvalWindow& window) {
  std::ofstream f = open_out(path);
  std::string line;
  for (const MetricName& n : kMetricNames) line += fmt::format("{},", n.rgbench);
  f << line << "sim_time,target_time\n";
  for (const FrameRow& r : rows) {
    line.clear();
    for (const MetricName& n : kMetricNames) line += csv_number(r.m.*n.field) + ",";
    f << line << csv_number(r.sim_time) << "," << csv_number(r.target_time) << "\n";
  }
  const Summary s = summarize(rows, window);
  if (s.frames > 0) {
    for (const Metrics* m : {&s.mean, &s.std_dev}) {
      line.clear();
      for (const MetricName& n : kMetricNames) line += csv_number(m->*n.field) + ",";
      f << line << ",\n";
    }
  } else {
    gd::log().warn("write_metrics_csv: no row in the calculate window [{}, {}]; '{}' has no mean "
                   "/ std_dev rows (as RGBench)",
                   window.start_calculate_time, window.end_calculate_time, path);
  }
  if (!f) throw InputError(fmt::format("error while writing '{}'", path));
}

nlohmann::json summary_json(const std::vector<FrameRow>& rows, const EvalWindow& window,
                            const nlohmann::json& extra) {
  const Summary s = summarize(rows, window);
  nlohmann::json j = extra.is_object() ? extra : nlohmann::json::object();
  j["rows"] = s.rows;
  j["frames_in_window"] = s.frames;
  j["window"] = window_json(window);
  j["mean"] = metrics_json_nullable(s.mean);
  j["std_dev"] = metrics_json_nullable(s.std_dev);
  return j;
}

void write_summary_json(const std::string& path, const std::vector<FrameRow>& rows,
                        const EvalWindow& window, const nlohmann::json& extra) {
  std::ofstream f = open_out(path);
  f << summary_json(rows, window, extra).dump(2) << "\n";
  if (!f) throw InputError(fmt::format("error while writing '{}'", path));
}

std::string paper_garment(const std::string& garment) {
  static const std::map<std::string, std::string> kPaper = {
      {"tshirt", "green_tshirt"},         {"dress", "blue_dress"},       {"pleat_skirt", "grey_pleat_skirt"},
      {"cake_skirt", "white_cakeskirt"}, {"hoodie", "beige_hoodie"}, {"coat", "brown_coat"}};
  const auto it = kPaper.find(garment);
  return it == kPaper.end() ? garment : it->second;
}

std::vector<BaselineRow> load_paper_baselines(const std::string& csv_path,
                                              const std::string& garment,
                                              const std::string& action, const std::string& mode) {
  std::ifstream f(csv_path);
  if (!f) throw InputError(fmt::format("cannot open paper baselines '{}'", csv_path));
  std::string line;
  if (!std::getline(f, line))
    throw InputError(fmt::format("paper baselines '{}' is empty", csv_path));
  const auto header = split_csv_line(line);
  auto col = [&](const std::string& name) -> size_t {
    for (size_t i = 0; i < header.size(); ++i)
      if (header[i] == name) return i;
    throw InputError(fmt::format("paper baselines '{}' has no column '{}'", csv_path, name));
  };
  const size_t cg = col("garment"), ca = col("action"), cs = col("simulator"), cm = col("mode"),
               cn = col("n_samples");
  std::array<size_t, kMetricNames.size()> cmet{};
  for (size_t k = 0; k < kMetricNames.size(); ++k) cmet[k] = col(kMetricNames[k].key);

  std::vector<BaselineRow> out;
  int lineno = 1;
  while (std::getline(f, line)) {
    ++lineno;
    if (line.empty() || line == "\r") continue;
    const auto v = split_csv_line(line);
    if (v.size() != header.size())
      throw InputError(fmt::format("paper baselines '{}' line {}: {} fields, header has {}",
                                   csv_path, lineno, v.size(), header.size()));
    if (!garment.empty() && v[cg] != garment) continue;
    if (!action.empty() && v[ca] != action) continue;
    if (!mode.empty() && v[cm] != mode) continue;
    BaselineRow r{v[cg], v[ca], v[cs], v[cm], 0, {}};
    try {
      r.n_samples = std::stoi(v[cn]);
      for (size_t k = 0; k < kMetricNames.size(); ++k)
        r.m.*kMetricNames[k].field = v[cmet[k]].empty() ? kNaN : std::stod(v[cmet[k]]);
    } catch (const std::exception&) {
      throw InputError(fmt::format("paper baselines '{}' line {}: a number does not parse",
                                   csv_path, lineno));
    }
    out.push_back(std::move(r));
  }
  return out;
}

void write_comparison(const std::string& dir, const std::string& garment,
                      const std::string& action, const std::string& mode,
                      const std::string& our_label, const Metrics& ours, int n_samples,
                      const std::vector<BaselineRow>& baselines, const std::string& synthetic_capture) {
  const bool synthetic = !synthetic_capture.empty();
  fs::create_directories(dir);
  std::vector<BaselineRow> all;
  all.push_back({garment, action, our_label, mode, n_samples, ours});
  all.insert(all.end(), baselines.begin(), baselines.end());

  {
    std::ofstream f = open_out((fs::path(dir) / "comparison.csv").string());
    f << "garment,action,simulator,mode,n_samples";
    for (const MetricName& n : kMetricNames) f << "," << n.key;
    f << ",capture\n";
    for (const BaselineRow& r : all) {
      f << r.garment << "," << r.action << "," << r.simulator << "," << r.mode << "," << r.n_samples;
      for (const MetricName& n : kMetricNames) f << "," << csv_number(r.m.*n.field);
      f << "," << (&r == &all.front() && synthetic ? "synthetic" : "real") << "\n";
    }
  }
  {
    std::ofstream f = open_out((fs::path(dir) / "comparison.md").string());
    f << fmt::format("# {} / {} ({}): ours beside the RGBench paper\n\n", garment, action,
                     mode.empty() ? "all modes" : mode);
    if (synthetic)
      f << "**Not comparable:** our row is measured against a synthetic capture (" << synthetic_capture
        << "), the paper's rows against real captures of a real garment. A synthetic capture "
           "checks the pipeline (frames, time alignment, metrics), not fidelity to real cloth.\n\n";
    f << "| simulator | capture | mode | samples |";
    for (const MetricName& n : kMetricNames) f << " " << n.key << " |";
    f << "\n|---|---|---|---|";
    for (size_t k = 0; k < kMetricNames.size(); ++k) f << "---|";
    f << "\n";
    for (const BaselineRow& r : all) {
      const bool us = &r == &all.front();
      f << "| " << (us ? "**" + r.simulator + "**" : r.simulator) << " | " << (us && synthetic ? "synthetic" : "real")
        << " | " << r.mode << " | " << r.n_samples << " |";
      for (const MetricName& n : kMetricNames) {
        const double v = r.m.*n.field;
        f << " " << (std::isfinite(v) ? fmt::format("{:.4f}", v) : std::string("-")) << " |";
      }
      f << "\n";
    }
    f << "\nMetres; lower is better. `mujoco_style3d` is the paper's own GarmentDynamics. Paper "
         "rows: mean over samples of each run's calculate-window mean, from Hu et al., \"Real "
         "Garment Benchmark (RGBench)\", AAAI 2026 (github.com/hwk0809/RGBench, "
         "results/paper_baselines.csv; code MIT, data CC-BY-4.0).\n";
    if (baselines.empty()) f << "\nThe paper has no row for this garment/action.\n";
    else if (baselines.front().garment != garment)
      f << fmt::format("\nThe paper's rows are for its {}, the real garment of this type.\n",
                       baselines.front().garment);
  }
}

void write_report_frames(const std::string& dir, const std::vector<FramePair>& kept) {
  const fs::path d = fs::path(dir) / "frames";
  fs::create_directories(d);
  nlohmann::json index = nlohmann::json::array();
  for (size_t k = 0; k < kept.size(); ++k) {
    save_ply((d / fmt::format("sim_{}.ply", k)).string(), kept[k].sim);
    save_ply((d / fmt::format("real_{}.ply", k)).string(), kept[k].real);
    index.push_back({{"k", k}, {"row", kept[k].row}, {"sim_time", kept[k].sim_time}});
  }
  std::ofstream f = open_out((d / "frames.json").string());
  f << index.dump(2) << "\n";
}

}  // namespace gd::metrics
