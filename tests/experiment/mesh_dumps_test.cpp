// `mesh_interval` (gd run --mesh-every) writes the garment as OBJ files at the requested times.
#include <gtest/gtest.h>

#include <filesystem>
#include <set>
#include <string>

#include "experiment/experiment.h"
#include "experiment/temp_dir.h"
#include "sim/demand.h"
#include "sim/mesh.h"

namespace gd::experiment {
namespace {
namespace fs = std::filesystem;

ExperimentConfig small_towel_grasp(const std::string& out) {
  ExperimentConfig c;
  c.garment = "towel";
  c.task = "grasp";
  c.vertices = 200;
  c.scene.dt = 0.01;
  c.scene.self_contact = false;  // only the files are under test here
  c.task_params.time_scale = 0.1;
  c.settle_after = 0;
  c.plots = false;
  c.out_dir = out;
  return c;
}

TEST(MeshDumps, WritesOneObjPerIntervalWithTheGarmentsTopology) {
  const testing::TempDir tmp("mesh_dumps");
  ExperimentConfig c = small_towel_grasp(tmp.str());
  c.mesh_interval = 0.25;
  const ExperimentResult r = run_experiment(c);
  const double end = r.summary["sim_seconds"];
  std::set<std::string> names;
  for (const auto& e : fs::directory_iterator(tmp.str() + "/meshes")) names.insert(e.path().filename().string());
  ASSERT_FALSE(names.empty());
  EXPECT_EQ(*names.begin(), "t_000000.obj");
  EXPECT_TRUE(names.count("t_000250.obj")) << "a mesh at t = 0.25 s";
  EXPECT_TRUE(names.count("t_000500.obj"));
  // one at t = 0 and one per interval after it (the step that reaches each multiple)
  EXPECT_NEAR(static_cast<double>(names.size()), 1 + std::floor(end / 0.25 + 1e-9), 1.0);
  const sim::Mesh first = sim::read_obj(tmp.str() + "/meshes/t_000000.obj");
  const sim::Mesh later = sim::read_obj(tmp.str() + "/meshes/t_000500.obj");
  EXPECT_EQ(first.x.size(), static_cast<size_t>(r.summary["vertices"].get<int>()));
  EXPECT_EQ(later.tris, first.tris);
  EXPECT_NE(later.x, first.x) << "the garment moved";
}

TEST(MeshDumps, OffByDefaultAndANegativeIntervalIsRefused) {
  const testing::TempDir tmp("mesh_dumps_off");
  ExperimentConfig c = small_towel_grasp(tmp.str());
  run_experiment(c);
  EXPECT_FALSE(fs::exists(tmp.str() + "/meshes"));
  c.mesh_interval = -1;
  try {
    run_experiment(c);
    FAIL() << "a negative mesh_interval was accepted";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("mesh_interval"), std::string::npos);
  }
}

}  // namespace
}  // namespace gd::experiment
