// The solver's budget of blocking round trips to the host (a GPU stalls on each), counted by the
// CUDA backend's code paths run on the CPU (BackendKind::kCpuGpuPaths; sim/backend/round_trips.h):
// PCG keeps its scalars in the backend's memory and reads its stop flag once every 8 iterations,
// and a Newton iteration makes a fixed, small number of round trips whatever its PCG count.
#include "sim/backend/round_trips.h"

#include <gtest/gtest.h>

#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/scene.h"
#include "sim/library_materials.h"

namespace gd::sim {
namespace {

using test::cotton;

/// Round trips of one step of `s` on this thread.
HostRoundTrips step_round_trips(Scene& s) {
  const HostRoundTrips before = host_round_trips();
  EXPECT_TRUE(s.step()) << s.failure();
  const HostRoundTrips after = host_round_trips();
  return {after.reductions - before.reductions, after.downloads - before.downloads};
}

/// A 0.3 m square (961 vertices) hanging from two corners.
std::unique_ptr<Scene> hanging_square(SceneOptions o) {
  Mesh m = make_rect(0.3, 0.3, 0.01);
  for (Vec3& p : m.x) p.z() = 0.3;
  auto s = Scene::create(m, cotton(), o);
  s->pin({0, 30});
  return s;
}

// PCG's share: a Newton iteration of the swinging square solved to 1e-2 and one solved to 1e-12
// (many more PCG iterations) differ by one round trip per 8 PCG iterations.
TEST(GpuPathsRoundTrips, PcgReadsTheHostOncePerEightIterations) {
  SceneOptions o;
  o.backend = BackendKind::kCpuGpuPaths;
  o.threads = 1;
  o.newton_max_iters = 1;
  o.pcg_newton_fraction = 0;
  o.preconditioner = PreconditionerKind::kBlockJacobi;
  o.pcg_max_iters = 400;  // both stop at their tolerance, not at the cap
  auto loose = hanging_square(o);
  o.pcg_tol = 1e-12;
  auto tight = hanging_square(o);
  for (Scene* s : {loose.get(), tight.get()}) ASSERT_TRUE(s->step(10)) << s->failure();  // swinging
  const HostRoundTrips a = step_round_trips(*loose), b = step_round_trips(*tight);
  const int pcg_a = loose->last_stats().pcg_iters, pcg_b = tight->last_stats().pcg_iters;
  ASSERT_GT(pcg_b - pcg_a, 80);
  EXPECT_EQ(b.reductions, a.reductions) << "PCG's dot products must stay on the backend";
  EXPECT_LE(b.downloads - a.downloads, (pcg_b - pcg_a) / 8 + 1);
}

// A whole step, with and without self-contact: at most 25 round trips per Newton iteration
// (contact lists, the MAS estimator's level sizes, the stopping rule) plus PCG's one per 8
// iterations. An evaluation reads its five energy terms back at once, the CCD bounds come back
// together, and so do an accepted step's two norms; with a round trip per reduction (33-36 per
// Newton iteration beside PCG's in this fold) the budget fails, and with one per PCG iteration,
// as before the scalars moved to the backend, it would be several hundred per step here.
TEST(GpuPathsRoundTrips, AStepStaysWithinItsBudget) {
  for (const bool contact : {false, true}) {
    Mesh m = make_rect(0.3, 0.3, 0.01);
    for (Vec3& p : m.x)  // contact: folded in half, the flap 4 mm above the base
      p = contact && p.x() > 0.15 ? Vec3(0.3 - p.x(), p.y(), 0.304) : Vec3(p.x(), p.y(), 0.3);
    SceneOptions o;
    o.backend = BackendKind::kCpuGpuPaths;
    o.self_contact = contact;
    o.threads = 1;
    auto s = Scene::create(m, cotton(), o);
    if (!contact) s->pin({0, 30});
    long pcg = 0;
    for (int k = 0; k < 8; ++k) {
      const HostRoundTrips r = step_round_trips(*s);
      const StepStats& st = s->last_stats();
      pcg += st.pcg_iters;
      EXPECT_LE(r.total(), 25 * st.newton_iters + st.pcg_iters / 8 + 10)
          << (contact ? "fold" : "drape") << " step " << k << ": " << st.newton_iters << " Newton, " << st.pcg_iters
          << " PCG iterations, " << r.reductions << " reductions, " << r.downloads << " downloads";
    }
    EXPECT_GT(pcg, 100);
  }
}

// The CPU backend's own paths count nothing: its "device" is the host.
TEST(GpuPathsRoundTrips, TheCpuBackendCountsNone) {
  SceneOptions o;
  o.threads = 1;
  auto s = hanging_square(o);
  EXPECT_EQ(step_round_trips(*s).total(), 0);
}

}  // namespace
}  // namespace gd::sim
