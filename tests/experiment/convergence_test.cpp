// The mesh-convergence study (gd converge): its surface sampling and distances against shapes
// whose distance is known in closed form, and one small study end to end (files, rows, refusals,
// its runs in parallel).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "experiment/convergence.h"
#include "experiment/temp_dir.h"
#include "sim/demand.h"
#include "sim/mesh.h"

namespace gd::experiment {
namespace {
namespace fs = std::filesystem;

sim::Mesh moved(sim::Mesh m, const sim::Vec3& by) {
  for (auto& p : m.x) p += by;
  return m;
}

TEST(SampleSurface, DrawsByAreaOnTheSurfaceAndRepeatsItsDraw) {
  // Two triangles of one plane, areas 1 and 3 (unit and three-unit right triangles side by side).
  const std::vector<sim::Vec3> x = {{0, 0, 0}, {1, 0, 0}, {0, 2, 0}, {3, 0, 0}, {1, 3, 0}};
  const std::vector<Eigen::Vector3i> tris = {{0, 1, 2}, {1, 3, 4}};  // areas 1 and 3
  const auto pts = sample_surface(x, tris, 40000);
  ASSERT_EQ(pts.size(), 40000u);
  int in_first = 0;
  for (const auto& p : pts) {
    EXPECT_EQ(p.z(), 0.0);
    // inside the first triangle: x >= 0, y >= 0, x + y/2 <= 1
    if (p.x() >= 0 && p.y() >= 0 && p.x() + 0.5 * p.y() <= 1 + 1e-12) ++in_first;
  }
  EXPECT_NEAR(in_first / 40000.0, 0.25, 0.01);  // binomial sd 0.002
  EXPECT_EQ(sample_surface(x, tris, 100), sample_surface(x, tris, 100)) << "a fixed seed draws the same points";
  EXPECT_THROW(sample_surface(x, {}, 10), sim::InputError);
}

TEST(SurfaceDistance, TheSameSurfaceMeshedTwiceIsAtZeroAndAShiftIsMeasuredExactly) {
  const sim::Mesh coarse = sim::make_rect(0.3, 0.2, 0.05), fine = sim::make_rect(0.3, 0.2, 0.007);
  ASSERT_GT(fine.x.size(), 10 * coarse.x.size());
  const SurfaceDistance same = surface_distance(coarse, fine, 5000);
  EXPECT_LT(same.cd, 1e-9) << "the same rectangle: every sample lies on the other mesh";
  EXPECT_LT(same.hd, 1e-9);
  const SurfaceDistance lifted = surface_distance(coarse, moved(fine, {0, 0, 0.01}), 5000);
  EXPECT_NEAR(lifted.cd, 0.01, 1e-9) << "a parallel copy 1 cm above";
  EXPECT_NEAR(lifted.hd, 0.01, 1e-9);
  // Slid 2 cm along x: the overlapping part is at zero, the 2 cm strips at each end up to 2 cm.
  const SurfaceDistance slid = surface_distance(coarse, moved(fine, {0.02, 0, 0}), 20000);
  EXPECT_NEAR(slid.hd, 0.02, 2e-4);  // the farthest sample lies within ~0.1 mm of the strip's end
  // Mean over a 30 cm length of a ramp 0..2 cm over the 2 cm strip: 0.02 * (0.02/0.3) / 2.
  EXPECT_NEAR(slid.cd, 0.02 * 0.02 / 0.3 / 2, 2e-4);
  EXPECT_NEAR(slid.cd_ab, slid.cd_ba, 2e-4) << "a slide is the same seen from either side";
  // Half the rectangle against the whole: every point of the half lies on the whole (0 one way),
  // the other half of the whole is up to 15 cm from it (a ramp: 3.75 cm on average over the whole).
  const sim::Mesh half = sim::make_rect(0.15, 0.2, 0.01);
  const SurfaceDistance part = surface_distance(half, fine, 20000);
  EXPECT_LT(part.cd_ab, 1e-9);
  EXPECT_LT(part.hd_ab, 1e-9);
  EXPECT_NEAR(part.cd_ba, 0.5 * 0.15 / 2, 1e-3);
  EXPECT_NEAR(part.hd_ba, 0.15, 1e-3);
  EXPECT_NEAR(part.cd, 0.5 * (part.cd_ab + part.cd_ba), 1e-12);
  EXPECT_EQ(part.hd, std::max(part.hd_ab, part.hd_ba));
}

ConvergenceConfig small_study(const std::string& out) {
  ConvergenceConfig c;
  c.base.garment = "towel";
  c.base.task = "grasp";
  c.base.scene.dt = 0.01;
  c.base.task_params.time_scale = 0.1;
  c.base.settle_after = 0;
  c.base.plots = false;
  c.base.out_dir = out;
  c.vertices = {300, 200};  // any order: the largest is the reference
  c.snapshot_interval = 0.5;
  c.samples = 4000;
  return c;
}

TEST(Convergence, ComparesEachRunWithTheFinestAtTheSameTimes) {
  const testing::TempDir tmp("convergence");
  const ConvergenceResult r = run_convergence(small_study(tmp.str()));
  for (const char* f : {"convergence.csv", "convergence.json", "v200/final.obj", "v300/final.obj", "v300/meshes"})
    EXPECT_TRUE(fs::exists(tmp / f)) << f;
  ASSERT_GE(r.rows.size(), 3u) << "t = 0, at least one snapshot, the final shapes";
  EXPECT_TRUE(r.rows.back().final);
  EXPECT_EQ(r.rows.front().t, 0.0);
  // At t = 0 both towels lie flat where they were placed: the same rectangle, meshed twice.
  EXPECT_LT(r.rows.front().cd, 1e-3);
  for (const ShapeDistance& d : r.rows) {
    EXPECT_LT(d.vertices, r.summary["reference_vertices"].get<int>());
    EXPECT_TRUE(std::isfinite(d.cd) && std::isfinite(d.hd));
    EXPECT_LE(d.cd, d.hd + 1e-12) << "a mean is at most the maximum";
  }
  const auto json = nlohmann::json::parse(std::ifstream(tmp / "convergence.json"));
  EXPECT_EQ(json["runs"].size(), 2u);
  EXPECT_EQ(json["rows"].size(), r.rows.size());
}

// With two draws per resolution (two meshes 2.5% apart in vertex count) each row is the mean over
// the four (run draw, finest draw) pairs, and carries the spread between the two draws of its
// resolution and of the finest; before the grasp every mesh lies as placed, so that spread is
// (nearly) zero there.
TEST(Convergence, DrawsMeasureEachResolutionsSpreadBesideTheDistance) {
  EXPECT_EQ(draw_vertex_factor(0), 1.0);
  EXPECT_EQ(draw_vertex_factor(1), 1.025);
  EXPECT_EQ(draw_vertex_factor(2), 0.975);
  EXPECT_EQ(draw_vertex_factor(3), 1.05);
  const testing::TempDir tmp("convergence_draws");
  ConvergenceConfig c = small_study(tmp.str());
  c.draws = 2;
  const ConvergenceResult r = run_convergence(c);
  for (const char* f : {"v200/final.obj", "v200_d1/final.obj", "v300/final.obj", "v300_d1/final.obj"})
    ASSERT_TRUE(fs::exists(tmp / f)) << f;
  ASSERT_GE(r.rows.size(), 3u);
  EXPECT_EQ(r.rows.front().t, 0.0);
  EXPECT_LT(r.rows.front().cd_floor, 1e-3) << "both draws lie as placed before the grasp";
  EXPECT_LT(r.rows.front().ref_cd_floor, 1e-3);
  for (const ShapeDistance& d : r.rows) {
    EXPECT_TRUE(std::isfinite(d.cd_floor) && std::isfinite(d.ref_cd_floor) && std::isfinite(d.hd_floor)) << d.t;
    EXPECT_LE(d.cd_floor, d.hd_floor + 1e-12);
  }
  // The final row, recomputed from the four final shapes.
  const ShapeDistance& fin = r.rows.back();
  ASSERT_TRUE(fin.final);
  const sim::Mesh a0 = sim::read_obj(tmp / "v200/final.obj"), a1 = sim::read_obj(tmp / "v200_d1/final.obj");
  const sim::Mesh b0 = sim::read_obj(tmp / "v300/final.obj"), b1 = sim::read_obj(tmp / "v300_d1/final.obj");
  double cd = 0, hd = 0;
  for (const sim::Mesh* a : {&a0, &a1})
    for (const sim::Mesh* b : {&b0, &b1}) {
      const SurfaceDistance d = surface_distance(*a, *b, c.samples);
      cd += d.cd / 4, hd += d.hd / 4;
    }
  EXPECT_NEAR(fin.cd, cd, 1e-12);
  EXPECT_NEAR(fin.hd, hd, 1e-12);
  EXPECT_NEAR(fin.cd_floor, surface_distance(a0, a1, c.samples).cd, 1e-12);
  EXPECT_NEAR(fin.ref_cd_floor, surface_distance(b0, b1, c.samples).cd, 1e-12);
  const auto json = nlohmann::json::parse(std::ifstream(tmp / "convergence.json"));
  EXPECT_EQ(json["runs"].size(), 4u);
  EXPECT_EQ(json["draws"].get<int>(), 2);
  EXPECT_EQ(json["runs"][1]["resolution"].get<int>(), 200);
  EXPECT_GT(json["runs"][1]["vertices"].get<int>(), json["runs"][0]["vertices"].get<int>()) << "2.5% more";
}

TEST(Convergence, RefusesWhatItCannotStudy) {
  const testing::TempDir tmp("convergence_refusals");
  ConvergenceConfig one = small_study(tmp.str());
  one.vertices = {300, 300};
  EXPECT_THROW(run_convergence(one), sim::InputError) << "one distinct vertex count";
  ConvergenceConfig obj = small_study(tmp.str());
  obj.base.garment = "/tmp/shirt.obj";
  EXPECT_THROW(run_convergence(obj), sim::InputError) << "an imported mesh cannot be remeshed";
  ConvergenceConfig none = small_study(tmp.str());
  none.draws = 0;
  EXPECT_THROW(run_convergence(none), sim::InputError) << "no draw";
  ConvergenceConfig small = small_study(tmp.str());
  small.draws = 3;  // draw 2 of 200 vertices: 195, below what a garment is meshed with
  EXPECT_THROW(run_convergence(small), sim::InputError) << "a draw below the garments' vertex range";
  ConvergenceConfig no_jobs = small_study(tmp.str());
  no_jobs.jobs = 0;
  EXPECT_THROW(run_convergence(no_jobs), sim::InputError) << "no job to run the runs";
  ConvergenceConfig two_counts = small_study(tmp.str());
  two_counts.dts = {0.01, 0.005};
  EXPECT_THROW(run_convergence(two_counts), sim::InputError) << "a time-step study runs one vertex count";
  ConvergenceConfig one_dt = small_study(tmp.str());
  one_dt.vertices = {200};
  one_dt.dts = {0.01, 0.01};
  EXPECT_THROW(run_convergence(one_dt), sim::InputError) << "one distinct time step";
  ConvergenceConfig bad_dt = one_dt;
  bad_dt.dts = {0.01, -0.005};
  EXPECT_THROW(run_convergence(bad_dt), sim::InputError) << "a negative time step";
  EXPECT_FALSE(fs::exists(tmp / "v200")) << "refused before running anything";
  EXPECT_FALSE(fs::exists(tmp / "dt10ms"));
}

// A time-step study (--dts): one resolution at two steps, each shape compared with the smaller
// step's run at the same time. Steps of 10 and 7.5 ms write their snapshots at different steps
// (0.5 s and 0.5025 s), which are matched within half the larger step.
TEST(Convergence, ATimeStepStudyComparesEachStepWithTheSmallestAtTheSameTimes) {
  const testing::TempDir tmp("convergence_dts");
  ConvergenceConfig c = small_study(tmp.str());
  c.vertices = {200};
  c.dts = {0.0075, 0.01};  // any order: the smallest is the reference
  const ConvergenceResult r = run_convergence(c);
  for (const char* f : {"dt10ms/final.obj", "dt7.5ms/final.obj", "dt7.5ms/meshes", "convergence.csv"})
    ASSERT_TRUE(fs::exists(tmp / f)) << f;
  EXPECT_EQ(r.summary["axis"], "dt");
  EXPECT_EQ(r.summary["reference_dt"].get<double>(), 0.0075);
  int snapshots = 0;  // the reference's shapes along the run, t = 0 included
  for (const auto& e : fs::directory_iterator(tmp / "dt7.5ms/meshes")) snapshots += e.path().extension() == ".obj";
  ASSERT_GE(snapshots, 3);
  ASSERT_EQ(static_cast<int>(r.rows.size()), snapshots + 1) << "every snapshot matched, and the final shapes";
  for (const ShapeDistance& d : r.rows) {
    EXPECT_EQ(d.dt, 0.01);
    EXPECT_EQ(d.vertices, r.summary["reference_vertices"].get<int>()) << "the same mesh at both steps";
    EXPECT_TRUE(std::isfinite(d.cd) && std::isfinite(d.hd));
  }
  EXPECT_LT(r.rows.front().cd, 1e-9) << "at t = 0 the same mesh lies as placed at both steps";
  const ShapeDistance& fin = r.rows.back();
  ASSERT_TRUE(fin.final);
  const SurfaceDistance d = surface_distance(sim::read_obj(tmp / "dt10ms/final.obj"),
                                             sim::read_obj(tmp / "dt7.5ms/final.obj"), c.samples);
  EXPECT_EQ(fin.cd, d.cd);
  EXPECT_GT(fin.cd, 1e-6) << "the steps moved the lifted towel differently";
  std::ifstream csv(tmp / "convergence.csv");
  std::string header;
  std::getline(csv, header);
  EXPECT_NE(header.find(",dt,reference_dt"), std::string::npos) << header;
}

// --jobs: the study's four runs (two resolutions, two draws each), one thread each, three at a
// time, give the rows of one run after another to the last bit (each run is deterministic on one
// thread, and the rows are computed after all of them); the runs' progress reports show them
// overlapping, never more than three at once.
TEST(Convergence, JobsRunTheRunsAtOnceWithTheResultsOfOneAfterAnother) {
  const testing::TempDir serial_dir("convergence_serial"), jobs_dir("convergence_jobs");
  ConvergenceConfig serial = small_study(serial_dir.str());
  serial.draws = 2;
  serial.base.scene.threads = 1;
  ConvergenceConfig jobs = serial;
  jobs.base.out_dir = jobs_dir.str();
  jobs.jobs = 3;
  const ConvergenceResult a = run_convergence(serial);
  std::vector<std::pair<long, long>> span(4, {-1, -1});  // per run: its first and last report
  long calls = 0;
  const ConvergenceResult b = run_convergence(jobs, [&](int run, int runs, int, double, double) {
    ASSERT_EQ(runs, 4);
    if (span[run].first < 0) span[run].first = calls;
    span[run].second = calls++;
  });
  ASSERT_EQ(a.rows.size(), b.rows.size());
  for (size_t i = 0; i < a.rows.size(); ++i) {
    EXPECT_EQ(a.rows[i].vertices, b.rows[i].vertices);
    EXPECT_EQ(a.rows[i].t, b.rows[i].t);
    EXPECT_EQ(a.rows[i].cd, b.rows[i].cd) << i;
    EXPECT_EQ(a.rows[i].hd, b.rows[i].hd) << i;
    EXPECT_EQ(a.rows[i].cd_floor, b.rows[i].cd_floor) << i;
    EXPECT_EQ(a.rows[i].ref_cd_floor, b.rows[i].ref_cd_floor) << i;
  }
  ASSERT_EQ(b.summary["runs"].size(), 4u);
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(b.summary["runs"][k]["vertices"], a.summary["runs"][k]["vertices"]) << "the runs in the same order";
    EXPECT_EQ(b.summary["runs"][k]["draw"].get<int>(), k % 2);
  }
  EXPECT_EQ(b.summary["jobs"].get<int>(), 3);
  EXPECT_EQ(b.summary["threads_per_run"].get<int>(), 1);
  int most = 0;  // runs between their first and last report at one call
  for (long c = 0; c < calls; ++c) {
    int open = 0;
    for (const auto& [first, last] : span) open += first <= c && c <= last;
    most = std::max(most, open);
  }
  EXPECT_GE(most, 2) << "the runs overlap";
  EXPECT_LE(most, 3) << "at most --jobs at once";
}

}  // namespace
}  // namespace gd::experiment
