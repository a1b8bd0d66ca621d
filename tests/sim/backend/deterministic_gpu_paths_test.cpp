// SceneOptions::deterministic on the atomic backends: the CUDA backend's code paths (run here on
// the CPU, BackendKind::kCpuGpuPaths, ctest label gpu-paths) with element loops colour by colour
// and the contact pairs' adds sorted by vertex, so that the sums no longer depend on which thread
// adds first. Without the option the same scene's atomic adds race on two threads and its steps
// differ in the last bits from one run to the next (checked by hand when this test was written:
// the bit-identity assertions below fail with deterministic = false).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "sim/contact/collider.h"
#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/scene.h"
#include "sim/solver/solver.h"
#include "sim/stacked_sheets.h"
#include "sim/tight_solve.h"

namespace gd::sim {
namespace {

/// Two 22 cm sheets of 941 vertices each, the top one 0.7 mm above the bottom one: every parallel
/// loop runs in parallel (over 1024 elements, 4096 coordinates, 1024 contact pairs).
Mesh two_sheets() { return test::stacked_sheets(0.22, 0.008, 0.001, Vec3(0.004, 0.003, 0.0007)); }

/// Self-contact with cloth friction, a grip dragging the top sheet, a pinned corner and a rod
/// with friction pressing on the top sheet, stepped `steps` times.
std::vector<Vec3> run(const Mesh& m, SceneOptions o, int threads, int steps, StepStats* last = nullptr) {
  o.threads = threads;
  o.self_contact = true;
  o.table_height = 0.0;
  auto s = Scene::create(m, MaterialLibrary::load_default().get("cotton"), o);
  const int nb = static_cast<int>(m.x.size()) / 2;
  s->pin({0});
  s->set_targets({nb + 5}, {m.x[nb + 5] + Vec3(0.001, 0.0, 0.0005)});
  Collider rod = Collider::capsule(0.01, 0.03);  // axis along local z, turned to lie along x
  rod.set_pose([](double t) {  // 0.4 mm above the top sheet, coming down 0.1 mm a step
    Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
    p.translate(Vec3(0.11, 0.11, 0.0121 - 0.02 * t));
    p.rotate(Eigen::AngleAxisd(M_PI / 2, Vec3::UnitY()));
    return p;
  });
  rod.set_friction(0.4);
  s->add_collider(rod);
  EXPECT_TRUE(s->step(steps)) << s->failure();
  if (last) *last = s->last_stats();
  return s->positions();
}

SceneOptions deterministic_gpu_paths() {
  SceneOptions o;
  o.backend = BackendKind::kCpuGpuPaths;
  o.deterministic = true;
  return o;
}

int differing(const std::vector<Vec3>& a, const std::vector<Vec3>& b) {
  EXPECT_EQ(a.size(), b.size());
  int n = 0;
  for (size_t i = 0; i < a.size() && i < b.size(); ++i) n += a[i] != b[i];
  return n;
}

TEST(DeterministicGpuPaths, OneAndTwoThreadsAndRepeatedRunsTakeBitIdenticalSteps) {
  const Mesh m = two_sheets();
  StepStats st;
  const std::vector<Vec3> one = run(m, deterministic_gpu_paths(), 1, 3);
  const std::vector<Vec3> two = run(m, deterministic_gpu_paths(), 2, 3, &st);
  const std::vector<Vec3> again = run(m, deterministic_gpu_paths(), 2, 3);
  EXPECT_GE(st.contacts, 1024) << "the pairs' adds should run on every thread";
  EXPECT_EQ(st.intersecting_pairs, 0);
  EXPECT_EQ(differing(one, two), 0) << "vertices whose positions differ in any bit between 1 and 2 threads";
  EXPECT_EQ(differing(two, again), 0) << "vertices whose positions differ in any bit between two runs";
}

// On a CUDA device (skipped elsewhere; scripts/gpu-check runs it): two runs take the same steps
// bit for bit.
TEST(DeterministicGpuPaths, CudaRepeatsItselfBitForBit) {
  if (!cuda_available()) GTEST_SKIP() << "no CUDA device on this machine";
  const Mesh m = two_sheets();
  SceneOptions o;
  o.backend = BackendKind::kCuda;
  o.deterministic = true;
  const std::vector<Vec3> a = run(m, o, 2, 3), b = run(m, o, 2, 3);
  EXPECT_EQ(differing(a, b), 0) << "vertices whose positions differ in any bit between two runs";
}

// The fixed order changes only the order of the additions: with every step solved tightly the
// deterministic paths take the CPU backend's steps to rounding.
TEST(DeterministicGpuPaths, MatchTheCpuBackendToRounding) {
  const Mesh m = two_sheets();
  const SceneOptions tight = test::tight_solve();
  SceneOptions det = tight;
  det.backend = BackendKind::kCpuGpuPaths;
  det.deterministic = true;
  const std::vector<Vec3> cpu = run(m, tight, 2, 3), gpu = run(m, det, 2, 3);
  double worst = 0, moved = 0;
  for (size_t i = 0; i < cpu.size(); ++i) {
    worst = std::max(worst, (cpu[i] - gpu[i]).norm());
    moved = std::max(moved, (cpu[i] - m.x[i]).norm());
  }
  EXPECT_GT(moved, 2e-4);
  EXPECT_LT(worst, 1e-8) << "moved " << moved;
}

}  // namespace
}  // namespace gd::sim
