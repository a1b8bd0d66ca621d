// A sheet landing on the table: the table's CCD bound is applied per vertex (Solver::cut_at_table),
// so the few vertices that reach the table first no longer shorten every other vertex's step. The
// landing keeps every vertex above the table and every step meets the Newton rule in few
// iterations.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/scene.h"

namespace gd::sim {
namespace {

struct Landing {
  int newton = 0, steps = 0, converged = 0;
  double min_alpha = 1, min_z = 1;
};

/// A 0.3 m cotton square tilted by `tilt` (rad) about the y axis, its lowest edge `gap` above the
/// table, falling at 0.6 m/s: one edge lands first, the rest follows over a few steps.
Landing land(double tilt, double gap) {
  Mesh m = make_rect(0.3, 0.3, 0.01);
  for (Vec3& p : m.x) p.z() = gap + std::sin(tilt) * p.x();
  SceneOptions o;
  auto s = Scene::create(m, MaterialLibrary::load_default().get("cotton"), o);
  s->set_state(s->positions(), std::vector<Vec3>(m.x.size(), Vec3(0, 0, -0.6)));
  Landing r;
  for (int k = 0; k < 30; ++k) {
    EXPECT_TRUE(s->step()) << s->failure();
    const StepStats& st = s->last_stats();
    r.newton += st.newton_iters;
    r.converged += st.converged ? 1 : 0;
    r.min_alpha = std::min(r.min_alpha, st.min_alpha);
    ++r.steps;
    for (const Vec3& p : s->positions()) r.min_z = std::min(r.min_z, p.z());
  }
  return r;
}

TEST(TableLanding, TiltedSheetsLandInFewNewtonIterations) {
  for (double tilt : {0.02, 0.05, 0.1}) {
    for (double gap : {0.002, 0.004}) {
      const Landing r = land(tilt, gap);
      SCOPED_TRACE(testing::Message() << "tilt " << tilt << " gap " << gap);
      EXPECT_GT(r.min_z, 0.0);
      EXPECT_EQ(r.converged, r.steps);
      // With the table's bound taken over the whole step, the first vertices down cut every
      // step of the landing to alpha 0.25-0.34 (47-73 Newton iterations over the 30 steps);
      // cut per vertex, no step is shortened (alpha 1, 45-59 iterations).
      EXPECT_GE(r.min_alpha, 0.5);
      EXPECT_LE(r.newton, 2 * r.steps);
    }
  }
}

}  // namespace
}  // namespace gd::sim
