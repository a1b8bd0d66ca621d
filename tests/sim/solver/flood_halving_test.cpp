// The self-contact pair budget (Solver::find_candidates, solver/candidates.h): a motion whose broad phase would
// hold more pairs than the budget is halved until it fits. A wild Newton direction once swept
// boxes across a 4000-vertex T-shirt and one query held 17 million pairs (19 GB, out of memory);
// ordinary steps stay far below the default budget and are untouched.
#include <gtest/gtest.h>

#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/contact/broad_phase.h"
#include "sim/scene.h"
#include "sim/solver/self_contact.h"

namespace gd::sim {
namespace {

std::unique_ptr<Scene> sheet_with_self_contact(Mesh* mesh, std::size_t pair_budget) {
  *mesh = make_rect(0.3, 0.3, 0.01);
  for (Vec3& p : mesh->x) p.z() += 0.3;
  SceneOptions o;
  o.self_contact = true;
  o.dt = 0.01;
  o.self_contact_pair_budget = pair_budget;
  return Scene::create(*mesh, MaterialLibrary::load_default().get("cotton"), o);
}

std::vector<int> edge_vertices(const Mesh& m) {
  std::vector<int> out;
  for (int i = 0; i < static_cast<int>(m.x.size()); ++i)
    if (m.x[i].y() < 1e-9) out.push_back(i);
  return out;
}

/// Releases the sheet (1098 vertices) stretched to 1.6 times its size: its first Newton directions
/// move the rim by centimetres, several edges, and their queries hold over 200 pairs per vertex.
std::unique_ptr<Scene> released_stretched_sheet(Mesh* m, std::size_t pair_budget) {
  auto s = sheet_with_self_contact(m, pair_budget);
  const Vec3 c(0.15, 0.15, 0.3);
  std::vector<Vec3> x = s->positions();
  for (Vec3& p : x) p = c + 1.6 * (p - c);
  s->set_state(x, std::vector<Vec3>(x.size(), Vec3::Zero()));
  return s;
}

// With a budget of 20 pairs per vertex the snapping sheet's wild steps are halved until their
// queries fit; the candidates stay within the budget, the sheet still relaxes, and nothing
// intersects.
TEST(FloodHalving, AStretchedSheetSnapsBackWithinASmallBudget) {
  Mesh m;
  const std::size_t budget = 20 * 31 * 31;
  auto s = released_stretched_sheet(&m, budget);
  int halvings = 0;
  for (int k = 0; k < 11; ++k) {
    ASSERT_TRUE(s->step()) << s->failure();
    const StepStats& st = s->last_stats();
    halvings += st.flood_halvings;
    EXPECT_LE(static_cast<std::size_t>(st.candidates), budget) << "step " << k;
    EXPECT_EQ(st.intersecting_pairs, 0) << "step " << k;
    if (k == 0) EXPECT_GE(st.flood_halvings, 1) << "the first direction sweeps ~9 cm";
  }
  // Released: the 60% strain is gone (the sheet overshoots and crumples, as a released rubber
  // sheet would).
  EXPECT_LT(s->max_strain(), 0.1) << halvings << " halvings";
}

// The default budget (200 pairs per vertex) halves the same release's widest motions too (a
// settled or hanging sheet's queries hold a few pairs per vertex), and the sheet relaxes as well.
TEST(FloodHalving, TheDefaultBudgetHalvesTheWidestMotions) {
  Mesh m;
  auto s = released_stretched_sheet(&m, 0);
  int halvings = 0;
  for (int k = 0; k < 11; ++k) {
    ASSERT_TRUE(s->step()) << s->failure();
    halvings += s->last_stats().flood_halvings;
    EXPECT_EQ(s->last_stats().intersecting_pairs, 0) << "step " << k;
  }
  EXPECT_GE(halvings, 1);
  EXPECT_EQ(s->flood_halvings(), halvings) << "the scene's count is the steps' sum";
  EXPECT_LT(s->max_strain(), 0.1) << halvings << " halvings";
}

// A sheet hanging from its edge and swinging down: never halved, and bit for bit the steps of a
// scene without a budget.
TEST(FloodHalving, OrdinaryStepsAreUntouched) {
  Mesh m;
  auto s = sheet_with_self_contact(&m, 0);
  auto unbounded = sheet_with_self_contact(&m, kNoPairLimit);
  s->pin(edge_vertices(m));
  unbounded->pin(edge_vertices(m));
  for (int k = 0; k < 30; ++k) {
    ASSERT_TRUE(s->step()) << s->failure();
    ASSERT_TRUE(unbounded->step()) << unbounded->failure();
    EXPECT_EQ(s->last_stats().flood_halvings, 0) << "step " << k;
  }
  EXPECT_EQ(s->positions(), unbounded->positions());
}

// A diverging motion (every vertex thrown at 1e5 m/s: the kind of direction a pressed, ill-
// conditioned solve once gave in robot mode) is halved until no vertex moves farther than the
// contact distance before the broad phase may answer without a bound, so the query stays that of
// a garment at rest instead of sweeping every pair (10.7 million pairs and out of memory with ten
// halvings).
TEST(FloodHalving, ADivergingMotionIsHalvedDownToTheContactDistance) {
  Mesh m;
  const std::size_t budget = 20 * 31 * 31;
  auto s = sheet_with_self_contact(&m, budget);
  std::vector<Vec3> v(s->vertex_count());
  for (size_t i = 0; i < v.size(); ++i)  // neighbours thrown apart in all directions
    v[i] = 1e5 * Vec3(std::sin(1.3 * i), std::cos(2.1 * i), std::sin(0.7 * i + 1));
  s->set_state(s->positions(), v);
  s->step();
  const StepStats& st = s->last_stats();
  // 1e5 m/s for 0.01 s is 1 km: about 20 halvings down to the 1 mm contact distance.
  EXPECT_GT(st.flood_halvings, SelfContact::kMaxFloodHalvings) << "halved on past the old ten";
  EXPECT_LE(static_cast<std::size_t>(st.candidates), budget) << "no unbounded query of a wild motion";
}

}  // namespace
}  // namespace gd::sim
