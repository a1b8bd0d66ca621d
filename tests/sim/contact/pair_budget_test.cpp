// BroadPhase::find's pair budget: a query that would hold more pairs than max_pairs answers
// false with nothing in its output, on every implementation (Embree, brute force, the LBVH on both
// CPU policies and on a CUDA device where there is one), and the next query is unaffected.
#include <gtest/gtest.h>

#include <functional>
#include <string>

#include "sim/backend/cpu/exec_cpu.h"
#include "sim/contact/broad_phase.h"
#include "sim/contact/lbvh_broad_phase.h"
#include "sim/mesh.h"
#include "sim/solver/solver.h"

namespace gd::sim {
namespace {

struct Flat {
  int n = 0;
  std::vector<int> tris;
  std::vector<Eigen::Vector2i> edges;
  std::vector<double> x;
};

/// A 12 cm sheet at 1 cm spacing folded over itself with a 2 mm gap: many pairs within a few mm.
Flat folded_sheet() {
  Mesh m = make_rect(0.12, 0.12, 0.01);
  for (Vec3& p : m.x)
    if (p.x() > 0.06) p = Vec3(0.12 - p.x(), p.y(), 0.002);
  Flat f;
  f.n = static_cast<int>(m.x.size());
  for (const auto& t : m.tris) f.tris.insert(f.tris.end(), {t[0], t[1], t[2]});
  f.edges = build_topology(m).edges;
  for (const Vec3& p : m.x) f.x.insert(f.x.end(), {p.x(), p.y(), p.z()});
  return f;
}

using Factory = std::function<std::unique_ptr<BroadPhase>(const Flat&)>;

void expect_budget_respected(const Factory& make) {
  const Flat f = folded_sheet();
  auto bp = make(f);
  std::vector<double> x1 = f.x;
  for (size_t k = 2; k < x1.size(); k += 3) x1[k] += 0.003;  // swept: lifted 3 mm
  ContactCandidates all;
  ASSERT_TRUE(bp->find(f.x, x1, 0.004, &all));
  const std::size_t total = all.vf.size() + all.ee.size();
  ASSERT_GT(all.vf.size(), 100u);
  ASSERT_GT(all.ee.size(), 100u);

  ContactCandidates c;
  EXPECT_TRUE(bp->find(f.x, x1, 0.004, &c, total)) << "exactly the budget fits";
  EXPECT_EQ(c.vf, all.vf);
  EXPECT_EQ(c.ee, all.ee);
  // One pair over: refused, in the VF part and in the EE part.
  for (std::size_t budget : {total - 1, all.vf.size() - 1, std::size_t{0}}) {
    SCOPED_TRACE("budget " + std::to_string(budget) + " of " + std::to_string(total));
    c = all;
    EXPECT_FALSE(bp->find(f.x, x1, 0.004, &c, budget));
    EXPECT_TRUE(c.vf.empty());
    EXPECT_TRUE(c.ee.empty());
  }
  // The refusals left nothing behind: the next unbounded query gives the same sets.
  EXPECT_TRUE(bp->find(f.x, x1, 0.004, &c));
  EXPECT_EQ(c.vf, all.vf);
  EXPECT_EQ(c.ee, all.ee);
  // Triangle pairs are not bounded and still work after a refusal.
  std::vector<Eigen::Vector2i> tp;
  bp->triangle_pairs(f.x, f.x, 0.004, &tp);
  EXPECT_FALSE(tp.empty());
}

TEST(PairBudget, EmbreeRefusesAQueryOverItsBudget) {
  expect_budget_respected([](const Flat& f) { return make_embree_broad_phase(f.tris, f.edges, f.n); });
}

TEST(PairBudget, BruteForceRefusesAQueryOverItsBudget) {
  expect_budget_respected([](const Flat& f) { return make_brute_force_broad_phase(f.tris, f.edges, f.n); });
}

TEST(PairBudget, LbvhRefusesAQueryOverItsBudget) {
  expect_budget_respected([](const Flat& f) { return make_lbvh_broad_phase(f.tris, f.edges, f.n); });
}

TEST(PairBudget, LbvhGpuPathsRefusesAQueryOverItsBudget) {
  expect_budget_respected(
      [](const Flat& f) { return std::make_unique<LbvhBroadPhase<CpuGpuPathsExec>>(f.tris, f.edges, f.n); });
}

TEST(PairBudget, CudaLbvhRefusesAQueryOverItsBudget) {
  if (!cuda_available()) GTEST_SKIP() << "no CUDA device (scripts/gpu-check runs this where there is one)";
  expect_budget_respected([](const Flat& f) { return make_cuda_lbvh_broad_phase(f.tris, f.edges, f.n); });
}

}  // namespace
}  // namespace gd::sim
