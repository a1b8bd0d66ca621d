// The solver's self-contact candidates (solver/candidates.h), on the CPU backend and on the GPU's
// code paths: motions that, after one common translation, stay within slack/2 of the last
// query's boxes are answered from it, on the backend, and their candidates (select_along) are
// exactly the pairs a fresh query with margin dhat reports along the motion (none of the folded
// sheet's is at zero distance); a motion past the slack queries again; a non-finite motion is
// refused or reaches the broad phase's InputError.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <set>
#include <vector>

#include "sim/backend/cpu/exec_cpu.h"
#include "sim/demand.h"
#include "sim/solver/folded_sheet.h"
#include "sim/solver/solver_impl.h"

namespace gd::sim {
namespace {

using namespace testing_fold;

SceneOptions self_contact_options() {
  SceneOptions o;
  o.self_contact = true;
  o.threads = 2;
  return o;
}

template <class Exec>
struct FoldedSolver {
  Folded f;
  double dhat;
  std::unique_ptr<Solver<Exec>> s;
  FoldedSolver() : f(folded_sheet(0.0)) {
    const SceneOptions o = self_contact_options();
    dhat = effective_contact_distance(o, f.data.thickness);
    f = folded_sheet(1.5 * dhat);  // the flap within dhat + slack of the base
    s = std::make_unique<Solver<Exec>>(std::make_shared<const SceneData>(f.data), o);
  }
  long queries() const { return s->self_contact()->broad_phase_queries(); }
  int gen = 1 << 20;  ///< positions' generations for select_along, one per call (no distance kept between calls)
  /// The candidates of x0 -> x1, as a set.
  std::set<Quad> candidates(const std::vector<double>& x0, std::vector<double> x1) {
    EXPECT_EQ(s->find_candidates(x0, x1, false), 0);
    s->select_along(x0, ++gen);
    return as_set(s->candidate_pairs());
  }
};

template <class Exec>
void small_motions_reuse_the_query_and_miss_nothing() {
  FoldedSolver<Exec> t;
  t.candidates(t.f.x, t.f.x);
  ASSERT_EQ(t.queries(), 1);
  const double within = 0.45 * kBroadPhaseSlack * t.dhat;  // each coordinate, both ends: inside slack/2
  for (unsigned seed = 1; seed <= 4; ++seed) {
    const std::vector<double> x0 = jiggled(t.f.x, within, seed), x1 = jiggled(t.f.x, within, 100 + seed);
    const std::set<Quad> have = t.candidates(x0, x1), need = fresh(t.f.data, x0, x1, t.dhat);
    EXPECT_EQ(t.queries(), 1) << "seed " << seed;
    ASSERT_GT(need.size(), 100u);
    EXPECT_EQ(have, need) << "seed " << seed;  // what a query with margin dhat gives
  }
  EXPECT_EQ(t.s->self_contact()->broad_phase_reuses(), 4);
}

TEST(Candidates, SmallMotionsReuseTheQueryAndMissNothing) { small_motions_reuse_the_query_and_miss_nothing<CpuExec>(); }
TEST(GpuPathsCandidates, SmallMotionsReuseTheQueryAndMissNothing) {
  small_motions_reuse_the_query_and_miss_nothing<CpuGpuPathsExec>();
}

// Cloth falling or carried as a whole: far beyond slack/2 in absolute terms, within it after the
// common translation.
template <class Exec>
void translated_motions_reuse_the_query() {
  FoldedSolver<Exec> t;
  t.candidates(t.f.x, t.f.x);
  ASSERT_EQ(t.queries(), 1);
  const double within = 0.2 * kBroadPhaseSlack * t.dhat;  // jiggle: each end within +-slack/5 ...
  for (unsigned seed = 1; seed <= 4; ++seed) {
    const Vec3 t0(0.01 * seed, -0.02, -0.03 * seed), t1 = t0 + Vec3(0.3, 0.1, -0.2) * kBroadPhaseSlack * t.dhat;
    // ... and the ends 0.37 slack apart by translation: every box spread over < slack
    const std::vector<double> x0 = jiggled(translated(t.f.x, t0), within, seed);
    const std::vector<double> x1 = jiggled(translated(t.f.x, t1), within, 100 + seed);
    const std::set<Quad> have = t.candidates(x0, x1), need = fresh(t.f.data, x0, x1, t.dhat);
    EXPECT_EQ(t.queries(), 1) << "seed " << seed;
    ASSERT_GT(need.size(), 100u);
    EXPECT_EQ(have, need) << "seed " << seed;
  }
  // One vertex moving relative to the rest by more than the slack: a new query, and its answer's
  // candidates.
  const std::vector<double> x0 = translated(t.f.x, Vec3(0.05, 0, 0));
  std::vector<double> x1 = x0;
  x1[3 * 7 + 2] += 1.2 * kBroadPhaseSlack * t.dhat;
  EXPECT_EQ(t.candidates(x0, x1), fresh(t.f.data, x0, x1, t.dhat));
  EXPECT_EQ(t.queries(), 2);
}

TEST(Candidates, TranslatedMotionsReuseTheQuery) { translated_motions_reuse_the_query<CpuExec>(); }
TEST(GpuPathsCandidates, TranslatedMotionsReuseTheQuery) { translated_motions_reuse_the_query<CpuGpuPathsExec>(); }

TEST(Candidates, ANonFiniteMotionIsRefusedOrReachesTheBroadPhase) {
  FoldedSolver<CpuExec> t;
  t.candidates(t.f.x, t.f.x);
  std::vector<double> bad = t.f.x;
  bad[0] = std::nan("");
  EXPECT_EQ(t.s->find_candidates(t.f.x, bad, true), -1);
  EXPECT_EQ(t.queries(), 1);
  EXPECT_THROW(t.s->find_candidates(t.f.x, bad, false), InputError);  // not "covered": the broad phase refuses it
}

}  // namespace
}  // namespace gd::sim
