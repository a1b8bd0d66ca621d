// The `gd` command line's remote commands, run as a process against a real gd-server: output,
// files written and exit codes (0 ok, 1 failed, 2 bad input, 3 unreachable/RPC error).
#include <sys/wait.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "client_cpp/server_fixture.h"

namespace gd::client_test {
namespace {

struct CliRun {
  int rc = -1;
  std::string out;  ///< stdout
  std::string err;  ///< stderr
};

std::string slurp(const std::filesystem::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::vector<std::string> lines(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string l; std::getline(ss, l);)
    if (!l.empty()) out.push_back(l);
  return out;
}

class CliTest : public ServerTest {
 protected:
  /// Runs `gd ARGS` (arguments are shell words without quotes) and collects its output; with
  /// `whole`, ARGS is the whole command line (e.g. with environment assignments in front).
  CliRun gd(const std::string& args, bool whole = false) {
    const auto err_file = fresh_dir("cli_stderr") / "stderr.txt";
    const std::string cmd = (whole ? args : std::string(GD_CLI_BINARY) + " " + args) + " 2>" + err_file.string();
    CliRun r;
    FILE* p = ::popen(cmd.c_str(), "r");
    if (p == nullptr) return r;
    char buf[4096];
    for (size_t n; (n = std::fread(buf, 1, sizeof buf, p)) > 0;) r.out.append(buf, n);
    const int status = ::pclose(p);
    r.rc = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    r.err = slurp(err_file);
    return r;
  }
  std::string server_flag() const { return "--server " + address(); }
};

TEST_F(CliTest, InfoGarmentsMaterials) {
  CliRun r = gd(server_flag() + " info");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("backend cpu"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("health SERVING"), std::string::npos) << r.out;
  r = gd(server_flag() + " garments");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("towel\n"), std::string::npos) << r.out;
  r = gd(server_flag() + " materials");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("cotton"), std::string::npos) << r.out;
}

TEST_F(CliTest, CreateStepWritesNpyAndPlyThenDestroy) {
  CliRun r = gd(server_flag() + " create --garment towel --vertices 200 --count 2 --seed 3 --no-self-contact");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto ids = lines(r.out);
  ASSERT_EQ(ids.size(), 2u) << r.out;

  const auto dir = fresh_dir("cli_step");
  r = gd(server_flag() + " step --ids " + ids[0] + "," + ids[1] + " --substeps 3 --out " + (dir / "x.npy").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  ASSERT_EQ(lines(r.out).size(), 2u) << r.out;
  EXPECT_EQ(r.out.rfind(ids[0], 0), 0u) << r.out;
  EXPECT_NE(r.out.find("steps 3"), std::string::npos) << r.out;

  // The .npy holds the first scene's positions: header (a multiple of 64 bytes) + N*3 float32.
  const std::string npy = slurp(dir / "x.npy");
  ASSERT_GT(npy.size(), 10u);
  EXPECT_EQ(npy.substr(0, 6), "\x93NUMPY");
  const size_t header = 10 + static_cast<unsigned char>(npy[8]) + 256 * static_cast<unsigned char>(npy[9]);
  EXPECT_EQ(header % 64, 0u);
  const auto state = client_.get_state({ids[0]});
  ASSERT_EQ(state.size(), 1u);
  ASSERT_EQ(npy.size(), header + 4 * state[0].positions.size());
  EXPECT_NE(npy.find("'shape': (" + std::to_string(state[0].positions.size() / 3) + ", 3)"), std::string::npos);
  std::vector<float> from_file(state[0].positions.size());
  std::memcpy(from_file.data(), npy.data() + header, 4 * from_file.size());
  EXPECT_EQ(from_file, state[0].positions);

  r = gd(server_flag() + " step --ids " + ids[0] + " --out " + (dir / "x.ply").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(slurp(dir / "x.ply").substr(0, 3), "ply");

  r = gd(server_flag() + " destroy --ids " + ids[0] + "," + ids[1]);
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("destroyed 2"), std::string::npos) << r.out;
}

TEST_F(CliTest, RunAsAJobWritesTheReportFiles) {
  const auto dir = fresh_dir("cli_run");
  CliRun r = gd(server_flag() + " run --garment towel --vertices 200 --task grasp --time-scale 0.3 --settle 0.2 "
                             "--no-self-contact --quiet --label cli --out " +
             (dir / "out").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_TRUE(std::filesystem::exists(dir / "out" / "summary.json")) << r.err;
  EXPECT_TRUE(std::filesystem::exists(dir / "out" / "final.obj")) << r.err;
  EXPECT_NE(r.out.find("towel / cotton / grasp"), std::string::npos) << r.out;

  // The job is listed and its report can be fetched again into another directory.
  r = gd(server_flag() + " reports --limit 5");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto first = lines(r.out).at(0);
  EXPECT_NE(first.find("succeeded"), std::string::npos) << r.out;
  const std::string job = first.substr(0, first.find(' '));
  r = gd(server_flag() + " report " + job + " --out " + (dir / "again").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(slurp(dir / "again" / "summary.json"), slurp(dir / "out" / "summary.json"));
  // Every run's frames come with it (animation.npy); --open draws the animation here (this server
  // has no --plots) and writes the report as one HTML page with the pictures inside.
  EXPECT_TRUE(std::filesystem::exists(dir / "again" / "animation.npy"));
  r = gd(server_flag() + " report " + job + " --out " + (dir / "page").string() + " --open");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("report.html"), std::string::npos) << r.out;
  const std::string page = slurp(dir / "page" / "report.html");
  EXPECT_NE(page.find("<h1>towel grasp"), std::string::npos);
  if (std::filesystem::exists(dir / "page" / "animation.gif"))  // a Python with matplotlib drew it
    EXPECT_NE(page.find("data:image/gif;base64,"), std::string::npos);
}

/// Vertices the grippers held in a local `gd run` towel grasp with these extra flags.
int held_vertices(const std::filesystem::path& out) {
  const auto s = nlohmann::json::parse(slurp(out / "summary.json"));
  int n = 0;
  for (const auto& e : s.at("grasp_events"))
    if (e.at("grasp").get<bool>()) n += e.at("vertices").get<int>();
  return n;
}

TEST_F(CliTest, JawRadiusSetsHowMuchClothAGripperTakes) {
  const auto dir = fresh_dir("cli_jaw");
  const std::string run = " run --garment towel --vertices 200 --task grasp --time-scale 0.3 --settle 0.1 "
                          "--no-self-contact --no-plots --quiet --threads 1 --out ";
  CliRun r = gd(run + (dir / "default").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  r = gd(run + (dir / "wide").string() + " --jaw-radius 0.08");
  ASSERT_EQ(r.rc, 0) << r.err;
  const int narrow = held_vertices(dir / "default"), wide = held_vertices(dir / "wide");
  EXPECT_GE(narrow, 2);  // at least the nearest vertex per arm
  EXPECT_GT(wide, 2 * narrow) << narrow << " vertices held at 2 cm, " << wide << " at 8 cm";
  // A local-only option: refused with --server (the server decides), and a negative radius.
  r = gd(server_flag() + " run --garment towel --task grasp --jaw-radius 0.05 --out " + (dir / "remote").string());
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("--jaw-radius"), std::string::npos) << r.err;
  r = gd(run + (dir / "negative").string() + " --jaw-radius -1");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("jaw_radius"), std::string::npos) << r.err;
}

TEST_F(CliTest, ContactHessianReachesTheSceneAndTheSummary) {
  // --contact-hessian gauss-newton was once parsed and then dropped (the run stayed projected).
  const auto dir = fresh_dir("cli_contact_hessian");
  const std::string run = " run --garment towel --vertices 200 --task grasp --time-scale 0.3 --settle 0.1 "
                          "--no-plots --quiet --threads 1 --out ";
  auto kind = [&](const std::string& name) {
    return nlohmann::json::parse(slurp(dir / name / "summary.json")).at("contact_hessian").get<std::string>();
  };
  CliRun r = gd(run + (dir / "default").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_EQ(kind("default"), "termwise");  // auto, without colliders
  for (const std::string name : {"gauss-newton", "projected"}) {
    r = gd(run + (dir / name).string() + " --contact-hessian " + name);
    ASSERT_EQ(r.rc, 0) << r.err;
    EXPECT_EQ(kind(name), name);
  }
  r = gd(run + (dir / "bad").string() + " --contact-hessian exact");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("--contact-hessian"), std::string::npos) << r.err;
}

TEST_F(CliTest, BroadPhaseReachesTheSceneAndTheSummaryAndFindsTheSamePairs) {
  const auto dir = fresh_dir("cli_broad_phase");
  const std::string run = " run --garment towel --vertices 200 --task grasp --time-scale 0.3 --settle 0.1 "
                          "--no-plots --quiet --threads 1 --out ";
  auto summary = [&](const std::string& name) { return nlohmann::json::parse(slurp(dir / name / "summary.json")); };
  CliRun r = gd(run + (dir / "default").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  r = gd(run + (dir / "embree").string() + " --broad-phase embree");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto a = summary("default"), b = summary("embree");
  EXPECT_EQ(a.at("broad_phase"), "lbvh");
  EXPECT_EQ(b.at("broad_phase"), "embree");
  // Both report the same candidate pairs, so the runs take the same steps.
  EXPECT_EQ(a.at("final"), b.at("final"));
  EXPECT_EQ(a.at("pcg_per_step"), b.at("pcg_per_step"));
  r = gd(run + (dir / "bad").string() + " --broad-phase bvh");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("--broad-phase"), std::string::npos) << r.err;
  r = gd(server_flag() + " run --garment towel --task grasp --broad-phase lbvh --out " + (dir / "remote").string());
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("--broad-phase"), std::string::npos) << r.err;
}

// --deterministic reaches the scene and the summary; the CPU backend is deterministic either way,
// so its run takes the same steps with the flag; a server decides it for itself.
TEST_F(CliTest, DeterministicReachesTheSummaryAndLeavesTheCpuBackendsStepsAlone) {
  const auto dir = fresh_dir("cli_deterministic");
  const std::string run = " run --garment towel --vertices 200 --task grasp --time-scale 0.3 --settle 0.1 "
                          "--no-plots --quiet --threads 1 --out ";
  auto summary = [&](const std::string& name) { return nlohmann::json::parse(slurp(dir / name / "summary.json")); };
  CliRun r = gd(run + (dir / "default").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  r = gd(run + (dir / "det").string() + " --deterministic");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto a = summary("default"), b = summary("det");
  EXPECT_EQ(a.at("deterministic"), false);
  EXPECT_EQ(b.at("deterministic"), true);
  EXPECT_EQ(a.at("final"), b.at("final"));
  EXPECT_EQ(a.at("pcg_per_step"), b.at("pcg_per_step"));
  r = gd(server_flag() + " run --garment towel --task grasp --deterministic --out " + (dir / "remote").string());
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("--deterministic"), std::string::npos) << r.err;
}

// Robot mode: the URDF arms run a generated grasp locally (their solved joints written as
// RGBench joints CSVs) and as a job with the URDF sent to the server; without a URDF (locally,
// or on a server without --robot-urdf) it is refused with what to do.
TEST_F(CliTest, RobotModeRunsLocallyAndAsAJobAndIsRefusedWithoutAUrdf) {
  const char* shared = std::getenv("GD_SHARED_DIR");
  const std::string urdf = shared ? std::string(shared) + "/data/rgbench/piper_with_gripper.urdf" : "";
  if (urdf.empty() || !std::ifstream(urdf)) GTEST_SKIP() << "../shared/data/rgbench/piper_with_gripper.urdf not present";
  const auto dir = fresh_dir("cli_robot");
  const std::string run = " run --garment towel --vertices 200 --task grasp --time-scale 0.3 --settle 0.1 "
                          "--task-param lift_height=0.3 --no-plots --quiet --threads 1 --mode robot";
  CliRun r = gd(run + " --urdf " + urdf + " --out " + (dir / "local").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto s = nlohmann::json::parse(slurp(dir / "local" / "summary.json"));
  EXPECT_EQ(s.at("mode"), "robot");
  EXPECT_GT(s.at("robot").at("ik_samples").get<int>(), 100);
  EXPECT_LT(s.at("robot").at("ik_max_tilt_deg").get<double>(), 120.0);
  // Down to the table: 5 mm plus the height of the settled towel's corners (lying cloth rests half a
  // contact distance, 0.5 mm, up).
  EXPECT_GT(s.at("task_params").at("grasp_depth").get<double>(), 0.005);
  EXPECT_LT(s.at("task_params").at("grasp_depth").get<double>(), 0.0065);
  EXPECT_EQ(s.at("robot").at("hands_half_turned").size(), 2u);
  EXPECT_EQ(s.at("robot").at("rigid_hands"), true);  // a hand's pads yield together (--independent-pads: not)
  EXPECT_DOUBLE_EQ(s.at("robot").at("pad_stiffness").get<double>(), 3e5);  // a stopped hand goes on in the solve
  EXPECT_EQ(s.at("contact_hessian"), "projected");  // auto: the exact projection where fingers press the cloth
  EXPECT_EQ(s.at("robot").at("pad_samples"), true);  // the cloth's surface samples kept out of the pads
  // The 200-vertex towel is meshed coarser round its grasp points than the pads are thick (8 mm):
  // the run says so and what to do, and records how coarse.
  const char* coarse = "coarser than the pads are thick";
  EXPECT_GT(s.at("robot").at("grasp_edge_m").get<double>(), 0.008);
  EXPECT_NE(r.err.find(coarse), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("--refine-grasp 0.008 --refine-grasp-radius 0.03"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("grasp_inset=0.01"), std::string::npos) << r.err;
  {
    CliRun off = gd(run + " --no-pad-samples --urdf " + urdf + " --out " + (dir / "vertices_alone").string());
    ASSERT_EQ(off.rc, 0) << off.err;
    EXPECT_EQ(nlohmann::json::parse(slurp(dir / "vertices_alone" / "summary.json")).at("robot").at("pad_samples"),
              false);
    EXPECT_EQ(off.err.find(coarse), std::string::npos) << "pads that pass between the vertices need no finer mesh";
  }
  // The time series carries each hand's opening (within the finger's travel), squeeze, lift
  // off the table and squeeze limit (the URDF's 10 N without a schedule), the squeeze split into
  // the inner faces' push and the outer faces' (summing to it), the vertices doing each, and the
  // pads' reached fractions, where the pads cut the cloth (a count, and a depth within a pad's
  // 4 mm half thickness); and the hands close.
  std::ifstream ts(dir / "local" / "timeseries.csv");
  std::string ts_header, ts_row;
  std::getline(ts, ts_header);
  EXPECT_NE(ts_header.find(",left_gripper,right_gripper,left_squeeze_n,right_squeeze_n,left_table_lift,right_table_lift,"
                           "left_grip_limit_n,right_grip_limit_n,left_push_open_n,left_push_close_n,right_push_open_n,"
                           "right_push_close_n,left_vertices_open,left_vertices_close,right_vertices_open,"
                           "right_vertices_close,left_reached,right_reached,left_pad_cuts,right_pad_cuts,"
                           "left_pad_cut_depth_mm,right_pad_cut_depth_mm"),
            std::string::npos) << ts_header;
  double narrowest = 1;
  while (std::getline(ts, ts_row)) {
    std::vector<double> c;
    std::stringstream cells_ts(ts_row);
    for (std::string v; std::getline(cells_ts, v, ',');) c.push_back(std::stod(v));
    ASSERT_EQ(c.size(), 34u);
    EXPECT_DOUBLE_EQ(c[18], 10.0);
    EXPECT_DOUBLE_EQ(c[19], 10.0);
    for (int hand : {0, 1}) {
      const double open = c[20 + 2 * hand], close = c[21 + 2 * hand];
      EXPECT_GE(open, 0.0);
      EXPECT_LE(close, 0.0);
      EXPECT_NEAR(open + close, c[14 + hand], 1e-3 + 1e-4 * std::abs(c[14 + hand]));  // 4 decimals written
      if (c[24 + 2 * hand] == 0) EXPECT_EQ(open, 0.0);  // no vertex on the inner faces, no push
      EXPECT_GE(c[28 + hand], 0.0);
      EXPECT_LE(c[28 + hand], 1.0);
      EXPECT_GE(c[30 + hand], 0.0);
      if (c[30 + hand] == 0) EXPECT_EQ(c[32 + hand], 0.0) << "no cut, no depth";
      EXPECT_LE(c[32 + hand], 4.0 + 1e-3);
    }
    for (int k : {12, 13}) {
      EXPECT_GE(c[k], 0.0);
      EXPECT_LE(c[k], 0.035 + 1e-9);
      narrowest = std::min(narrowest, c[k]);
    }
    EXPECT_TRUE(std::isfinite(c[14]) && std::isfinite(c[15]));
  }
  EXPECT_LT(narrowest, 0.005) << "m: the hands close";
  // The left arm's joints CSV: RGBench's header, six joint angles that are not all zero.
  std::ifstream joints(dir / "local" / "joints" / "left_arm_joint_states_and_end_pose.csv");
  std::string header, row;
  std::getline(joints, header);
  std::getline(joints, row);
  EXPECT_EQ(header.rfind("time,pos_1,pos_2,pos_3,pos_4,pos_5,pos_6,pos_gripper", 0), 0u) << header;
  std::stringstream cells(row);
  std::vector<double> f;
  for (std::string c; std::getline(cells, c, ',');) f.push_back(std::stod(c));
  ASSERT_EQ(f.size(), 15u);
  EXPECT_GT(std::abs(f[2]) + std::abs(f[3]), 0.1);  // joint2 and joint3 bend the arm down to the table
  r = gd(run + " --out " + (dir / "no_urdf").string());
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("--urdf"), std::string::npos) << r.err;
  // A squeeze-limit schedule: a knot that is not T:N, and knots out of order, are refused naming
  // what to fix; the schedule is local only.
  r = gd(run + " --urdf " + urdf + " --grip-force-schedule 1:10 2 --out " + (dir / "bad_knot").string());
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("T:VALUE"), std::string::npos) << r.err;
  r = gd(run + " --urdf " + urdf + " --grip-force-schedule 2:10 1:5 --out " + (dir / "bad_order").string());
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("increasing time"), std::string::npos) << r.err;
  r = gd(server_flag() + " run --garment towel --task grasp --mode robot --grip-force-schedule 1:10 --out " +
         (dir / "remote_schedule").string());
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("--grip-force-schedule is not available with --server"), std::string::npos) << r.err;
  r = gd(server_flag() + " run --garment towel --task grasp --mode robot --independent-pads --out " +
         (dir / "remote_pads").string());
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("--independent-pads is not available with --server"), std::string::npos) << r.err;
  // The same as a job: the URDF's text, the lift tilt bound and the pads' stiffness go with it, and
  // the job's report says robot mode with those.
  r = gd(server_flag() + run.substr(0, run.find(" --no-plots")) + " --quiet --mode robot --urdf " + urdf +
         " --lift-max-tilt 20 --pad-stiffness 1e5 --out " + (dir / "remote").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto rs = nlohmann::json::parse(slurp(dir / "remote" / "summary.json"));
  EXPECT_EQ(rs.at("mode"), "robot");
  EXPECT_GT(rs.at("robot").at("ik_samples").get<int>(), 100);
  EXPECT_NEAR(rs.at("robot").at("lift_max_tilt_deg").get<double>(), 20.0, 1e-9);
  EXPECT_DOUBLE_EQ(rs.at("robot").at("pad_stiffness").get<double>(), 1e5);
  EXPECT_NEAR(s.at("robot").at("lift_max_tilt_deg").get<double>(), 30.0, 1e-9);  // the local run's default
  // Without a URDF: this server has no --robot-urdf of its own.
  r = gd(server_flag() + " run --garment towel --task grasp --mode robot --out " + (dir / "remote_no_urdf").string());
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("--robot-urdf"), std::string::npos) << r.err;
}

// --garment-position moves the garment (RGBench's init_pose): the initial mesh starts where asked
// and the summary records it; a server places jobs itself.
TEST_F(CliTest, GarmentPositionPlacesTheGarment) {
  const auto dir = fresh_dir("cli_position");
  const std::string run = " run --garment towel --vertices 200 --task grasp --time-scale 0.3 --settle 0.1 "
                          "--no-self-contact --no-plots --quiet --threads 1 --out ";
  CliRun r = gd(run + (dir / "moved").string() + " --garment-position 0.3 0.05 0.02");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto s = nlohmann::json::parse(slurp(dir / "moved" / "summary.json"));
  EXPECT_EQ(s.at("garment_position"), nlohmann::json::array({0.3, 0.05, 0.02}));
  std::ifstream obj(dir / "moved" / "initial.obj");
  double lo_x = 1e9, lo_y = 1e9, hi_y = -1e9;
  for (std::string line; std::getline(obj, line);) {
    if (line.rfind("v ", 0) != 0) continue;
    std::stringstream v(line.substr(2));
    double x, y, z;
    v >> x >> y >> z;
    lo_x = std::min(lo_x, x), lo_y = std::min(lo_y, y), hi_y = std::max(hi_y, y);
  }
  EXPECT_NEAR(lo_x, 0.3, 1e-6);               // the towel's near edge (its frame's x = 0)
  EXPECT_NEAR(0.5 * (lo_y + hi_y), 0.05, 1e-6);  // centred on y = 0.05
  r = gd(run + (dir / "bad").string() + " --garment-position 0.3 0 -0.1");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("garment position"), std::string::npos) << r.err;
  r = gd(server_flag() + " run --garment towel --task grasp --garment-position 0.3 0 0.01 --out " +
         (dir / "remote").string());
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("--garment-position"), std::string::npos) << r.err;
}

TEST_F(CliTest, GarmentParamSizesTheGarmentLocallyAndAsAJob) {
  const auto dir = fresh_dir("cli_sizes");
  const std::string run = " run --garment towel --vertices 200 --task grasp --time-scale 0.3 --settle 0.1 "
                          "--no-self-contact --quiet --garment-param length=0.45 --garment-param width=0.3 --out ";
  CliRun r = gd(run + (dir / "local").string() + " --no-plots --threads 1");
  ASSERT_EQ(r.rc, 0) << r.err;
  auto s = nlohmann::json::parse(slurp(dir / "local" / "summary.json"));
  EXPECT_NEAR(s.at("garment_length").get<double>(), 0.45, 1e-6);
  EXPECT_NEAR(s.at("garment_width").get<double>(), 0.30, 1e-6);
  EXPECT_DOUBLE_EQ(s.at("garment_params").at("length").get<double>(), 0.45);
  // The same sizes travel with a job to the server.
  r = gd(server_flag() + run + (dir / "remote").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  s = nlohmann::json::parse(slurp(dir / "remote" / "summary.json"));
  EXPECT_NEAR(s.at("garment_length").get<double>(), 0.45, 1e-6);
  EXPECT_DOUBLE_EQ(s.at("garment_params").at("width").get<double>(), 0.3);
  // And to scenes.
  r = gd(server_flag() + " create --garment towel --vertices 200 --garment-param length=0.45 --no-self-contact");
  ASSERT_EQ(r.rc, 0) << r.err;
  // Not NAME=VALUE, an unknown name (locally and on the server), a size that makes no garment: 2.
  r = gd(run + (dir / "bad1").string() + " --garment-param length");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("NAME=VALUE"), std::string::npos) << r.err;
  r = gd(run + (dir / "bad2").string() + " --garment-param lenght=0.5");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("lenght"), std::string::npos) << r.err;
  r = gd(server_flag() + run + (dir / "bad3").string() + " --garment-param lenght=0.5");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("lenght"), std::string::npos) << r.err;
  r = gd(server_flag() + " create --garment towel --vertices 200 --garment-param length=-1");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("length"), std::string::npos) << r.err;
}

TEST_F(CliTest, RefineGraspRefinesLocallyAndAsAJob) {
  // gd run --refine-grasp: the same refined mesh locally and on the server (the flag once went
  // unsent with --server); past the server's vertex limit the job is refused (exit 3).
  const auto dir = fresh_dir("cli_refine");
  const std::string run = " run --garment towel --vertices 200 --task grasp --time-scale 0.3 --settle 0.1 "
                          "--no-self-contact --quiet --refine-grasp 0.01 --refine-grasp-radius 0.04 --out ";
  CliRun r = gd(run + (dir / "local").string() + " --no-plots --threads 1");
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto local = nlohmann::json::parse(slurp(dir / "local" / "summary.json"));
  r = gd(server_flag() + run + (dir / "remote").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  const auto remote = nlohmann::json::parse(slurp(dir / "remote" / "summary.json"));
  EXPECT_DOUBLE_EQ(remote.at("refine_grasp").at("edge_m").get<double>(), 0.01);
  EXPECT_DOUBLE_EQ(remote.at("refine_grasp").at("radius_m").get<double>(), 0.04);
  EXPECT_EQ(remote.at("vertices"), local.at("vertices"));
  EXPECT_GT(local.at("vertices").get<int>(), 220);
  r = gd(server_flag() + " run --garment towel --vertices 200 --task grasp --quiet --refine-grasp 0.001 "
                         "--refine-grasp-radius 2 --out " + (dir / "huge").string());
  EXPECT_EQ(r.rc, 3) << r.err;  // RESOURCE_EXHAUSTED: the server's limit, not a malformed request
  EXPECT_NE(r.err.find("--max-vertices"), std::string::npos) << r.err;
}

/// A 30 x 20 cm rectangle at height z as an OBJ of n x n quads (two triangles each).
void write_rect_obj(const std::filesystem::path& path, int n, double z) {
  std::ofstream f(path);
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) f << "v " << 0.3 * i / n << " " << 0.2 * j / n << " " << z << "\n";
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i + 1, b = a + 1, c = a + n + 1, d = c + 1;
      f << "f " << a << " " << b << " " << d << "\nf " << a << " " << d << " " << c << "\n";
    }
}

TEST_F(CliTest, MetricsSurfaceComparesTwoMeshingsOfOneShapeAsTheSame) {
  // gd metrics --surface: one rectangle meshed as 2 triangles and as 800 is at zero as a surface,
  // where the vertex clouds are centimetres apart (the fine vertices far from the coarse corners);
  // lifted 1 cm, both directions read 1 cm.
  const auto dir = fresh_dir("cli_metrics_surface");
  write_rect_obj(dir / "coarse.obj", 1, 0.0);
  write_rect_obj(dir / "fine.obj", 20, 0.0);
  write_rect_obj(dir / "lifted.obj", 20, 0.01);
  CliRun r = gd("metrics --json --surface 4000 --sim " + (dir / "coarse.obj").string() + " --real " +
                (dir / "fine.obj").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  auto j = nlohmann::json::parse(r.out);
  EXPECT_GT(j.at("cd_l1_r2s").get<double>(), 0.05) << "the fine vertices to the nearest coarse corner";
  for (const char* k : {"surface_cd_s2r", "surface_cd_r2s", "surface_hd_s2r", "surface_hd_r2s"})
    EXPECT_LT(j.at(k).get<double>(), 1e-9) << k;
  r = gd("metrics --json --surface 4000 --sim " + (dir / "coarse.obj").string() + " --real " +
         (dir / "lifted.obj").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  j = nlohmann::json::parse(r.out);
  for (const char* k : {"surface_cd_s2r", "surface_cd_r2s", "surface_hd_s2r", "surface_hd_r2s"})
    EXPECT_NEAR(j.at(k).get<double>(), 0.01, 1e-9) << k;
  // Without --surface: RGBench's seven alone; a cloud that is not a mesh is refused with --surface.
  r = gd("metrics --json --sim " + (dir / "coarse.obj").string() + " --real " + (dir / "fine.obj").string());
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_FALSE(nlohmann::json::parse(r.out).contains("surface_cd_s2r"));
  std::ofstream(dir / "cloud.ply") << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                       "property float z\nend_header\n0 0 0\n0.3 0 0\n0 0.2 0\n";
  r = gd("metrics --surface 100 --sim " + (dir / "coarse.obj").string() + " --real " + (dir / "cloud.ply").string());
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("OBJ"), std::string::npos) << r.err;
}

TEST_F(CliTest, MaterialParamReachesTheServersScenes) {
  CliRun r = gd(server_flag() + " create --garment towel --vertices 200 --no-self-contact --material-param "
                                "stretch_g_s2=230000 --material-param areal_density_g_m2=220");
  ASSERT_EQ(r.rc, 0) << r.err;
  r = gd(server_flag() + " create --garment towel --vertices 200 --material-param strech_g_s2=230000");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("strech_g_s2"), std::string::npos) << r.err;
  r = gd(server_flag() + " create --garment towel --vertices 200 --material-param poisson");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("NAME=VALUE"), std::string::npos) << r.err;
}

TEST_F(CliTest, TaskParamChangesTheGeneratedTaskLocallyAndAsAJob) {
  const auto dir = fresh_dir("cli_task_params");
  const std::string run = " run --garment towel --vertices 200 --task grasp --time-scale 0.5 --settle 0.1 "
                          "--no-self-contact --quiet --out ";
  auto sim_seconds = [&](const std::string& name) {
    return nlohmann::json::parse(slurp(dir / name / "summary.json")).at("sim_seconds").get<double>();
  };
  CliRun r = gd(run + (dir / "plain").string() + " --no-plots --threads 1");
  ASSERT_EQ(r.rc, 0) << r.err;
  // A hold 2 s longer (scaled by --time-scale 0.5: 1 s more simulated), locally and as a job.
  r = gd(run + (dir / "local").string() + " --no-plots --threads 1 --task-param hold_duration=5");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NEAR(sim_seconds("local") - sim_seconds("plain"), 1.0, 0.011);
  r = gd(server_flag() + run + (dir / "remote").string() + " --task-param hold_duration=5");
  ASSERT_EQ(r.rc, 0) << r.err;
  EXPECT_NEAR(sim_seconds("remote") - sim_seconds("plain"), 1.0, 0.011);
  // The summaries record the generated task's parameters.
  for (const char* name : {"local", "remote"}) {
    const auto tp = nlohmann::json::parse(slurp(dir / name / "summary.json")).at("task_params");
    EXPECT_DOUBLE_EQ(tp.at("hold_duration").get<double>(), 5.0) << name;
    EXPECT_DOUBLE_EQ(tp.at("time_scale").get<double>(), 0.5) << name;
    EXPECT_EQ(tp.size(), 29u) << name;
    EXPECT_DOUBLE_EQ(tp.at("grasp_yaw").get<double>(), 0.0) << name;
    EXPECT_DOUBLE_EQ(tp.at("grasp_inset_side").get<double>(), 0.0) << name;
    EXPECT_DOUBLE_EQ(tp.at("grasp_depth").get<double>(), 0.0) << name;  // "auto": 0 in pseudo mode
  }
  // An unknown name, or a bad value, locally and on the server: 2, naming it.
  r = gd(run + (dir / "bad1").string() + " --task-param hold_time=5");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("hold_time"), std::string::npos) << r.err;
  r = gd(server_flag() + run + (dir / "bad2").string() + " --task-param lift_duration=-1");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("lift_duration"), std::string::npos) << r.err;
}

TEST_F(CliTest, ExitCodes) {
  // Bad input refused by the server: 2, with its message.
  CliRun r = gd(server_flag() + " create --garment sock");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("sock"), std::string::npos) << r.err;
  r = gd(server_flag() + " step --ids nope");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("NOT_FOUND"), std::string::npos) << r.err;
  // Bad input found locally: 2.
  r = gd("step --ids a");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("--server"), std::string::npos) << r.err;
  r = gd(server_flag() + " run --backend cuda --out /tmp/unused");
  EXPECT_EQ(r.rc, 2) << r.err;
  // A flag or value the command line itself refuses: 2 as well, with what was wrong.
  r = gd("metrics --sim a.obj --real b.obj --surface 9000000");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("--surface"), std::string::npos) << r.err;
  r = gd("metrics --sim a.obj");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("--real"), std::string::npos) << r.err;
  r = gd("run --no-such-flag");
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_EQ(gd("--help").rc, 0);
  // No server there: 3.
  r = gd("--server 127.0.0.1:1 info");
  EXPECT_EQ(r.rc, 3) << r.err;
  EXPECT_NE(r.err.find("unreachable"), std::string::npos) << r.err;
}

TEST_F(CliTest, ATokenFileOrGdTokenFileReachesAServerThatNeedsTokens) {
  const auto dir = fresh_dir("cli_tokens");
  const std::string token = "cli-token-0123456789abcdef01234";
  std::ofstream(dir / "tokens") << token << "\n";
  std::ofstream(dir / "mine") << "# my token\n" << token << "\n";
  ServerProcessOptions o;
  o.binary = GD_SERVER_BINARY;
  o.data_dir = (dir / "data").string();
  o.log_file = (dir / "server.log").string();
  o.args = {"--auth-token-file", (dir / "tokens").string()};
  ServerProcess secured(o);
  const std::string at = "--server " + secured.address();
  CliRun r = gd(at + " info");
  EXPECT_EQ(r.rc, 3);
  EXPECT_NE(r.err.find("UNAUTHENTICATED"), std::string::npos) << r.err;
  r = gd(at + " --token-file " + (dir / "mine").string() + " info");
  EXPECT_EQ(r.rc, 0) << r.err;
  EXPECT_NE(r.out.find("backend cpu"), std::string::npos) << r.out;
  r = gd("GD_TOKEN_FILE=" + (dir / "mine").string() + " " + std::string(GD_CLI_BINARY) + " " + at + " info", true);
  EXPECT_EQ(r.rc, 0) << r.err;
  r = gd(at + " --token-file " + (dir / "missing").string() + " info");
  EXPECT_EQ(r.rc, 2);
  EXPECT_NE(r.err.find("--token-file: no file"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace gd::client_test

namespace gd::client_test {
namespace {

// `gd view`: the Python viewer on a scene of this server, its page rendered by headless Chromium
// into a PNG (--screenshot); an unknown scene is refused before any page. Needs the build's
// venv with the client and viser (scripts/build) and Chromium; skipped without them.
TEST_F(CliTest, ViewWritesAScreenshotOfTheScenesPage) {
  const std::filesystem::path python = std::filesystem::path(GD_BUILD_DIR) / "venv" / "bin" / "python";
  if (!std::filesystem::exists(python)) GTEST_SKIP() << "no " << python;
  if (std::system((python.string() + " -c 'import viser, garmentdynamics.viewer' >/dev/null 2>&1").c_str()) != 0)
    GTEST_SKIP() << "the venv has no viser or garmentdynamics.viewer";
  if (std::system("command -v chromium >/dev/null 2>&1") != 0) GTEST_SKIP() << "no chromium";
  CliRun r = gd(server_flag() + " create --garment towel --vertices 200");
  ASSERT_EQ(r.rc, 0) << r.err;
  const std::string id = lines(r.out).at(0);
  const auto png = fresh_dir("cli_view") / "towel.png";
  const std::string env = "GD_PYTHON=" + python.string() + " ";
  r = gd(env + GD_CLI_BINARY + " " + server_flag() + " view --ids " + id + " --port 0 --wait 4 --screenshot " +
             png.string(),
         true);
  ASSERT_EQ(r.rc, 0) << r.err;
  ASSERT_TRUE(std::filesystem::exists(png)) << r.out << r.err;
  EXPECT_GT(std::filesystem::file_size(png), 5000u);
  EXPECT_EQ(slurp(png).substr(1, 3), "PNG");
  r = gd(env + GD_CLI_BINARY + " " + server_flag() + " view --ids s-nope --port 0 --screenshot " + png.string(), true);
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("s-nope"), std::string::npos) << r.err;
  // A job: an unknown one is refused by the viewer's stream, saying so; neither scenes nor a job
  // is a usage error.
  r = gd(env + GD_CLI_BINARY + " " + server_flag() + " view --job j-nope --port 0 --screenshot " + png.string(), true);
  EXPECT_EQ(r.rc, 2) << r.err;
  EXPECT_NE(r.err.find("NOT_FOUND"), std::string::npos) << r.err;
  EXPECT_NE(r.err.find("j-nope"), std::string::npos) << r.err;
  r = gd(env + GD_CLI_BINARY + " " + server_flag() + " view --port 0", true);
  EXPECT_NE(r.rc, 0);
  EXPECT_NE(r.err.find("--job"), std::string::npos) << r.err;
}

}  // namespace
}  // namespace gd::client_test
