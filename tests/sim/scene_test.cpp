// The scene API: creation errors, kinematic vertices, failure handling, anisotropy, backends.
#include "sim/scene.h"

#include <gtest/gtest.h>

#include <cmath>

#include "sim/demand.h"
#include "sim/library_materials.h"

namespace gd::sim {
namespace {

using test::cotton;

Mesh lifted_square(double size, double spacing, double z) {
  Mesh m = make_rect(size, size, spacing);
  for (Vec3& p : m.x) p.z() = z;
  return m;
}

TEST(SceneCreate, RejectsMeshOnOrBelowTheTable) {
  const Mesh m = lifted_square(0.1, 0.02, 0.0);
  EXPECT_THROW(Scene::create(m, cotton()), InputError);
  SceneOptions o;
  o.table = false;
  EXPECT_NO_THROW(Scene::create(m, cotton(), o));
}

/// Success when Scene::create rejects `o` with an InputError whose message names `option`.
::testing::AssertionResult rejected_naming(const SceneOptions& o, const std::string& option) {
  try {
    Scene::create(lifted_square(0.1, 0.02, 0.1), cotton(), o);
  } catch (const InputError& e) {
    if (std::string(e.what()).find(option) != std::string::npos) return ::testing::AssertionSuccess();
    return ::testing::AssertionFailure() << "the error does not name " << option << ": " << e.what();
  }
  return ::testing::AssertionFailure() << option << " accepted";
}

TEST(SceneCreate, RejectsBadOptionsWithTheirName) {
  SceneOptions o;
  o.dt = -1;
  EXPECT_TRUE(rejected_naming(o, "dt"));
  o.dt = 1e-300;  // would step without advancing the clock
  EXPECT_TRUE(rejected_naming(o, "dt must be at least"));
  o = SceneOptions();
  o.gravity = Vec3(0, 0, NAN);
  EXPECT_TRUE(rejected_naming(o, "gravity"));
  o = SceneOptions();
  o.grip_stiffness = 0;
  EXPECT_TRUE(rejected_naming(o, "grip_stiffness"));
  for (int bad : {0, -3, 1001}) {
    o = SceneOptions();
    o.grip_newton_max_iters = bad;
    EXPECT_TRUE(rejected_naming(o, "option grip_newton_max_iters")) << "cap " << bad;
    o = SceneOptions();
    o.newton_max_iters = bad;
    EXPECT_TRUE(rejected_naming(o, "option newton_max_iters")) << "cap " << bad;
  }
  for (Real bad : {0.0, -1.0, static_cast<Real>(NAN)}) {
    o = SceneOptions();
    o.grip_force_limit = bad;
    EXPECT_TRUE(rejected_naming(o, "grip_force_limit")) << "limit " << bad;
  }
  o = SceneOptions();
  o.grip_force_limit = INFINITY;  // no limit
  EXPECT_NO_THROW(Scene::create(lifted_square(0.1, 0.02, 0.1), cotton(), o));
  for (Real bad : {0.0, -0.1, 1.5, static_cast<Real>(NAN)}) {
    o = SceneOptions();
    o.compression_ratio = bad;
    EXPECT_TRUE(rejected_naming(o, "compression_ratio")) << "ratio " << bad;
  }
  for (int bad : {-1, 100001}) {
    o = SceneOptions();
    o.pcg_max_iters = bad;
    EXPECT_TRUE(rejected_naming(o, "option pcg_max_iters")) << "cap " << bad;
  }
}

// PCG's cap (0: automatic) follows the iterations block-Jacobi needs as the mesh refines, about
// sqrt(n): 50 up to ~22.5k vertices, 67 at gd-bench's fold/40000; a cap the user sets stays.
TEST(SceneCreate, PcgCapGrowsWithTheMesh) {
  SceneOptions o;
  EXPECT_EQ(o.pcg_max_iters, 0);
  EXPECT_EQ(effective_pcg_max_iters(o, 400), 50);
  EXPECT_EQ(effective_pcg_max_iters(o, 15625), 50);
  EXPECT_EQ(effective_pcg_max_iters(o, 20273), 57);
  EXPECT_EQ(effective_pcg_max_iters(o, 40401), 81);
  EXPECT_GT(effective_pcg_max_iters(o, 160000), effective_pcg_max_iters(o, 40401));
  o.pcg_max_iters = 400;
  EXPECT_EQ(effective_pcg_max_iters(o, 40401), 400);
  EXPECT_NO_THROW(Scene::create(lifted_square(0.1, 0.02, 0.1), cotton(), SceneOptions()));
}

TEST(SceneCreate, RejectsZeroThicknessMaterial) {
  Material m = cotton();
  m.thickness = 0;
  EXPECT_THROW(Scene::create(lifted_square(0.1, 0.02, 0.1), m), InputError);
}

TEST(SceneCreate, CudaWithoutDeviceIsAClearError) {
  if (cuda_available()) GTEST_SKIP() << "a CUDA device is present";
  SceneOptions o;
  o.backend = BackendKind::kCuda;
  EXPECT_THROW(Scene::create(lifted_square(0.1, 0.02, 0.1), cotton(), o), InputError);
  o.backend = BackendKind::kAuto;
  EXPECT_EQ(Scene::create(lifted_square(0.1, 0.02, 0.1), cotton(), o)->backend(), "cpu");
}

TEST(SceneKinematics, AttachedVerticesFollowTheirPose) {
  SceneOptions o;
  o.table = false;
  const Mesh m = lifted_square(0.2, 0.02, 0.5);
  auto s = Scene::create(m, cotton(), o);
  const int v = nearest_vertex(m, Vec3(0.1, 0.1, 0.5));
  const Vec3 start = m.x[v];
  s->attach({v}, [](double t) { return Eigen::Isometry3d(Eigen::Translation3d(0.1 * t, 0, 0.2 * t)); });
  ASSERT_TRUE(s->step(20));
  const Vec3 expect = start + Vec3(0.1, 0, 0.2) * s->time();
  // With self-contact on, kinematic vertices are held by a very stiff spring (so CCD guards
  // them too): they follow to well under a micrometre.
  EXPECT_LT((s->positions()[v] - expect).norm(), 1e-6);
  EXPECT_EQ(s->kinematic_vertices(), std::vector<int>{v});
}

TEST(SceneKinematics, ReleasedClothFalls) {
  SceneOptions o;
  o.table = false;
  const Mesh m = lifted_square(0.2, 0.02, 0.5);
  auto s = Scene::create(m, cotton(), o);
  const int g = s->pin({0, 1, 2});
  ASSERT_TRUE(s->step(10));
  s->release(g);
  EXPECT_THROW(s->release(g), InputError);
  ASSERT_TRUE(s->step(20));
  for (const Vec3& p : s->positions()) EXPECT_LT(p.z(), 0.5 - 0.01);
}

TEST(SceneKinematics, BadIndicesAndPosesAreInputErrors) {
  auto s = Scene::create(lifted_square(0.1, 0.02, 0.1), cotton());
  EXPECT_THROW(s->pin({-1}), InputError);
  EXPECT_THROW(s->pin({s->vertex_count()}), InputError);
  EXPECT_THROW(s->pin({}), InputError);
  EXPECT_THROW(s->attach({0}, [](double) { return Eigen::Isometry3d(Eigen::Translation3d(NAN, 0, 0)); }), InputError);
  EXPECT_THROW(s->set_targets({0}, {Vec3(0, 0, INFINITY)}), InputError);
  EXPECT_THROW(s->set_state({}, {}), InputError);
}

TEST(SceneFailure, NonFiniteStateMarksFailedAndKeepsLastState) {
  SceneOptions o;
  o.table = false;
  auto s = Scene::create(lifted_square(0.1, 0.02, 0.5), cotton(), o);
  const auto before = s->positions();
  // A target at 1e300 m overflows the membrane energy: the state turns non-finite.
  s->set_targets({0}, {Vec3(1e300, 0, 0)});
  EXPECT_FALSE(s->step());
  EXPECT_TRUE(s->failed());
  EXPECT_NE(s->failure().find("non-finite"), std::string::npos);
  const auto after = s->positions();
  for (size_t i = 0; i < before.size(); ++i) EXPECT_EQ(before[i], after[i]);
  EXPECT_FALSE(s->step());  // refused while failed
}

TEST(SceneFailure, PoseThatTurnsNonFiniteLaterFailsTheStepNotTheProcess) {
  SceneOptions o;
  o.table = false;
  auto s = Scene::create(lifted_square(0.1, 0.02, 0.5), cotton(), o);
  s->attach({0}, [](double t) {
    return Eigen::Isometry3d(Eigen::Translation3d(t > 0.02 ? NAN : 0.0, 0, 0));
  });
  EXPECT_FALSE(s->step(10));
  EXPECT_TRUE(s->failed());
  EXPECT_NE(s->failure().find("not finite"), std::string::npos);
}

// Anisotropy: the same strip pulled along the warp and along the weft stretches in the ratio
// of the two stiffnesses.
TEST(SceneAnisotropy, WarpAndWeftStretchByTheirOwnStiffness) {
  Material m = cotton();
  m.stretch_warp = 1000;
  m.stretch_weft = 250;
  SceneOptions o;
  o.table = false;
  o.gravity = Vec3::Zero();
  o.dt = 1.0;
  o.linear_solver = LinearSolverKind::kDirect;
  o.newton_max_iters = 30;
  auto elongation = [&](bool along_warp) {
    Mesh mesh = make_rect(0.1, 0.02, 0.005);  // long along x
    for (size_t i = 0; i < mesh.x.size(); ++i) {
      mesh.x[i].z() = 0.5;
      if (!along_warp) mesh.uv[i] = Vec2(mesh.uv[i].y(), -mesh.uv[i].x());  // warp across, weft along
    }
    auto s = Scene::create(mesh, m, o);
    s->pin(vertices_where(mesh, [](const Vec3& p) { return p.x() < 1e-9; }));
    const auto end = vertices_where(mesh, [](const Vec3& p) { return p.x() > 0.1 - 1e-9; });
    std::vector<Vec3> f(end.size(), Vec3(0.02 / end.size(), 0, 0));  // 0.02 N in total
    s->set_external_forces(end, f);
    s->relax(30, 1e-12);
    double d = 0;
    const auto x = s->positions();
    for (int i : end) d += x[i].x() - mesh.x[i].x();
    return d / end.size();
  };
  const double warp = elongation(true), weft = elongation(false);
  EXPECT_NEAR(warp, 0.02 / 0.02 / 1000 * 0.1, 0.03 * warp);
  EXPECT_NEAR(weft / warp, 4.0, 0.15);
}

// The CUDA backend runs the same element functions: one step must agree with the CPU step.
TEST(SceneBackends, CudaStepMatchesCpuStep) {
  if (!cuda_available()) GTEST_SKIP() << "no CUDA device on this machine";
  SceneOptions o;
  o.pcg_tol = 1e-8;
  o.pcg_newton_fraction = 0;  // a tight linear solve on both
  o.pcg_max_iters = 2000;
  o.newton_max_iters = 10;
  o.newton_tol = 1e-8;
  const Mesh m = lifted_square(0.3, 0.01, 0.2);
  auto cpu = Scene::create(m, cotton(), o);
  o.backend = BackendKind::kCuda;
  auto gpu = Scene::create(m, cotton(), o);
  for (auto* s : {cpu.get(), gpu.get()}) s->pin({0, nearest_vertex(m, Vec3(0.3, 0, 0.2))});
  ASSERT_TRUE(cpu->step(5));
  ASSERT_TRUE(gpu->step(5));
  const auto a = cpu->positions(), b = gpu->positions();
  double worst = 0;
  for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, (a[i] - b[i]).norm() / std::max(1e-3, (a[i] - m.x[i]).norm()));
  EXPECT_LT(worst, 1e-4);
}

TEST(SceneMemory, ReportsBytesPerVertex) {
  auto s = Scene::create(lifted_square(0.2, 0.01, 0.1), cotton());
  EXPECT_GT(s->bytes_per_vertex(), 500);
  EXPECT_LT(s->bytes_per_vertex(), 20000);
}

}  // namespace
}  // namespace gd::sim

namespace gd::sim {
namespace {

// A sheet dropped onto another resting on the table lands on it: self-contact keeps the layers
// apart (positive gap, no intersecting pair) and the top sheet comes to rest.
TEST(SceneSelfContact, SheetLandsOnSheet) {
  SceneOptions o;
  o.self_contact = true;
  Mesh bottom = make_rect(0.1, 0.1, 0.01);
  Mesh m = bottom;
  const int nb = static_cast<int>(bottom.x.size());
  for (Vec3& p : m.x) p.z() = 0.0005;
  for (int i = 0; i < nb; ++i) {  // the second sheet, 2 cm above and shifted by a third of a cell
    m.x.push_back(bottom.x[i] + Vec3(0.003, 0.002, 0.02));
    m.uv.push_back(bottom.uv[i]);
  }
  for (const auto& t : bottom.tris) m.tris.emplace_back(t + Eigen::Vector3i::Constant(nb));
  auto s = Scene::create(m, cotton(), o);
  int worst = 0;
  for (int k = 0; k < 60; ++k) {
    ASSERT_TRUE(s->step()) << s->failure();
    worst = std::max(worst, s->last_stats().intersecting_pairs);
  }
  EXPECT_EQ(worst, 0);
  EXPECT_EQ(s->untangle_runs(), 0);
  const auto x = s->positions();
  double top_min = 1e9, bottom_max = -1e9;
  for (int i = 0; i < nb; ++i) bottom_max = std::max(bottom_max, x[i].z());
  for (int i = nb; i < 2 * nb; ++i) top_min = std::min(top_min, x[i].z());
  EXPECT_GT(top_min, bottom_max);          // still on top
  EXPECT_LT(top_min, bottom_max + 0.003);  // and resting on it, not hovering
  EXPECT_GT(s->last_stats().contacts, 0);
}

// The PCG applies the contact pairs' off-diagonal blocks merged per vertex pair (CPU); the direct
// solver assembles the pairs' own blocks into one sparse matrix. On two sheets pressed together
// (barrier and friction pairs, a pinned corner among them) the two must take the same steps.
TEST(SceneSelfContact, PcgWithMergedPairBlocksMatchesTheDirectSolver) {
  SceneOptions o;
  o.self_contact = true;
  o.pcg_tol = 1e-12;
  o.pcg_max_iters = 5000;
  o.newton_max_iters = 8;
  // Both run Newton to newton_tol: the residual rule stops each where its own iterates first
  // fall under the threshold, which two solvers' rounding can put one iteration apart.
  o.newton_rtol = o.newton_atol = 0;
  Mesh bottom = make_rect(0.08, 0.08, 0.01);
  Mesh m = bottom;
  const int nb = static_cast<int>(bottom.x.size());
  for (Vec3& p : m.x) p.z() = 0.0005;
  for (int i = 0; i < nb; ++i) {  // the second sheet 1.5 mm above, shifted by a third of a cell
    m.x.push_back(bottom.x[i] + Vec3(0.003, 0.002, 0.0015));
    m.uv.push_back(bottom.uv[i]);
  }
  for (const auto& t : bottom.tris) m.tris.emplace_back(t + Eigen::Vector3i::Constant(nb));
  auto pcg = Scene::create(m, cotton(), o);
  o.linear_solver = LinearSolverKind::kDirect;
  auto direct = Scene::create(m, cotton(), o);
  for (Scene* s : {pcg.get(), direct.get()}) {
    s->pin({nb});  // a top corner: its pairs have a fixed vertex
    ASSERT_TRUE(s->step(4)) << s->failure();
  }
  EXPECT_GT(pcg->last_stats().contacts, 50);
  const auto a = pcg->positions(), b = direct->positions();
  double worst = 0, moved = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    worst = std::max(worst, (a[i] - b[i]).norm());
    moved = std::max(moved, (b[i] - m.x[i]).norm());
  }
  EXPECT_GT(moved, 1e-4);
  EXPECT_LT(worst, 1e-4 * moved);
}

}  // namespace
}  // namespace gd::sim

namespace gd::sim {
namespace {

TEST(SceneColliders, BadPosesAreInputErrorsOrFailedSteps) {
  SceneOptions o;
  o.table = false;
  auto s = Scene::create(lifted_square(0.1, 0.02, 0.5), cotton(), o);
  Collider box = Collider::box(Vec3(0.01, 0.01, 0.01));
  box.set_pose([](double) { return Eigen::Isometry3d(Eigen::Translation3d(NAN, 0, 0)); });
  EXPECT_THROW(s->add_collider(box), InputError);
  Collider later = Collider::capsule(0.01, 0.02);
  later.set_pose([](double t) { return Eigen::Isometry3d(Eigen::Translation3d(t > 0.02 ? NAN : 0.0, 0, 0)); });
  const int id = s->add_collider(later);
  EXPECT_FALSE(s->step(10));
  EXPECT_TRUE(s->failed());
  EXPECT_NE(s->failure().find("t="), std::string::npos) << s->failure();
  EXPECT_NO_THROW(s->remove_collider(id));
  EXPECT_THROW(s->remove_collider(id), InputError);
}

// A capsule sweeping through a hanging sheet pushes it aside: no vertex ends inside it.
TEST(SceneColliders, MovingCapsulePushesClothAside) {
  SceneOptions o;
  o.table = false;
  Mesh m = make_rect(0.2, 0.2, 0.01);
  for (Vec3& p : m.x) p = Vec3(p.x(), 0, 0.4 + p.y());  // hanging in the xz plane
  auto s = Scene::create(m, cotton(), o);
  s->pin(vertices_where(m, [](const Vec3& p) { return p.z() > 0.6 - 1e-9; }));
  Collider rod = Collider::capsule(0.01, 0.05);  // axis along local z, turned to lie along x
  rod.set_pose([](double t) {
    Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
    p.translate(Vec3(0.1, -0.05 + 0.2 * t, 0.5));
    p.rotate(Eigen::AngleAxisd(M_PI / 2, Vec3::UnitY()));
    return p;
  });
  rod.set_friction(0.3);
  s->add_collider(rod);
  ASSERT_TRUE(s->step(100)) << s->failure();  // 0.5 s: the rod moves 10 cm through y = 0
  double min_d = 1e9;
  for (const Vec3& p : s->positions()) min_d = std::min(min_d, rod.query(p, s->time()).distance);
  EXPECT_GT(min_d, 0.0);
  double max_y = -1e9;
  for (const Vec3& p : s->positions()) max_y = std::max(max_y, p.y());
  EXPECT_GT(max_y, 0.02);  // the sheet was pushed along with the rod
}

}  // namespace
}  // namespace gd::sim
