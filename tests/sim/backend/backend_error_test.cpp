// A device failure (a kernel that cannot launch) fails the step of that scene with a message and
// keeps its last good state; other scenes go on. Simulated on the CPU with the GPU paths' test
// seam (CpuGpuPathsExec::launches_before_failure), the way CudaExec's launch check throws.
#include <gtest/gtest.h>

#include "sim/backend/cpu/exec_cpu.h"
#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/scene.h"

namespace gd::sim {
namespace {

std::unique_ptr<Scene> hanging_square(BackendKind backend) {
  Mesh m = make_rect(0.2, 0.2, 0.02);
  for (Vec3& p : m.x) p.z() = 0.3;
  SceneOptions o;
  o.backend = backend;
  o.threads = 1;
  auto s = Scene::create(m, MaterialLibrary::load_default().get("cotton"), o);
  s->pin({0, 10});
  return s;
}

TEST(GpuPathsFailures, AFailedLaunchFailsThatScenesStepOnly) {
  auto failing = hanging_square(BackendKind::kCpuGpuPaths);
  auto other = hanging_square(BackendKind::kCpuGpuPaths);
  ASSERT_TRUE(failing->step(3));
  ASSERT_TRUE(other->step(3));
  const auto before = failing->positions();
  const double t = failing->time();
  CpuGpuPathsExec::launches_before_failure = 20;  // somewhere inside the next step
  EXPECT_FALSE(failing->step());
  EXPECT_TRUE(failing->failed());
  EXPECT_NE(failing->failure().find("kernel launch failed"), std::string::npos) << failing->failure();
  EXPECT_NE(failing->failure().find("t="), std::string::npos) << failing->failure();
  EXPECT_EQ(failing->time(), t);
  const auto after = failing->positions();  // the last good state, not a half-done step
  for (size_t i = 0; i < before.size(); ++i) EXPECT_EQ(after[i], before[i]) << "vertex " << i;
  EXPECT_FALSE(failing->step());  // stays failed
  EXPECT_EQ(CpuGpuPathsExec::launches_before_failure, -1);
  EXPECT_TRUE(other->step(3)) << other->failure();  // the other scene goes on
}

}  // namespace
}  // namespace gd::sim
