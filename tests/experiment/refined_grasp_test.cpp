// ExperimentConfig::refine_grasp_edge (gd run --refine-grasp): the run's garment is refined near
// the points its task grasps (the shoulders; the fold's hem corners too) and nowhere else, the
// run goes through with it, and the summary says so.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "experiment/experiment.h"
#include "experiment/temp_dir.h"
#include "sim/demand.h"

namespace gd::experiment {
namespace {

ExperimentConfig refined_towel(const std::string& task, const std::string& out) {
  ExperimentConfig c;
  c.garment = "towel";
  c.task = task;
  c.vertices = 300;
  c.scene.dt = 0.01;
  c.task_params.time_scale = 0.1;
  c.settle_after = 0;
  c.plots = false;
  c.out_dir = out;
  c.refine_grasp_edge = 0.01;
  c.refine_grasp_radius = 0.05;
  return c;
}

/// The longest edge of the triangles whose centroid lies within r of p (0 if none).
double longest_edge_near(const garments::Garment& g, const sim::Vec3& p, double r) {
  double longest = 0;
  for (const auto& f : g.mesh.tris) {
    const sim::Vec3 c = (g.mesh.x[f[0]] + g.mesh.x[f[1]] + g.mesh.x[f[2]]) / 3.0;
    if ((c - p).norm() > r) continue;
    for (int k = 0; k < 3; ++k) longest = std::max(longest, (g.mesh.x[f[k]] - g.mesh.x[f[(k + 1) % 3]]).norm());
  }
  return longest;
}

TEST(RefinedGrasp, RefinesNearTheTasksGraspPointsOnly) {
  const testing::TempDir tmp("refined_grasp_mesh");
  ExperimentConfig grasp = refined_towel("grasp", tmp.str());
  ExperimentConfig plain = grasp;
  plain.refine_grasp_edge = 0;
  const garments::Garment coarse = make_experiment_garment(plain);
  const garments::Garment fine = make_experiment_garment(grasp);
  const garments::Landmarks& l = coarse.landmarks;
  ASSERT_GT(longest_edge_near(coarse, l.left_shoulder, 0.05), 0.02) << "a 300-vertex towel's edges are ~3 cm";
  EXPECT_LE(longest_edge_near(fine, l.left_shoulder, 0.05), 0.01 + 1e-12);
  EXPECT_LE(longest_edge_near(fine, l.right_shoulder, 0.05), 0.01 + 1e-12);
  EXPECT_GT(longest_edge_near(fine, l.left_hem, 0.05), 0.02) << "a grasp holds the shoulders only";
  ExperimentConfig fold = grasp;
  fold.task = "fold";
  EXPECT_LE(longest_edge_near(make_experiment_garment(fold), l.left_hem, 0.05), 0.01 + 1e-12)
      << "a fold also grasps the hem corners";
  EXPECT_GT(fine.mesh.x.size(), coarse.mesh.x.size());
}

TEST(RefinedGrasp, RunsAndSaysSoInTheSummaryAndABadEdgeIsRefused) {
  const testing::TempDir tmp("refined_grasp_run");
  ExperimentConfig c = refined_towel("grasp", tmp.str());
  const ExperimentResult r = run_experiment(c);
  EXPECT_FALSE(r.summary.value("failed", false));
  EXPECT_EQ(r.summary["intersecting_pairs_max"].get<int>(), 0);
  EXPECT_EQ(r.summary["refine_grasp"]["edge_m"].get<double>(), 0.01);
  EXPECT_EQ(r.summary["refine_grasp"]["radius_m"].get<double>(), 0.05);
  EXPECT_EQ(r.summary["vertices"].get<int>(), static_cast<int>(make_experiment_garment(c).mesh.x.size()));
  EXPECT_GT(r.summary["final"]["max_z"].get<double>(), 0.1) << "the grasp lifted the refined towel";
  c.refine_grasp_edge = 5e-4;
  EXPECT_THROW(run_experiment(c), sim::InputError) << "an edge below 1 mm";
  c.refine_grasp_edge = 0.01;
  c.refine_grasp_radius = 0;
  EXPECT_THROW(run_experiment(c), sim::InputError) << "no radius";
}

}  // namespace
}  // namespace gd::experiment
