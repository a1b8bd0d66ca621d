// SelfContact, the host side of self-contact: a pair query keeps the broad phase's answer (the
// pairs within dhat + slack along the motion, as a fresh brute-force query reports them) and
// refuses non-finite positions; the intersection count reuses its triangle query while the cloth
// stays within slack/2 of it, up to a common translation, and agrees with a fresh instance. (The
// candidates the solver takes from an answer for each motion: candidates_test.cpp.)
#include "sim/solver/self_contact.h"

#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <vector>

#include "sim/demand.h"
#include "sim/solver/folded_sheet.h"

namespace gd::sim {
namespace {

using namespace testing_fold;

constexpr Real kDhat = 1e-3;

std::set<Quad> answer(const SceneData& d, const ContactCandidates& raw) {
  const std::vector<Eigen::Vector2i> edges = sorted_edges(d);
  std::set<Quad> s;
  for (const auto& p : raw.vf) s.insert({0, p[0], d.tris[3 * p[1]], d.tris[3 * p[1] + 1], d.tris[3 * p[1] + 2]});
  for (const auto& p : raw.ee) s.insert({1, edges[p[0]][0], edges[p[0]][1], edges[p[1]][0], edges[p[1]][1]});
  return s;
}

TEST(SelfContactQuery, KeepsTheBroadPhasesAnswerWithItsSlack) {
  const Folded f = folded_sheet(1.5e-3);
  SelfContact sc(f.data, kDhat);
  const std::vector<double> x1 = jiggled(f.x, 0.3 * kDhat, 3);
  ASSERT_TRUE(sc.query(f.x, x1));
  EXPECT_EQ(sc.pair_queries(), 1);
  EXPECT_EQ(sc.raw_pairs(), static_cast<int>(sc.raw().vf.size() + sc.raw().ee.size()));
  const std::set<Quad> need = fresh(f.data, f.x, x1, kDhat + sc.slack());
  ASSERT_GT(need.size(), 100u);
  EXPECT_EQ(answer(f.data, sc.raw()), need);
  // A bound below the answer's size: refused, nothing kept.
  EXPECT_FALSE(sc.query(f.x, x1, need.size() / 2));
  EXPECT_EQ(sc.raw_pairs(), 0);
  EXPECT_EQ(sc.pair_queries(), 2);
  std::vector<double> bad = f.x;
  bad[0] = std::nan("");
  EXPECT_THROW(sc.query(f.x, bad), InputError);
}

TEST(SelfContactBroadPhase, IntersectionCountReusesItsQueryAndAgreesWithAFreshOne) {
  Folded f = folded_sheet(1.5e-3);
  // Push two flap vertices 3 mm down through the base, off the base's grid lines (the flap lies
  // right above the base's vertices): their triangles cross it.
  int pushed = 0;
  for (int i = 0; i < f.data.n && pushed < 2; ++i)
    if (f.x[3 * i + 2] > 1e-3 && f.x[3 * i] > 0.03 && f.x[3 * i] < 0.07 && f.x[3 * i + 1] > 0.03 && f.x[3 * i + 1] < 0.07 &&
        (pushed == 0 || f.x[3 * i] > 0.05))
      f.x[3 * i] += 3.3e-3, f.x[3 * i + 1] += 2.7e-3, f.x[3 * i + 2] -= 4.5e-3, ++pushed;
  ASSERT_EQ(pushed, 2);
  SelfContact reused(f.data, kDhat);
  const int first = reused.count_intersections(f.x);
  EXPECT_GT(first, 0);
  const long queries = reused.broad_phase_queries();
  for (unsigned seed = 1; seed <= 4; ++seed) {
    const std::vector<double> x = jiggled(f.x, 0.45 * kBroadPhaseSlack * kDhat, seed);
    SelfContact fresh_instance(f.data, kDhat);
    EXPECT_EQ(reused.count_intersections(x), fresh_instance.count_intersections(x)) << "seed " << seed;
    const std::vector<double> moved = translated(x, Vec3(0.1, -0.05, 0.2) * seed);  // carried as a whole
    SelfContact fresh_moved(f.data, kDhat);
    EXPECT_EQ(reused.count_intersections(moved), fresh_moved.count_intersections(moved)) << "seed " << seed;
  }
  EXPECT_EQ(reused.broad_phase_queries(), queries);
}

}  // namespace
}  // namespace gd::sim
