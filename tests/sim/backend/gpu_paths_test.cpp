// The CUDA backend's code paths, run on the CPU (BackendKind::kCpuGpuPaths: uncoloured element
// loops with atomic adds, the contact pairs' adds in parallel, PCG's scalars in the backend's
// memory) against the CPU backend's own (chunk colouring, serial pair adds), on scenes that
// exercise every term: self-contact barriers and friction with grip springs, kinematic colliders
// with friction, the table, pins. No GPU is needed: these are the paths a GPU would take, minus
// memory transfer and launch (ctest label gpu-paths). Where a CUDA device is present the same
// scenes also run on it (the GPU parity test; elsewhere those cases skip). Both solve each step
// tightly, so the two must take the same steps to rounding.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <string>
#include <vector>

#include "sim/contact/collider.h"
#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/scene.h"
#include "sim/solver/solver.h"
#include "sim/stacked_sheets.h"
#include "sim/tight_solve.h"
#include "sim/library_materials.h"

namespace gd::sim {
namespace {

using test::cotton;

/// Solver settings under which a step's result does not depend on the linear solver's path
/// (test::tight_solve), on two threads (so the atomic adds race).
SceneOptions tight(bool self_contact) {
  SceneOptions o = test::tight_solve();
  o.self_contact = self_contact;
  o.threads = 2;
  return o;
}

using Setup = std::function<void(Scene&)>;

/// The GPU paths on the CPU, and on a CUDA device where there is one.
class GpuPaths : public ::testing::TestWithParam<BackendKind> {
 protected:
  void SetUp() override {
    if (GetParam() == BackendKind::kCuda && !cuda_available()) GTEST_SKIP() << "no CUDA device on this machine";
  }
};

/// Steps one scene on the CPU backend and on `other` (with `other_broad_phase`) and returns the
/// largest distance between their vertices over the steps, m; `moved` gets the largest
/// displacement of a vertex from its start.
double largest_difference(BackendKind other, const Mesh& m, const SceneOptions& base, const Setup& setup, int steps,
                          double* moved, BroadPhaseKind other_broad_phase = BroadPhaseKind::kEmbree,
                          const Material& material = cotton()) {
  SceneOptions a = base, b = base;
  a.backend = BackendKind::kCpu;
  a.broad_phase = BroadPhaseKind::kEmbree;
  b.backend = other;
  b.broad_phase = other_broad_phase;
  auto cpu = Scene::create(m, material, a);
  auto gpu = Scene::create(m, material, b);
  EXPECT_EQ(cpu->backend(), "cpu");
  EXPECT_EQ(gpu->backend(), other == BackendKind::kCuda ? "cuda" : "cpu-gpu-paths");
  setup(*cpu);
  setup(*gpu);
  double worst = 0;
  *moved = 0;
  for (int k = 0; k < steps; ++k) {
    EXPECT_TRUE(cpu->step()) << cpu->failure();
    EXPECT_TRUE(gpu->step()) << gpu->failure();
    const auto xa = cpu->positions(), xb = gpu->positions();
    for (size_t i = 0; i < xa.size(); ++i) {
      worst = std::max(worst, (xa[i] - xb[i]).norm());
      *moved = std::max(*moved, (xa[i] - m.x[i]).norm());
    }
    EXPECT_EQ(cpu->last_stats().intersecting_pairs, 0);
    EXPECT_EQ(gpu->last_stats().intersecting_pairs, 0);
  }
  if (base.self_contact) {
    EXPECT_GT(cpu->last_stats().contacts, 0);
    EXPECT_NEAR(gpu->last_stats().contacts, cpu->last_stats().contacts, 0.02 * cpu->last_stats().contacts + 1);
  }
  return worst;
}

/// Two 8 cm sheets, the top one 0.6 mm above the bottom one (in contact), on the table.
Mesh stacked_sheets() { return test::stacked_sheets(0.08, 0.01, 0.0005, Vec3(0.003, 0.002, 0.0006)); }

/// The grip dragging the top sheet's far edge 2 cm along x and pressing it 1 mm down, a pinned
/// corner holding the bottom sheet.
Setup drag_top_sheet(const Mesh& m) {
  const int nb = static_cast<int>(m.x.size()) / 2;
  return [&m, nb](Scene& s) {
    s.pin({0});
    std::vector<int> edge;
    for (int i = nb; i < 2 * nb; ++i)
      if (m.x[i].x() > 0.083 - 1e-9) edge.push_back(i);
    s.attach(edge, [](double t) {
      return Eigen::Isometry3d(Eigen::Translation3d(0.2 * t, 0.0, -0.001 * std::min(t, 0.02) / 0.02));
    });
  };
}

// Self-contact barriers and cloth-cloth friction: a grip drags the top sheet's edge across the
// bottom sheet (kinematic vertices are grip springs in self-contact mode). The GPU paths find
// their candidates with the LBVH (on the CPU policy here, on the device with CUDA), the CPU
// backend with Embree.
TEST_P(GpuPaths, SelfContactFrictionAndGripsMatchTheCpuPaths) {
  const Mesh m = stacked_sheets();
  double moved = 0;
  const double worst = largest_difference(GetParam(), m, tight(true), drag_top_sheet(m), 12, &moved,
                                          BroadPhaseKind::kLbvh);
  EXPECT_GT(moved, 0.005);
  EXPECT_LT(worst, 1e-7 * std::max(1.0, moved / 0.01)) << "moved " << moved;
}

// The LBVH and Embree report the same candidates, so the CPU backend takes bit-identical steps
// with either (default solver settings: any different candidate would show).
TEST(BroadPhases, LbvhAndEmbreeTakeBitIdenticalSteps) {
  const Mesh m = stacked_sheets();
  SceneOptions a, b;
  a.self_contact = b.self_contact = true;
  a.threads = b.threads = 2;
  a.broad_phase = BroadPhaseKind::kEmbree;
  b.broad_phase = BroadPhaseKind::kLbvh;
  auto embree = Scene::create(m, cotton(), a);
  auto lbvh = Scene::create(m, cotton(), b);
  const auto setup = drag_top_sheet(m);
  setup(*embree);
  setup(*lbvh);
  for (int k = 0; k < 12; ++k) {
    ASSERT_TRUE(embree->step()) << embree->failure();
    ASSERT_TRUE(lbvh->step()) << lbvh->failure();
    ASSERT_EQ(embree->last_stats().candidates, lbvh->last_stats().candidates) << "step " << k;
    const auto xa = embree->positions(), xb = lbvh->positions();
    for (size_t i = 0; i < xa.size(); ++i) ASSERT_EQ(xa[i], xb[i]) << "step " << k << " vertex " << i;
  }
  EXPECT_GT(embree->last_stats().contacts, 0);
}

// Kinematic colliders with friction: a capsule sweeps into a sheet hanging from its top edge and
// pushes it along, sliding on it.
TEST_P(GpuPaths, CollidersWithFrictionMatchTheCpuPaths) {
  Mesh m = make_rect(0.1, 0.1, 0.004);  // 1250 triangles: the element loops run in parallel
  for (Vec3& p : m.x) p = Vec3(p.x(), 0, 0.45 + p.y());  // hanging in the xz plane
  SceneOptions o = tight(false);
  o.table = false;
  double moved = 0;
  const double worst = largest_difference(GetParam(), m, o, [&](Scene& s) {
    s.pin(vertices_where(m, [](const Vec3& p) { return p.z() > 0.55 - 1e-9; }));
    Collider rod = Collider::capsule(0.01, 0.03);  // axis along local z, turned to lie along x
    rod.set_pose([](double t) {
      Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
      p.translate(Vec3(0.05, -0.0125 + 0.2 * t, 0.49));
      p.rotate(Eigen::AngleAxisd(M_PI / 2, Vec3::UnitY()));
      return p;
    });
    rod.set_friction(0.5);
    s.add_collider(rod);
  }, 16, &moved);
  EXPECT_GT(moved, 0.005);
  EXPECT_LT(worst, 1e-7 * std::max(1.0, moved / 0.01));
}

// Pins (Dirichlet rows), membrane, bending and their damping, air drag: a sheet swinging down
// from two corners, without contact.
TEST_P(GpuPaths, PinnedSheetSwingingMatchesTheCpuPaths) {
  Mesh m = make_rect(0.16, 0.16, 0.005);  // 2048 triangles: the element loops run in parallel
  for (Vec3& p : m.x) p.z() = 0.5;
  double moved = 0;
  const double worst = largest_difference(GetParam(), m, tight(false), [&](Scene& s) {
    s.pin(vertices_where(m, [](const Vec3& p) { return p.y() < 1e-9 && (p.x() < 1e-9 || p.x() > 0.16 - 1e-9); }));
  }, 12, &moved);
  EXPECT_GT(moved, 0.01);
  EXPECT_LT(worst, 1e-7 * std::max(1.0, moved / 0.01));
}

// Bending hysteresis (sim/energy/bending_friction.h): the friction term in the hinge kernels
// and the sliders' slip after each step, on the same swinging sheet.
TEST_P(GpuPaths, BendingHysteresisMatchesTheCpuPaths) {
  Mesh m = make_rect(0.16, 0.16, 0.005);
  for (Vec3& p : m.x) p.z() = 0.5;
  Material mat = cotton();
  mat.bend_friction_warp = 30 * mat.bend_warp;  // the limit moment at a bend of 30 1/m
  mat.bend_friction_weft = 30 * mat.bend_weft;
  double moved = 0;
  const double worst = largest_difference(GetParam(), m, tight(false), [&](Scene& s) {
    s.pin(vertices_where(m, [](const Vec3& p) { return p.y() < 1e-9 && (p.x() < 1e-9 || p.x() > 0.16 - 1e-9); }));
  }, 12, &moved, BroadPhaseKind::kEmbree, mat);
  EXPECT_GT(moved, 0.01);
  EXPECT_LT(worst, 1e-7 * std::max(1.0, moved / 0.01));
}

INSTANTIATE_TEST_SUITE_P(Backends, GpuPaths, ::testing::Values(BackendKind::kCpuGpuPaths, BackendKind::kCuda),
                         [](const ::testing::TestParamInfo<BackendKind>& i) {
                           return i.param == BackendKind::kCuda ? std::string("Cuda") : std::string("CpuGpuPaths");
                         });

}  // namespace
}  // namespace gd::sim
