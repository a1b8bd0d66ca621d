// Every garment type survives Grasp, Fold and Fling with self-contact on: no intersecting
// triangle pairs, no non-finite state, and the physical outcome the task is for.
#include <gtest/gtest.h>

#include <cstdlib>
#include <filesystem>
#include <set>
#include <string>
#include <tuple>

#include "experiment/experiment.h"
#include "experiment/temp_dir.h"
#include "garments/generator.h"
#include "sim/log.h"

namespace gd::experiment {
namespace {

using Case = std::tuple<std::string, std::string>;  // garment type, task

class GarmentTask : public ::testing::TestWithParam<Case> {};

TEST_P(GarmentTask, SurvivesWithItsPhysicalOutcome) {
  const auto& [garment, task] = GetParam();
  // Two-layer garments fold at 2000 vertices (gd run's default): at ~400 the coarse membrane
  // cannot crease across its edges and holds the folded stack 10-19 cm tall, a limit of the mesh,
  // not of the motion (docs/validation.md, "The two-layer folds at 2000 vertices"). The other
  // cases run at ~400 vertices. The hoodie fold lays the hood over first and then brings the hem
  // up to the shoulders (TaskParams::tuck_hood; docs/validation.md, "The hoodie fold"); it is the
  // longest case (949 steps, ~900 s on one core).
  static const std::set<std::string> kFine = {"tshirt_fold", "long_sleeve_fold", "dress_fold", "hoodie_fold",
                                              "coat_fold"};
  const std::string name = garment + "_" + task;
  ExperimentConfig c;
  c.garment = garment;
  c.task = task;
  // GD_TEST_VERTICES overrides the resolution of every case.
  c.vertices = std::getenv("GD_TEST_VERTICES") ? std::atoi(std::getenv("GD_TEST_VERTICES"))
               : kFine.count(name)            ? 2000
                                              : 400;
  c.scene.dt = 0.01;
  c.task_params.time_scale = 0.3;
  // The page turn itself takes 2 s (3.5 s at time scale 1): turned over in 1 s, at up to 1.7 m/s,
  // the coat's folded half landed askew in 4 of 5 runs that differed by a centimetre of grasp or
  // 15% of speed; in 2 s it folded flat in all 3 (docs/validation.md).
  c.task_params.fold_duration = 2.0 / c.task_params.time_scale;
  c.settle_after = 0.3;
  c.plots = false;
  const testing::TempDir tmp("garment_task_" + garment + "_" + task);
  c.out_dir = tmp.str();
  ASSERT_TRUE(c.scene.self_contact);
  const ExperimentResult r = run_experiment(c);
  const auto& s = r.summary;
  const auto& fin = s["final"];
  gd::log().info("{}/{}: {} vertices, {} steps, {:.1f} s wall, max intersecting pairs {}, untangling {}, final {}",
                 garment, task, s["vertices"].get<int>(), s["steps"].get<int>(), s["wall_seconds"].get<double>(),
                 s["intersecting_pairs_max"].get<int>(), s["untangle_runs"].get<int>(), fin.dump());
  ASSERT_FALSE(s["failed"].get<bool>()) << s["failure"];
  EXPECT_EQ(s["intersecting_pairs_max"].get<int>(), 0);
  const double length = s["garment_length"], width = s["garment_width"];
  if (task == "grasp") {
    EXPECT_GT(fin["min_z"].get<double>(), 0.01) << "the garment should hang clear of the table";
  } else if (task == "fold") {
    EXPECT_LT(fin["mean_z"].get<double>(), 0.03) << "the folded garment should lie on the table";
    EXPECT_LT(fin["max_z"].get<double>(), 0.1);
    const double ratio = fin["extent_x"].get<double>() / length;
    EXPECT_GT(ratio, 0.35) << "folded length / length";
    EXPECT_LT(ratio, 0.75) << "folded length / length";
  } else {  // fling
    EXPECT_GT(fin["min_z"].get<double>(), 0.01) << "the garment should end in the air";
    EXPECT_GT(fin["extent_y"].get<double>(), 0.4 * width) << "the garment should hang spread";
  }
}

std::string case_name(const ::testing::TestParamInfo<Case>& info) {
  return std::get<0>(info.param) + "_" + std::get<1>(info.param);
}

INSTANTIATE_TEST_SUITE_P(AllTypes, GarmentTask,
                         ::testing::Combine(::testing::ValuesIn(garments::garment_types()),
                                            ::testing::Values("grasp", "fold", "fling")),
                         case_name);

}  // namespace
}  // namespace gd::experiment
