// The Newton step's reach limit with self-contact (Solver::limit_reach): a Newton direction that
// reaches across the garment made one broad phase overlap nearly every pair (millions of pairs,
// 19 GB, at a 4000-vertex T-shirt fold). A step is scaled to at most a few mean edges per
// coordinate before its broad phase, so the candidates stay local, and ordinary steps are untouched.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/scene.h"

namespace gd::sim {
namespace {

std::unique_ptr<Scene> sheet_with_self_contact(Mesh* mesh) {
  *mesh = make_rect(0.3, 0.3, 0.01);
  for (Vec3& p : mesh->x) p.z() += 0.3;
  SceneOptions o;
  o.self_contact = true;
  o.dt = 0.01;
  return Scene::create(*mesh, MaterialLibrary::load_default().get("cotton"), o);
}

std::vector<int> edge_vertices(const Mesh& m) {
  std::vector<int> out;
  for (int i = 0; i < static_cast<int>(m.x.size()); ++i)
    if (m.x[i].y() < 1e-9) out.push_back(i);
  return out;
}

// A sheet released stretched to 1.6 times its size snaps back: its first Newton direction moves
// the rim by ~9 cm, three times the reach (three 1 cm edges). The steps are scaled down, the
// strain is still gone within a few steps, and no broad phase along them sees more than a
// sliver of the sheet's pairs.
TEST(NewtonReach, AStretchedSheetSnapsBackInShortSteps) {
  Mesh m;
  auto s = sheet_with_self_contact(&m);
  const Vec3 c(0.15, 0.15, 0.3);
  std::vector<Vec3> x = s->positions();
  for (Vec3& p : x) p = c + 1.6 * (p - c);
  s->set_state(x, std::vector<Vec3>(x.size(), Vec3::Zero()));
  ASSERT_TRUE(s->step()) << s->failure();
  const StepStats& st = s->last_stats();
  EXPECT_GE(st.reach_limited, 1);
  const double all_vf = double(s->vertex_count()) * m.tris.size();
  EXPECT_LT(st.max_candidates, 0.05 * all_vf) << st.max_candidates << " candidates of " << all_vf << " pairs";
  int limited = st.reach_limited;
  for (int k = 0; k < 10; ++k) {
    ASSERT_TRUE(s->step()) << s->failure();
    limited += s->last_stats().reach_limited;
    EXPECT_EQ(s->last_stats().intersecting_pairs, 0);
  }
  // Released: the 60% strain is gone (the sheet overshoots and crumples, as a released rubber sheet would).
  EXPECT_LT(s->max_strain(), 0.1) << limited << " steps scaled";
}

// A sheet hanging from its edge and swinging down: no Newton step comes near the limit.
TEST(NewtonReach, OrdinaryStepsAreUntouched) {
  Mesh m;
  auto s = sheet_with_self_contact(&m);
  s->pin(edge_vertices(m));
  for (int k = 0; k < 30; ++k) {
    ASSERT_TRUE(s->step()) << s->failure();
    EXPECT_EQ(s->last_stats().reach_limited, 0) << "step " << k;
  }
}

}  // namespace
}  // namespace gd::sim
