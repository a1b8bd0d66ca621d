// Pads in the solve (SceneOptions::pad_stiffness; server/sim/solver/pads_in_solve.h): a pad the
// predictor stopped short goes on within Newton's iterations, one unknown per hand pulled towards
// the step's end by a spring and held back by the cloth's barrier and friction. Checked against the
// physics it stands for: where the pad stops, the spring's pull balances the cloth's push on it;
// the layers it presses stay apart; cloth it does not touch moves as if it were not there.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <memory>

#include "sim/mesh.h"
#include "sim/scene.h"
#include "sim/solver/two_layers.h"

namespace gd::sim {
namespace {

using testing_layers::PadMotion;

struct ClosingRun {
  int stopped = 0, interior = 0, found = 0, untangled = 0;
  double first_reached = -1, min_gap = std::numeric_limits<double>::infinity();
  double worst_balance = 0;  // largest |pull - push| / pull over the steps the pad stopped within its path
  double last_pull = 0, last_push = 0;
  double patch_fell = 0, free_fall = 0;  // the far patch's mean drop, and backward Euler's free fall, m
  int waited = 0;                        // steps the pad waited at its step's start (s = 0)
  bool failed = false;
};

// Two hanging layers between two box pads; the +y pad closes on the still -y pad at 0.4 m/s until
// their faces would touch, and holds: the stack between them cannot get out of the way, so the
// pad stops short. With pad_stiffness K it stops where its spring K L (1 - s) (L: the step's path)
// meets the cloth's push along its motion (Scene::collider_forces, the barrier's reaction). A
// 3 x 3 cm patch 0.3 m away falls freely beside them (no air, nothing under it). Newton runs to
// 20 iterations a step (the pads have no friction, so the default cap of 8 would apply).
ClosingRun close_on_stack(double pad_stiffness, double seconds, double friction,
                          BackendKind backend = BackendKind::kCpu) {
  const Material cotton = MaterialLibrary::load_default().get("cotton");
  SceneOptions o = testing_layers::pinch_options();
  o.pad_stiffness = pad_stiffness;
  o.backend = backend;
  o.newton_max_iters = 20;
  const double dhat = effective_contact_distance(o, cotton.thickness);
  const double W = 0.04, L = 0.06, grip = 0.02, gap = 0.3 * dhat, thick = 0.005, speed = 0.4;
  Mesh mesh = testing_layers::two_hanging_layers(W, L, gap);
  const int n_stack = static_cast<int>(mesh.x.size());
  const Mesh patch = make_rect(0.03, 0.03, 0.006);
  for (const Vec3& p : patch.x) mesh.x.push_back(p + Vec3(0.3, 0, 0.5));
  mesh.uv.insert(mesh.uv.end(), patch.uv.begin(), patch.uv.end());
  for (const Eigen::Vector3i& t : patch.tris) mesh.tris.push_back(t + Eigen::Vector3i::Constant(n_stack));
  auto scene = Scene::create(mesh, cotton, o);
  auto patch_z = [&] {
    const std::vector<Vec3> x = scene->positions();
    double z = 0;
    for (size_t i = n_stack; i < x.size(); ++i) z += x[i].z();
    return z / static_cast<double>(x.size() - n_stack);
  };
  const double patch_z0 = patch_z();
  const double half_opening = 0.5 * gap + 0.25 * dhat, z = 0.5 + L - 0.5 * grip;
  const double y_start = half_opening + thick, y_end = -half_opening + thick;
  auto target = [=](double t) { return Vec3(0.5 * W, std::max(y_end, y_start - speed * t), z); };
  auto moving = std::make_shared<PadMotion>();
  moving->from = moving->to = target(0);
  const int id = testing_layers::add_squeeze_pads(*scene, moving, W, thick, grip, y_start, z, true, false, false,
                                                  friction).second;
  ClosingRun r;
  int steps = 0;
  while (scene->time() < seconds - 1e-9 && !scene->failed()) {
    moving->next(scene->collider_reached({id})[0], scene->time(), o.dt, target(scene->time() + o.dt));
    const Vec3 path = moving->to - moving->from;
    scene->step();
    const StepStats& st = scene->last_stats();
    r.found = std::max(r.found, st.intersecting_found);
    r.untangled += st.untangled;
    r.min_gap = std::min(r.min_gap, st.min_self_distance);
    const double s = scene->collider_reached({id})[0];
    if (s < 1.0 && path.norm() > 0) {
      ++r.stopped;
      if (r.first_reached < 0) r.first_reached = s;
      // The cloth's push on the pad where it got to (Scene::collider_forces reads the poses at the
      // scene's time: the motion is held there; the next step starts from it anyway).
      moving->from = moving->to = moving->at(moving->t0 + s * (moving->t1 - moving->t0)).translation();
      const double pull = pad_stiffness * path.norm() * (1 - s);
      const double push = -scene->collider_forces({id})[0].dot(path.normalized());
      if (std::getenv("GD_TEST_VERBOSE")) std::printf("  t %.3f s %.4f pull %.4g push %.4g\n", scene->time(), s, pull, push);
      // Within its path (0 < s < 1) the pad is where the two balance; at s = 0 the cloth pushes
      // harder than the spring pulls and the pad waits at the step's start (it does not go back
      // along a path it has already made).
      if (s <= 1e-3) ++r.waited;
      if (pad_stiffness > 0 && s > 1e-3) {
        ++r.interior;
        r.worst_balance = std::max(r.worst_balance, std::abs(pull - push) / pull);
        r.last_pull = pull, r.last_push = push;
      }
    }
  }
  r.failed = scene->failed();
  // Backward Euler from rest: v_k = v_(k-1) - g h, z_k = z_(k-1) + h v_k: g h^2 n (n + 1) / 2.
  const double n = std::round(scene->time() / o.dt);
  r.free_fall = kGravity * o.dt * o.dt * n * (n + 1) / 2;
  r.patch_fell = patch_z0 - patch_z();
  return r;
}

// Where the pad stops short within its path, its spring and the cloth's push balance (to Newton's
// tolerance), for a soft, a middling and a stiff spring (without friction, which the push leaves
// out); the stiffer the spring the further the pad gets; the layers stay apart and no step finds
// an intersecting pair.
TEST(PadsInTheSolve, APadStopsWhereItsSpringMeetsTheClothsPush) {
  double last_reached = 0;
  for (const double K : {3e3, 3e4, 3e5}) {
    SCOPED_TRACE(testing::Message() << "pad stiffness " << K << " N/m");
    const ClosingRun r = close_on_stack(K, 0.05, 0.0);
    std::printf("pad stiffness %.0f N/m: stopped short %d times (%d within the path), first at %.3f of the motion; "
                "spring %.4f N against the cloth's push %.4f N (worst mismatch %.2f%%), layers %.2e m apart at least\n",
                K, r.stopped, r.interior, r.first_reached, r.last_pull, r.last_push, 100 * r.worst_balance, r.min_gap);
    EXPECT_FALSE(r.failed);
    EXPECT_GT(r.interior, 0) << "the pad never stopped within its path: the test does not exercise the spring";
    EXPECT_LT(r.worst_balance, 0.05) << "the spring's pull and the cloth's push should balance";
    EXPECT_GT(r.first_reached, last_reached) << "a stiffer spring presses further";
    EXPECT_EQ(r.found, 0);
    EXPECT_EQ(r.untangled, 0);
    EXPECT_GT(r.min_gap, 1e-6);
    last_reached = r.first_reached;
  }
}

// While the cloth pushes the closing pad back harder than its spring pulls, the pad waits at its
// step's start (s = 0), and everything else takes its step as usual: the far patch falls as in
// free fall, to 1%. Solved by bounding the step length at s = 0 instead, every such step took none
// of Newton's direction after its first iteration and passed as converged: the patch fell 0.5-1.1
// mm of the 13.5 (docs/robot.md, "A hand at the other end of its step": a T-shirt stood still in
// mid-fling for 70 steps).
TEST(PadsInTheSolve, APadWaitingAtItsStepsStartHoldsNothingElseStill) {
  for (const double K : {3e3, 3e5}) {
    SCOPED_TRACE(testing::Message() << "pad stiffness " << K << " N/m");
    const ClosingRun r = close_on_stack(K, 0.05, 0.0);
    std::printf("pad stiffness %.0f N/m: the pad waited at its step's start %d times; the far patch fell %.3f mm, "
                "free fall %.3f mm\n", K, r.waited, 1e3 * r.patch_fell, 1e3 * r.free_fall);
    EXPECT_FALSE(r.failed);
    EXPECT_GT(r.waited, 0) << "the pad never waited at its step's start: the test does not exercise it";
    EXPECT_NEAR(r.patch_fell, r.free_fall, 0.01 * r.free_fall);
    EXPECT_EQ(r.found, 0);
  }
}

// The CUDA backend's paths (run on the CPU: BackendKind::kCpuGpuPaths) give the same squeeze: the
// hands' part is host code over the backend's arrays, and the pads' relative CCD bound a kernel.
TEST(PadsInTheSolveGpuPaths, TheSqueezeMatchesTheCpuBackend) {
  const ClosingRun cpu = close_on_stack(3e4, 0.02, 0.0);
  const ClosingRun gpu = close_on_stack(3e4, 0.02, 0.0, BackendKind::kCpuGpuPaths);
  std::printf("first stop: %.6f of the motion on the CPU, %.6f on the GPU's paths; push %.6f / %.6f N\n",
              cpu.first_reached, gpu.first_reached, cpu.last_push, gpu.last_push);
  EXPECT_FALSE(gpu.failed);
  EXPECT_GT(gpu.interior, 0);
  EXPECT_NEAR(gpu.first_reached, cpu.first_reached, 1e-3);
  EXPECT_NEAR(gpu.last_push, cpu.last_push, 1e-3 * cpu.last_push);
  EXPECT_EQ(gpu.found, 0);
}

}  // namespace
}  // namespace gd::sim
