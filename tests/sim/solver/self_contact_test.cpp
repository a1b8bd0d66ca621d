// SelfContact's broad-phase reuse: motions that, after one common translation, stay within
// slack/2 of the last query's boxes reuse its candidates, which still contain every pair a fresh
// query would report; a larger motion runs a new query. (The active pairs selected from the
// candidates, and the distances kept for them, are the solver's: active_set_test.cpp.)
#include "sim/solver/self_contact.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <set>
#include <vector>

#include "sim/contact/broad_phase.h"
#include "sim/demand.h"
#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/solver/scene_data.h"

namespace gd::sim {
namespace {

constexpr Real kDhat = 1e-3;

/// A 0.2 x 0.1 m sheet folded in half along x = 0.1, the flap 1.5 mm above the base.
struct Folded {
  SceneData data;
  std::vector<double> x;
};

Folded folded_sheet() {
  const Mesh m = make_rect(0.2, 0.1, 0.01);
  Folded f{build_scene_data(m, MaterialLibrary::load_default().get("cotton"), {}), {}};
  f.x.resize(3 * m.x.size());
  for (size_t i = 0; i < m.x.size(); ++i) {
    const bool flap = m.x[i].x() > 0.1 + 1e-9;
    f.x[3 * i] = flap ? 0.2 - m.x[i].x() : m.x[i].x();
    f.x[3 * i + 1] = m.x[i].y();
    f.x[3 * i + 2] = flap ? 1.5e-3 : 0.0;
  }
  return f;
}

/// x moved by a random vector of at most `amount` per coordinate.
std::vector<double> jiggled(const std::vector<double>& x, double amount, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-amount, amount);
  std::vector<double> y = x;
  for (double& c : y) c += u(rng);
  return y;
}

using Quad = std::array<int, 5>;  // type, 4 vertices

std::set<Quad> as_set(const ContactPairs& c) {
  std::set<Quad> s;
  for (int k = 0; k < c.size(); ++k) s.insert({c.type[k], c.v[4 * k], c.v[4 * k + 1], c.v[4 * k + 2], c.v[4 * k + 3]});
  return s;
}

/// What a fresh query with margin dhat reports, in SelfContact's vertex form.
std::set<Quad> fresh(const SceneData& d, const std::vector<double>& x0, const std::vector<double>& x1) {
  std::vector<Eigen::Vector2i> edges;
  for (int t = 0; t < d.triangles(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = d.tris[3 * t + k], b = d.tris[3 * t + (k + 1) % 3];
      edges.emplace_back(std::min(a, b), std::max(a, b));
    }
  std::sort(edges.begin(), edges.end(), [](const auto& p, const auto& q) { return p[0] != q[0] ? p[0] < q[0] : p[1] < q[1]; });
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  auto bp = make_brute_force_broad_phase(d.tris, edges, d.n);
  ContactCandidates c;
  bp->find(x0, x1, kDhat, &c);
  std::set<Quad> s;
  for (const auto& p : c.vf) s.insert({0, p[0], d.tris[3 * p[1]], d.tris[3 * p[1] + 1], d.tris[3 * p[1] + 2]});
  for (const auto& p : c.ee) s.insert({1, edges[p[0]][0], edges[p[0]][1], edges[p[1]][0], edges[p[1]][1]});
  return s;
}

TEST(SelfContactBroadPhase, SmallMotionsReuseTheQueryAndMissNothing) {
  const Folded f = folded_sheet();
  SelfContact sc(f.data, kDhat, 1.0);
  sc.find(f.x, f.x);
  ASSERT_EQ(sc.broad_phase_queries(), 1);
  const double within = 0.45 * kBroadPhaseSlack * kDhat;  // each coordinate, both ends: inside slack/2
  for (unsigned seed = 1; seed <= 4; ++seed) {
    const std::vector<double> x0 = jiggled(f.x, within, seed), x1 = jiggled(f.x, within, 100 + seed);
    sc.find(x0, x1);
    EXPECT_EQ(sc.broad_phase_queries(), 1) << "seed " << seed;
    const std::set<Quad> have = as_set(sc.candidates()), need = fresh(f.data, x0, x1);
    ASSERT_GT(need.size(), 100u);
    for (const Quad& q : need) EXPECT_TRUE(have.count(q)) << "missed type " << q[0] << " " << q[1] << " " << q[2];
  }
  EXPECT_EQ(sc.broad_phase_reuses(), 4);
}

/// x moved rigidly by t.
std::vector<double> translated(std::vector<double> x, const Vec3& t) {
  for (size_t k = 0; k < x.size(); ++k) x[k] += t[static_cast<int>(k % 3)];
  return x;
}

// Cloth falling or carried as a whole: far beyond slack/2 in absolute terms, within it after the
// common translation.
TEST(SelfContactBroadPhase, TranslatedMotionsReuseTheQueryAndMissNothing) {
  const Folded f = folded_sheet();
  SelfContact sc(f.data, kDhat, 1.0);
  sc.find(f.x, f.x);
  ASSERT_EQ(sc.broad_phase_queries(), 1);
  const double within = 0.2 * kBroadPhaseSlack * kDhat;  // jiggle: each end within +-slack/5 ...
  for (unsigned seed = 1; seed <= 4; ++seed) {
    const Vec3 t0(0.01 * seed, -0.02, -0.03 * seed), t1 = t0 + Vec3(0.3, 0.1, -0.2) * kBroadPhaseSlack * kDhat;
    // ... and the ends 0.37 slack apart by translation: every box spread over < slack
    const std::vector<double> x0 = jiggled(translated(f.x, t0), within, seed);
    const std::vector<double> x1 = jiggled(translated(f.x, t1), within, 100 + seed);
    sc.find(x0, x1);
    EXPECT_EQ(sc.broad_phase_queries(), 1) << "seed " << seed;
    const std::set<Quad> have = as_set(sc.candidates()), need = fresh(f.data, x0, x1);
    ASSERT_GT(need.size(), 100u);
    for (const Quad& q : need) EXPECT_TRUE(have.count(q)) << "missed type " << q[0] << " " << q[1] << " " << q[2];
    EXPECT_EQ(have, need) << "seed " << seed;  // the filtered list is exactly what a query with margin dhat gives
  }
  // One vertex moving relative to the rest by more than the slack: a new query.
  std::vector<double> x1 = translated(f.x, Vec3(0.05, 0, 0));
  x1[3 * 7 + 2] += 1.2 * kBroadPhaseSlack * kDhat;
  sc.find(translated(f.x, Vec3(0.05, 0, 0)), x1);
  EXPECT_EQ(sc.broad_phase_queries(), 2);
}

TEST(SelfContactBroadPhase, AMotionBeyondTheSlackRunsANewQuery) {
  const Folded f = folded_sheet();
  SelfContact sc(f.data, kDhat, 1.0);
  sc.find(f.x, f.x);
  std::vector<double> x1 = f.x;
  x1[3 * 7 + 2] += 1.2 * kBroadPhaseSlack * kDhat;  // one vertex, one coordinate: its box spreads past the slack
  sc.find(f.x, x1);
  EXPECT_EQ(sc.broad_phase_queries(), 2);
  std::vector<double> bad = f.x;
  bad[0] = std::nan("");
  EXPECT_THROW(sc.find(f.x, bad), InputError);  // not "covered": the broad phase sees it and refuses
}

TEST(SelfContactBroadPhase, IntersectionCountReusesItsQueryAndAgreesWithAFreshOne) {
  Folded f = folded_sheet();
  // Push two flap vertices 3 mm down through the base, off the base's grid lines (the flap lies
  // right above the base's vertices): their triangles cross it.
  int pushed = 0;
  for (int i = 0; i < f.data.n && pushed < 2; ++i)
    if (f.x[3 * i + 2] > 1e-3 && f.x[3 * i] > 0.03 && f.x[3 * i] < 0.07 && f.x[3 * i + 1] > 0.03 && f.x[3 * i + 1] < 0.07 &&
        (pushed == 0 || f.x[3 * i] > 0.05))
      f.x[3 * i] += 3.3e-3, f.x[3 * i + 1] += 2.7e-3, f.x[3 * i + 2] -= 4.5e-3, ++pushed;
  ASSERT_EQ(pushed, 2);
  SelfContact reused(f.data, kDhat, 1.0);
  const int first = reused.count_intersections(f.x);
  EXPECT_GT(first, 0);
  const long queries = reused.broad_phase_queries();
  for (unsigned seed = 1; seed <= 4; ++seed) {
    const std::vector<double> x = jiggled(f.x, 0.45 * kBroadPhaseSlack * kDhat, seed);
    SelfContact fresh_instance(f.data, kDhat, 1.0);
    EXPECT_EQ(reused.count_intersections(x), fresh_instance.count_intersections(x)) << "seed " << seed;
    const std::vector<double> moved = translated(x, Vec3(0.1, -0.05, 0.2) * seed);  // carried as a whole
    SelfContact fresh_moved(f.data, kDhat, 1.0);
    EXPECT_EQ(reused.count_intersections(moved), fresh_moved.count_intersections(moved)) << "seed " << seed;
  }
  EXPECT_EQ(reused.broad_phase_queries(), queries);
}

}  // namespace
}  // namespace gd::sim
