// The self-contact active set on the backend (solver/active_set.h), run by the CPU backend and by
// the GPU's code paths on the CPU: at every Newton iterate of a sheet falling onto another, the
// active pairs are exactly the pairs a brute-force search finds closer than dhat, the closest
// distance is theirs, the candidates hold them all, and the friction frames at the step start are
// the active pairs' own. Distances kept from the line search's accepted point and from the
// iterate's first selection are what measuring gives (a stale one would show as a wrong list).
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>
#include <set>
#include <vector>

#include "sim/backend/cpu/exec_cpu.h"
#include "sim/contact/barrier.h"
#include "sim/contact/distance.h"
#include "sim/contact/friction.h"
#include "sim/material.h"
#include "sim/solver/scene_data.h"
#include "sim/solver/solver_impl.h"
#include "sim/stacked_sheets.h"

namespace gd::sim {
namespace {

using Key = std::array<int, 5>;  // type, 4 vertices (EE: each edge's ends sorted, the edges sorted)

Key key(int type, const int* v) {
  if (type == 0) return {0, v[0], v[1], v[2], v[3]};
  std::array<int, 2> a{std::min(v[0], v[1]), std::max(v[0], v[1])}, b{std::min(v[2], v[3]), std::max(v[2], v[3])};
  if (b < a) std::swap(a, b);
  return {1, a[0], a[1], b[0], b[1]};
}

/// Every pair of the mesh at x, by its distance (VF: a vertex and a triangle without it; EE: two
/// edges sharing no vertex).
struct BruteForce {
  std::set<Key> active;
  double closest = std::numeric_limits<double>::infinity();
};

BruteForce brute_force(const SceneData& d, const std::vector<double>& x, double dhat) {
  auto at = [&](int i) { return Vec3(x[3 * i], x[3 * i + 1], x[3 * i + 2]); };
  BruteForce out;
  auto consider = [&](int type, const int* v) {
    const double d2 = type == 0 ? point_triangle_distance2(at(v[0]), at(v[1]), at(v[2]), at(v[3]), nullptr, nullptr)
                                : edge_edge_distance2(at(v[0]), at(v[1]), at(v[2]), at(v[3]), nullptr, nullptr);
    const double dist = std::sqrt(std::max(d2, 0.0));
    if (dist > 0 && dist < dhat) {
      out.active.insert(key(type, v));
      out.closest = std::min(out.closest, dist);
    }
  };
  for (int t = 0; t < d.triangles(); ++t)
    for (int i = 0; i < d.n; ++i) {
      const int v[4] = {i, d.tris[3 * t], d.tris[3 * t + 1], d.tris[3 * t + 2]};
      if (i != v[1] && i != v[2] && i != v[3]) consider(0, v);
    }
  std::set<std::array<int, 2>> edges;
  for (int t = 0; t < d.triangles(); ++t)
    for (int k = 0; k < 3; ++k) {
      const int a = d.tris[3 * t + k], b = d.tris[3 * t + (k + 1) % 3];
      edges.insert({std::min(a, b), std::max(a, b)});
    }
  const std::vector<std::array<int, 2>> e(edges.begin(), edges.end());
  for (size_t p = 0; p < e.size(); ++p)
    for (size_t q = p + 1; q < e.size(); ++q) {
      if (e[p][0] == e[q][0] || e[p][0] == e[q][1] || e[p][1] == e[q][0] || e[p][1] == e[q][1]) continue;
      const int v[4] = {e[p][0], e[p][1], e[q][0], e[q][1]};
      consider(1, v);
    }
  return out;
}

std::set<Key> pair_set(const ContactPairs& c, bool* duplicates) {
  std::set<Key> s;
  for (int k = 0; k < c.size(); ++k) s.insert(key(c.type[k], &c.v[4 * k]));
  *duplicates = static_cast<int>(s.size()) != c.size();
  return s;
}

/// The solver's lists at its current positions against the brute force there.
template <class Exec>
void expect_lists_at_current_positions(Solver<Exec>& s, const SceneData& d, double dhat, double closest,
                                       const char* where, int* active_seen) {
  std::vector<double> x;
  s.get_positions(x);
  const BruteForce ref = brute_force(d, x, dhat);
  bool dup_a = false, dup_c = false;
  const std::set<Key> active = pair_set(s.active_pairs(), &dup_a), cand = pair_set(s.candidate_pairs(), &dup_c);
  EXPECT_FALSE(dup_a) << where;
  EXPECT_FALSE(dup_c) << where;
  EXPECT_EQ(active, ref.active) << where;
  EXPECT_EQ(closest, ref.closest) << where;
  EXPECT_TRUE(std::includes(cand.begin(), cand.end(), active.begin(), active.end())) << where;
  *active_seen = std::max(*active_seen, static_cast<int>(active.size()));
}

/// The friction pairs at the step start: the active pairs with a positive normal force, in their
/// order, each with the frame and force the contact functions give at x_t.
template <class Exec>
void expect_friction_of_active_pairs(Solver<Exec>& s, const std::vector<double>& xt, double dhat) {
  auto at = [&](int i) { return Vec3(xt[3 * i], xt[3 * i + 1], xt[3 * i + 2]); };
  const ContactPairs a = s.active_pairs();
  const auto f = s.friction_pairs();
  size_t k = 0;
  for (int c = 0; c < a.size(); ++c) {
    const int* v = &a.v[4 * c];
    const Vec3 p0 = at(v[0]), p1 = at(v[1]), p2 = at(v[2]), p3 = at(v[3]);
    const double d2 = a.type[c] == 0 ? point_triangle_distance2(p0, p1, p2, p3, nullptr, nullptr)
                                     : edge_edge_distance2(p0, p1, p2, p3, nullptr, nullptr);
    double lambda = contact_normal_force(std::sqrt(std::max(d2, 0.0)), 0.0, dhat, a.kappa[c]);
    if (a.type[c] == 1) lambda *= ee_mollifier(p0, p1, p2, p3, a.eps_x[c], nullptr, nullptr);
    if (!(lambda > 0) || !std::isfinite(lambda)) continue;
    ASSERT_LT(k, f.lambda.size()) << "friction pair missing for active pair " << c;
    EXPECT_EQ(f.lambda[k], lambda);
    const ContactFrictionFrame fr = a.type[c] == 0 ? vf_friction_frame(p0, p1, p2, p3) : ee_friction_frame(p0, p1, p2, p3);
    for (int j = 0; j < 4; ++j) EXPECT_EQ(f.v[4 * k + j], v[j]);
    for (int j = 0; j < 4; ++j) EXPECT_EQ(f.w[4 * k + j], fr.w[j]);
    for (int j = 0; j < 6; ++j) EXPECT_EQ(f.T[6 * k + j], fr.T.data()[j]);
    ++k;
  }
  EXPECT_EQ(k, f.lambda.size());
}

/// A 4 x 4 cm sheet resting on the table and a copy 1.4 mm above it, shifted by a third of a
/// cell, falling onto it; one corner of the top sheet pulled up and sideways by a grip. The
/// driver's stages are called in step()'s order, checked after each selection.
template <class Exec>
void falling_sheet_selects_what_brute_force_finds() {
  const Mesh m = test::stacked_sheets(0.04, 0.005, 0.0005, Vec3(0.0017, 0.0011, 0.0014));
  auto data = std::make_shared<const SceneData>(build_scene_data(m, MaterialLibrary::load_default().get("cotton"), {}));
  const SceneData& d = *data;
  SceneOptions o;
  o.self_contact = true;
  o.threads = 2;
  const double dhat = effective_contact_distance(o, d.thickness);
  Solver<Exec> s(data, o);
  const int top_corner = d.n / 2;
  int active_seen = 0, friction_seen = 0;
  for (int step = 0; step < 8; ++step) {
    KinematicTargets kin;
    kin.vertices = {top_corner};
    const Vec3 target = m.x[top_corner] + Vec3(0.0004, 0.0, 0.0006) * step;
    kin.targets = {target.x(), target.y(), target.z()};
    std::vector<double> xt;
    s.get_positions(xt);
    s.begin_step(kin, false);
    expect_friction_of_active_pairs(s, xt, dhat);
    friction_seen = std::max(friction_seen, static_cast<int>(s.friction_pairs().lambda.size()));
    StepStats st;
    double scale = 0;
    for (int k = 0; k < 3; ++k) {
      const std::string at = "step " + std::to_string(step) + ", iteration " + std::to_string(k);
      s.select_contacts();
      expect_lists_at_current_positions(s, d, dhat, s.closest_active_pair(), (at + ", iterate").c_str(), &active_seen);
      const double e0 = s.assemble();
      ASSERT_TRUE(std::isfinite(e0)) << at;
      s.merge_couplings();
      s.prepare_linear_solve();
      s.order_estimator();
      s.solve_linear(scale);
      ASSERT_TRUE(s.find_contacts_along_step()) << at;
      expect_lists_at_current_positions(s, d, dhat, s.closest_active_pair(), (at + ", along the step").c_str(),
                                        &active_seen);
      const double alpha = s.step_length(s.max_step(), e0, &st);
      s.accept_step(alpha);  // the trial point's distances kept: the next selection reads them
      if (k == 0) scale = 1;
    }
    s.end_step();
  }
  EXPECT_GT(active_seen, 100) << "the sheets never came into contact: the test checks little";
  EXPECT_GT(friction_seen, 50);
}

TEST(ActiveSet, FallingSheetSelectsWhatBruteForceFinds) { falling_sheet_selects_what_brute_force_finds<CpuExec>(); }

TEST(GpuPathsActiveSet, FallingSheetSelectsWhatBruteForceFinds) {
  falling_sheet_selects_what_brute_force_finds<CpuGpuPathsExec>();
}

/// One code path: the CPU backend and the GPU's paths select the same lists at the same state
/// (the first iterate of the first step, before any atomic add has moved a bit), and a whole
/// step of each ends with the same active and candidate counts.
TEST(GpuPathsActiveSet, SameListsAsTheCpuBackend) {
  const Mesh m = test::stacked_sheets(0.04, 0.005, 0.0005, Vec3(0.0017, 0.0011, 0.0006));
  auto data = std::make_shared<const SceneData>(build_scene_data(m, MaterialLibrary::load_default().get("cotton"), {}));
  SceneOptions o;
  o.self_contact = true;
  Solver<CpuExec> cpu(data, o);
  Solver<CpuGpuPathsExec> gpu(data, o);
  const KinematicTargets kin;
  cpu.begin_step(kin, false);
  gpu.begin_step(kin, false);
  cpu.select_contacts();
  gpu.select_contacts();
  const ContactPairs a = cpu.active_pairs(), b = gpu.active_pairs();
  ASSERT_GT(a.size(), 100);
  EXPECT_EQ(a.v, b.v);
  EXPECT_EQ(a.type, b.type);
  EXPECT_EQ(a.kappa, b.kappa);
  EXPECT_EQ(cpu.candidate_pairs().v, gpu.candidate_pairs().v);
  EXPECT_EQ(cpu.friction_pairs().v, gpu.friction_pairs().v);
  EXPECT_EQ(cpu.friction_pairs().lambda, gpu.friction_pairs().lambda);
  EXPECT_EQ(cpu.closest_active_pair(), gpu.closest_active_pair());
}

}  // namespace
}  // namespace gd::sim
