// The CPU backend takes the same steps, bit for bit, at any thread count: its element loops add
// chunk by chunk in a fixed order (SceneData's Coloring) and its sums add fixed blocks in order
// (CpuExec::sum), so a run reproduces on a machine with another core count. The scene is large
// enough that every parallel loop runs in parallel (over 1024 vertices, over 4096 coordinates,
// over 1024 contact pairs) and has self-contact, friction and a grip.
#include <gtest/gtest.h>

#include <vector>

#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/scene.h"
#include "sim/stacked_sheets.h"

namespace gd::sim {
namespace {

/// Two 22 cm sheets of 941 vertices each, the top one 0.7 mm above the bottom one.
Mesh two_sheets() { return test::stacked_sheets(0.22, 0.008, 0.001, Vec3(0.004, 0.003, 0.0007)); }

std::vector<Vec3> run(int threads, const Mesh& m) {
  SceneOptions o;
  o.threads = threads;
  o.self_contact = true;
  o.table = true;
  o.table_height = 0.0;
  auto s = Scene::create(m, MaterialLibrary::load_default().get("cotton"), o);
  const int nb = static_cast<int>(m.x.size()) / 2;
  s->pin({0});                                    // a bottom corner
  s->set_targets({nb + 5}, {m.x[nb + 5] + Vec3(0.001, 0.0, 0.0005)});  // a grip drags the top sheet
  EXPECT_TRUE(s->step(3)) << s->failure();
  EXPECT_GE(s->last_stats().contacts, 1024) << "the pairs' adds should run on every thread (add_pair)";
  return s->positions();
}

TEST(ThreadCount, OneAndTwoThreadsTakeBitIdenticalSteps) {
  const Mesh m = two_sheets();
  ASSERT_GT(m.x.size(), 1366u);  // 3n > 4096: PCG's vector sums run in parallel
  const std::vector<Vec3> one = run(1, m), two = run(2, m);
  ASSERT_EQ(one.size(), two.size());
  int differing = 0;
  for (size_t i = 0; i < one.size(); ++i) differing += one[i] != two[i];
  EXPECT_EQ(differing, 0) << "vertices whose positions differ in any bit between 1 and 2 threads";
}

}  // namespace
}  // namespace gd::sim
