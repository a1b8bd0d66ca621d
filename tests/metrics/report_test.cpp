#include "metrics/report.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "metrics/test_util.h"

namespace gd::metrics {
namespace {

namespace fs = std::filesystem;
using testing::temp_dir;

std::vector<std::string> read_lines(const std::string& path) {
  std::ifstream f(path);
  std::vector<std::string> out;
  for (std::string l; std::getline(f, l);) out.push_back(l);
  return out;
}

std::vector<std::string> fields(const std::string& line) {
  std::vector<std::string> out;
  std::stringstream ss(line);
  for (std::string f; std::getline(ss, f, ',');) out.push_back(f);
  if (!line.empty() && line.back() == ',') out.push_back("");
  return out;
}

std::vector<FrameRow> make_rows() {
  std::vector<FrameRow> rows;
  for (int k = 0; k < 8; ++k) {
    FrameRow r;
    const double t = 0.1 * k;
    for (size_t i = 0; i < kMetricNames.size(); ++i) r.m.*kMetricNames[i].field = (i + 1) * 0.01 + t;
    r.sim_time = t + 0.051;
    r.target_time = t;
    rows.push_back(r);
  }
  return rows;
}

TEST(Report, MetricsCsvHasRgbenchShapeAndWindowedSummary) {
  const std::string d = temp_dir("csv");
  const auto rows = make_rows();
  const EvalWindow w{0, 1, 0.2, 0.5};  // sim_time 0.251, 0.351, 0.451 are in the window
  write_metrics_csv(d + "/metrics.csv", rows, w);
  const auto lines = read_lines(d + "/metrics.csv");
  ASSERT_EQ(lines.size(), 1 + rows.size() + 2);
  EXPECT_EQ(lines[0],
            "chamfer_l1_sim_to_real,chamfer_l2_sim_to_real,chamfer_l1_real_to_sim,"
            "one_sided_hausdorff_sim_to_real,one_sided_hausdorff_real_to_sim,sim_stability_score,"
            "z_mean_error,sim_time,target_time");
  const auto first = fields(lines[1]);
  ASSERT_EQ(first.size(), 9u);
  EXPECT_DOUBLE_EQ(std::stod(first[0]), 0.01);
  EXPECT_DOUBLE_EQ(std::stod(first[7]), 0.051);
  EXPECT_EQ(first[8], "0.0");
  // iloc[-2]: the mean over the three rows in the calculate window (t = 0.2, 0.3, 0.4).
  const auto mean = fields(lines[lines.size() - 2]);
  const auto sd = fields(lines.back());
  ASSERT_EQ(mean.size(), 9u);
  ASSERT_EQ(sd.size(), 9u);
  for (size_t i = 0; i < 7; ++i) {
    EXPECT_NEAR(std::stod(mean[i]), (i + 1) * 0.01 + 0.3, 1e-12) << i;
    EXPECT_NEAR(std::stod(sd[i]), 0.1, 1e-12) << i;  // ddof = 1
  }
  EXPECT_EQ(mean[7], "");
  EXPECT_EQ(mean[8], "");
  EXPECT_EQ(sd[7], "");

  const Summary s = summarize(rows, w);
  EXPECT_EQ(s.frames, 3u);
  EXPECT_EQ(s.rows, 8u);
}

TEST(Report, OneRowInWindowHasEmptyStdAndNoneHasNoSummaryRows) {
  const std::string d = temp_dir("csv1");
  const auto rows = make_rows();
  write_metrics_csv(d + "/one.csv", rows, EvalWindow{0, 1, 0.25, 0.26});
  auto lines = read_lines(d + "/one.csv");
  ASSERT_EQ(lines.size(), 11u);
  EXPECT_EQ(lines.back(), ",,,,,,,,");
  EXPECT_NEAR(std::stod(fields(lines[9])[0]), 0.21, 1e-12);
  write_metrics_csv(d + "/none.csv", rows, EvalWindow{0, 1, 5, 6});
  EXPECT_EQ(read_lines(d + "/none.csv").size(), 9u);
}

TEST(Report, SummaryJson) {
  const std::string d = temp_dir("json");
  write_summary_json(d + "/summary.json", make_rows(), EvalWindow{0, 1, 0.2, 0.5},
                     {{"garment", "blue_dress"}});
  std::ifstream f(d + "/summary.json");
  const auto j = nlohmann::json::parse(f);
  EXPECT_EQ(j["garment"], "blue_dress");
  EXPECT_EQ(j["frames_in_window"], 3);
  EXPECT_NEAR(j["mean"]["cd_l1_r2s"].get<double>(), 0.03 + 0.3, 1e-12);
  EXPECT_NEAR(j["std_dev"]["z_err"].get<double>(), 0.1, 1e-12);
  EXPECT_DOUBLE_EQ(j["window"]["end_calculate_time"].get<double>(), 0.5);
  const auto one = summary_json(make_rows(), EvalWindow{0, 1, 0.25, 0.26});
  EXPECT_TRUE(one["std_dev"]["cd_l1_s2r"].is_null());
}

TEST(Report, PaperBaselinesAndComparison) {
  const std::string data = testing::rgbench_data_dir();
  if (data.empty()) GTEST_SKIP() << "GD_SHARED_DIR/data/rgbench not available";
  const auto rows = load_paper_baselines(data + "/paper_baselines.csv", "beige_hoodie", "fling");
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[1].simulator, "mujoco_style3d");
  EXPECT_EQ(rows[1].mode, "fixed_point");
  EXPECT_EQ(rows[1].n_samples, 3);
  EXPECT_DOUBLE_EQ(rows[1].m.cd_l1_s2r, 0.0425);
  EXPECT_DOUBLE_EQ(rows[1].m.cd_l1_r2s, 0.0256);
  EXPECT_DOUBLE_EQ(rows[1].m.z_err, 0.0064);
  EXPECT_EQ(load_paper_baselines(data + "/paper_baselines.csv", "", "").size(), 105u);
  EXPECT_TRUE(load_paper_baselines(data + "/paper_baselines.csv", "no_such", "fling").empty());

  const std::string d = temp_dir("cmp");
  Metrics ours{0.03, 0.02, 0.025, 0.1, 0.09, 0.0011, 0.005};
  write_comparison(d, "beige_hoodie", "fling", "fixed_point", "garmentdynamics", ours, 1, rows);
  const auto csv = read_lines(d + "/comparison.csv");
  ASSERT_EQ(csv.size(), 5u);
  EXPECT_EQ(csv[0],
            "garment,action,simulator,mode,n_samples,cd_l1_s2r,cd_l2_s2r,cd_l1_r2s,hd_s2r,hd_r2s,sim_stab,z_err,capture");
  EXPECT_EQ(csv[1].rfind("beige_hoodie,fling,garmentdynamics,fixed_point,1,0.03,", 0), 0u) << csv[1];
  for (size_t k = 1; k < csv.size(); ++k) EXPECT_EQ(csv[k].substr(csv[k].rfind(',') + 1), "real") << csv[k];
  const auto md = read_lines(d + "/comparison.md");
  std::string all;
  for (const auto& l : md) all += l + "\n";
  EXPECT_NE(all.find("| **garmentdynamics** | real | fixed_point | 1 | 0.0300 |"), std::string::npos) << all;
  EXPECT_NE(all.find("RGBench"), std::string::npos);
  EXPECT_EQ(all.find("Not comparable"), std::string::npos) << all;
  testing::expect_input_error([&] { load_paper_baselines(d + "/nope.csv", "a", "b"); }, "nope.csv");
}

TEST(Report, AGeneratedGarmentIsComparedWithThePapersGarmentOfItsType) {
  EXPECT_EQ(paper_garment("tshirt"), "green_tshirt");
  EXPECT_EQ(paper_garment("cake_skirt"), "white_cakeskirt");
  EXPECT_EQ(paper_garment("green_tshirt"), "green_tshirt");  // a capture's own name
  EXPECT_EQ(paper_garment("towel"), "towel");                // no paper garment: no rows
  const std::string data = testing::rgbench_data_dir();
  if (data.empty()) GTEST_SKIP() << "GD_SHARED_DIR/data/rgbench not available";
  // Every mapped name is one the paper's table has, for all three actions.
  for (const char* type : {"tshirt", "dress", "pleat_skirt", "cake_skirt", "hoodie", "coat"})
    for (const char* action : {"grasp", "fold", "fling"})
      EXPECT_FALSE(load_paper_baselines(data + "/paper_baselines.csv", paper_garment(type), action).empty())
          << type << " " << action;
  const auto rows = load_paper_baselines(data + "/paper_baselines.csv", paper_garment("tshirt"), "fold");
  const std::string d = temp_dir("cmp_type");
  write_comparison(d, "tshirt", "fold", "pseudo", "garmentdynamics", Metrics{}, 1, rows);
  std::string all;
  for (const auto& l : read_lines(d + "/comparison.md")) all += l + "\n";
  EXPECT_NE(all.find("The paper's rows are for its green_tshirt"), std::string::npos) << all;
  EXPECT_EQ(all.find("no row"), std::string::npos) << all;
}

// A metric measured against a capture the simulator made itself is labelled as such beside the
// paper's rows (measured against real captures), in the CSV and in the markdown.
TEST(Report, OursAgainstASyntheticCaptureIsLabelledNotComparable) {
  BaselineRow paper{"green_tshirt", "fold", "mujoco_style3d", "fixed_point", 3, Metrics{0.04, 0.05, 0.03, 0.1, 0.1, 0, 0.01}};
  const std::string d = temp_dir("cmp_synthetic");
  write_comparison(d, "tshirt", "fold", "pseudo", "garmentdynamics (ours)", Metrics{0.01, 0.01, 0.01, 0.05, 0.05, 0, 0.001},
                   1, {paper}, "GarmentDynamics, tshirt fold at 680 vertices, cotton, dt 0.01 s");
  const auto csv = read_lines(d + "/comparison.csv");
  ASSERT_EQ(csv.size(), 3u);
  EXPECT_EQ(csv[1].substr(csv[1].rfind(',') + 1), "synthetic") << csv[1];
  EXPECT_EQ(csv[2].substr(csv[2].rfind(',') + 1), "real") << csv[2];
  std::string all;
  for (const auto& l : read_lines(d + "/comparison.md")) all += l + "\n";
  EXPECT_NE(all.find("**Not comparable:**"), std::string::npos) << all;
  EXPECT_NE(all.find("tshirt fold at 680 vertices"), std::string::npos) << all;
  EXPECT_NE(all.find("| **garmentdynamics (ours)** | synthetic | pseudo |"), std::string::npos) << all;
  EXPECT_NE(all.find("| mujoco_style3d | real | fixed_point |"), std::string::npos) << all;
}

TEST(Report, FramesForPlots) {
  const std::string d = temp_dir("frames");
  std::vector<FramePair> kept = {{0, 0.1, testing::random_cloud(50, 1), testing::random_cloud(60, 2)},
                                 {4, 0.5, testing::random_cloud(50, 3), testing::random_cloud(70, 4)}};
  write_report_frames(d, kept);
  EXPECT_EQ(load_cloud(d + "/frames/sim_1.ply").size(), 50u);
  EXPECT_EQ(load_cloud(d + "/frames/real_1.ply").size(), 70u);
  std::ifstream f(d + "/frames/frames.json");
  const auto j = nlohmann::json::parse(f);
  ASSERT_EQ(j.size(), 2u);
  EXPECT_EQ(j[1]["row"], 4);
}

}  // namespace
}  // namespace gd::metrics
