#include "sim/contact/untangle.h"
#include "sim/contact/tri_tri_intersect.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "sim/mesh.h"

namespace gd::sim {
namespace {

/// A flat mesh soup: positions (3 per vertex) and triangles (3 per triangle).
struct Soup {
  std::vector<double> x;
  std::vector<int> tris;
  int nv() const { return static_cast<int>(x.size() / 3); }
  int nt() const { return static_cast<int>(tris.size() / 3); }
  Vec3 v(int i) const { return Vec3(x[3 * i], x[3 * i + 1], x[3 * i + 2]); }
};

/// Appends `m` with each vertex mapped through f(rest position); returns the first vertex index.
template <class F>
int append(Soup* s, const Mesh& m, F f) {
  const int base = s->nv();
  for (const Vec3& p : m.x) {
    const Vec3 q = f(p);
    s->x.insert(s->x.end(), {q.x(), q.y(), q.z()});
  }
  for (const auto& t : m.tris) s->tris.insert(s->tris.end(), {base + t[0], base + t[1], base + t[2]});
  return base;
}

// Independent reference for triangles in general position: strict edge-through-triangle tests by
// signed volumes, with volumes below 1e-9 of the scale treated as zero (coplanar or touching
// configurations count as not intersecting; the test geometries avoid them).
int orient(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  const Vec3 u = b - a, v = c - a, w = d - a;
  const double vol = u.cross(v).dot(w);
  const double scale = u.norm() * v.norm() * w.norm();
  return vol > 1e-9 * scale ? 1 : (vol < -1e-9 * scale ? -1 : 0);
}

bool ref_segment_crosses(const Vec3& p, const Vec3& q, const Vec3& a, const Vec3& b, const Vec3& c) {
  if (orient(a, b, c, p) * orient(a, b, c, q) >= 0) return false;
  const int o0 = orient(p, q, a, b), o1 = orient(p, q, b, c), o2 = orient(p, q, c, a);
  return (o0 > 0 && o1 > 0 && o2 > 0) || (o0 < 0 && o1 < 0 && o2 < 0);
}

bool ref_tri_tri(const Soup& s, int ta, int tb) {
  const Vec3 A[3] = {s.v(s.tris[3 * ta]), s.v(s.tris[3 * ta + 1]), s.v(s.tris[3 * ta + 2])};
  const Vec3 B[3] = {s.v(s.tris[3 * tb]), s.v(s.tris[3 * tb + 1]), s.v(s.tris[3 * tb + 2])};
  for (int k = 0; k < 3; ++k) {
    if (ref_segment_crosses(A[k], A[(k + 1) % 3], B[0], B[1], B[2])) return true;
    if (ref_segment_crosses(B[k], B[(k + 1) % 3], A[0], A[1], A[2])) return true;
  }
  return false;
}

int ref_count(const Soup& s) {
  int n = 0;
  for (int a = 0; a < s.nt(); ++a)
    for (int b = a + 1; b < s.nt(); ++b) {
      bool shared = false;
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) shared |= s.tris[3 * a + i] == s.tris[3 * b + j];
      if (!shared && ref_tri_tri(s, a, b)) ++n;
    }
  return n;
}

double max_displacement(const Soup& before, const Soup& after, int first = 0, int last = -1) {
  if (last < 0) last = before.nv();
  double m = 0;
  for (int i = first; i < last; ++i) m = std::max(m, (after.v(i) - before.v(i)).norm());
  return m;
}

/// Runs untangle with all pairs as candidates and checks the end state exactly.
UntangleResult run_untangle(Soup* s, const std::vector<int>& fixed, double gap) {
  const auto all = all_triangle_pairs(s->tris, s->nv());
  auto cand = [&](const std::vector<double>&) { return all; };
  const UntangleResult r = untangle(&s->x, s->tris, fixed, cand, gap);
  EXPECT_EQ(r.intersecting_after, 0);
  EXPECT_TRUE(intersecting_pairs(s->x, s->tris, all).empty());
  EXPECT_EQ(ref_count(*s), 0);
  return r;
}

constexpr double kGap = 1e-3;

// Sheet A flat at z = 0; sheet B 5 mm above with a Gaussian bump pushed 4 mm through A.
constexpr double kBumpDepth = 0.004;
Soup bump_through_sheet(int* b_first) {
  Soup s;
  const Mesh a = make_rect(0.16, 0.16, 0.01);
  append(&s, a, [](const Vec3& p) { return Vec3(p.x(), p.y(), 0.0); });
  *b_first = append(&s, a, [](const Vec3& p) {
    const double x = p.x() + 0.003, y = p.y() + 0.004;  // not vertex-aligned with A
    const double r2 = (x - 0.08) * (x - 0.08) + (y - 0.08) * (y - 0.08);
    const double sigma = 0.02;
    return Vec3(x, y, 0.005 - (0.005 + kBumpDepth) * std::exp(-r2 / (2 * sigma * sigma)));
  });
  return s;
}

/// Fixes the boundary vertices of both sheets of bump_through_sheet.
std::vector<int> boundary_fixed(const Soup& s, int b_first) {
  std::vector<int> fixed(s.nv(), 0);
  for (int i = 0; i < s.nv(); ++i) {
    const Vec3 p = s.v(i);
    const double ox = i < b_first ? 0.0 : 0.003, oy = i < b_first ? 0.0 : 0.004;
    const double x = p.x() - ox, y = p.y() - oy;
    if (std::min({x, y, 0.16 - x, 0.16 - y}) < 1e-9) fixed[i] = 1;
  }
  return fixed;
}

TEST(ContactIntersectingPairs, FindsCrossingSheetsAndMatchesBruteForce) {
  int b0;
  const Soup s = bump_through_sheet(&b0);
  const int a_tris = static_cast<int>(make_rect(0.16, 0.16, 0.01).tris.size());
  const auto all = all_triangle_pairs(s.tris, s.nv());
  const auto pairs = intersecting_pairs(s.x, s.tris, all);
  EXPECT_GT(pairs.size(), 0u);
  EXPECT_EQ(static_cast<int>(pairs.size()), ref_count(s));
  for (const auto& p : pairs) EXPECT_LT(p[0], p[1]);
  EXPECT_TRUE(std::is_sorted(pairs.begin(), pairs.end(), [](const auto& p, const auto& q) {
    return p[0] < q[0] || (p[0] == q[0] && p[1] < q[1]);
  }));
  // Every pair joins a triangle of A with one of B (each sheet alone is intersection-free).
  for (const auto& p : pairs) EXPECT_TRUE(p[0] < a_tris && p[1] >= a_tris);
  // Candidate order and repetition do not matter.
  std::vector<Eigen::Vector2i> shuffled;
  for (auto it = all.rbegin(); it != all.rend(); ++it) {
    shuffled.emplace_back((*it)[1], (*it)[0]);
    shuffled.push_back(*it);
  }
  EXPECT_EQ(intersecting_pairs(s.x, s.tris, shuffled), pairs);
}

TEST(ContactIntersectingPairs, FlatSheetHasNone) {
  const Mesh m = make_rect(0.1, 0.1, 0.01);
  Soup s;
  append(&s, m, [](const Vec3& p) { return p; });
  // All pairs including adjacent ones (which touch and must be skipped).
  std::vector<Eigen::Vector2i> every;
  for (int a = 0; a < s.nt(); ++a)
    for (int b = a + 1; b < s.nt(); ++b) every.emplace_back(a, b);
  EXPECT_TRUE(intersecting_pairs(s.x, s.tris, every).empty());
  const auto all = all_triangle_pairs(s.tris, s.nv());
  EXPECT_LT(all.size(), every.size());
  EXPECT_TRUE(intersecting_pairs(s.x, s.tris, all).empty());
}

// Touching (a vertex on the other face, or through it by less than a nanometre) is contact, not a
// crossing; the same triangle a micrometre through the face is one.
TEST(ContactIntersectingPairs, TouchingIsContactNotACrossing) {
  const std::vector<int> tris = {0, 1, 2, 3, 4, 5};
  const std::vector<Eigen::Vector2i> cand = {{0, 1}};
  const Vec3 a0(0, 0, 0), a1(0.05, 0, 0), a2(0, 0.05, 0);
  const Vec3 up(0, 0, 0.02), side(0.01, 0, 0);
  auto count = [&](double depth) {  // B's lowest vertex at (0.01, 0.01, -depth)
    const Vec3 p(0.01, 0.01, -depth), q = p + up, r = p + up + side;
    EXPECT_TRUE(triangles_intersect(a0, a1, a2, p, q, r)) << depth;  // the closed test sees all
    const std::vector<double> x = {a0.x(), a0.y(), a0.z(), a1.x(), a1.y(), a1.z(), a2.x(), a2.y(), a2.z(),
                                   p.x(),  p.y(),  p.z(),  q.x(),  q.y(),  q.z(),  r.x(),  r.y(),  r.z()};
    return static_cast<int>(intersecting_pairs(x, tris, cand).size());
  };
  EXPECT_EQ(count(0.0), 0);
  EXPECT_EQ(count(1e-10), 0);
  EXPECT_EQ(count(1e-6), 1);
  EXPECT_EQ(count(1e-3), 1);
}

TEST(ContactUntangle, BumpPushedThroughSheet) {
  int b0;
  Soup s = bump_through_sheet(&b0);
  const Soup before = s;
  const std::vector<int> fixed = boundary_fixed(s, b0);
  const UntangleResult r = run_untangle(&s, fixed, kGap);
  EXPECT_GT(r.intersecting_before, 0);
  EXPECT_GT(r.iterations, 0);
  EXPECT_LE(r.iterations, 20);
  EXPECT_LT(max_displacement(before, s), 3 * (kBumpDepth + kGap));
  for (int i = 0; i < s.nv(); ++i)
    if (fixed[i]) EXPECT_EQ(s.v(i), before.v(i)) << i;
}

TEST(ContactUntangle, BumpThroughKinematicSheetMovesOnlyTheBump) {
  int b0;
  Soup s = bump_through_sheet(&b0);
  const Soup before = s;
  std::vector<int> fixed(s.nv(), 0);
  for (int i = 0; i < b0; ++i) fixed[i] = 1;  // sheet A is kinematic
  run_untangle(&s, fixed, kGap);
  EXPECT_EQ(max_displacement(before, s, 0, b0), 0.0);
  EXPECT_LT(max_displacement(before, s, b0), 3 * (kBumpDepth + kGap));
  // B now lies above A (flat at z = 0); the vertices that moved keep a clearance of about gap.
  for (int i = b0; i < s.nv(); ++i) {
    EXPECT_GT(s.v(i).z(), 0.0);
    if (s.v(i) != before.v(i)) EXPECT_GT(s.v(i).z(), 0.5 * kGap);
  }
}

TEST(ContactUntangle, TiltedSheetPushedThroughAnother) {
  Soup s;
  append(&s, make_rect(0.16, 0.16, 0.01), [](const Vec3& p) { return Vec3(p.x(), p.y(), 0.0); });
  const double theta = std::numbers::pi / 6, depth = 0.0093;  // no vertex on A's plane
  const int b0 = append(&s, make_rect(0.08, 0.08, 0.01), [&](const Vec3& p) {
    return Vec3(0.0405 + p.x() * std::cos(theta), 0.0395 + p.y(), -depth + p.x() * std::sin(theta));
  });
  const int before_count = static_cast<int>(intersecting_pairs(s.x, s.tris, all_triangle_pairs(s.tris, s.nv())).size());
  EXPECT_GT(before_count, 0);
  EXPECT_EQ(before_count, ref_count(s));
  const Soup before = s;
  std::vector<int> fixed(s.nv(), 0);
  for (int i = 0; i < b0; ++i) {  // A's boundary is held
    const Vec3 p = s.v(i);
    if (std::min({p.x(), p.y(), 0.16 - p.x(), 0.16 - p.y()}) < 1e-9) fixed[i] = 1;
  }
  const UntangleResult r = run_untangle(&s, fixed, kGap);
  EXPECT_EQ(r.intersecting_before, before_count);
  EXPECT_LT(max_displacement(before, s), 3 * (depth + kGap));
  for (int i = 0; i < s.nv(); ++i)
    if (fixed[i]) EXPECT_EQ(s.v(i), before.v(i));
  // The smaller side (B's lower strip) was moved, not the large sheet A.
  EXPECT_LT(max_displacement(before, s, 0, b0), 1e-12);
}

TEST(ContactUntangle, FoldedFlapThroughBase) {
  // 0.2 x 0.1 sheet folded at x = 0.1 around a half circle of radius rho; the flap comes back
  // over the base, sloping down so that its last ~1 cm lies up to 4 mm below the base.
  const double rho = 0.015, L = 0.1, tip_depth = 0.004;
  const double flap = L - std::numbers::pi * rho;
  const double slope = (2 * rho + tip_depth) / flap;
  Soup s;
  append(&s, make_rect(0.2, 0.1, 0.01), [&](const Vec3& p) {
    const double t = p.x() - L;
    if (t <= 0) return Vec3(p.x(), p.y(), 0.0);
    if (t <= std::numbers::pi * rho)
      return Vec3(L + rho * std::sin(t / rho), p.y(), rho * (1 - std::cos(t / rho)));
    const double u = t - std::numbers::pi * rho;
    return Vec3(L - u, p.y() + 0.03 * u, 2 * rho - slope * u);  // slight skew: no edge aligned with the base's
  });
  const int n0 = static_cast<int>(intersecting_pairs(s.x, s.tris, all_triangle_pairs(s.tris, s.nv())).size());
  EXPECT_GT(n0, 0);
  EXPECT_EQ(n0, ref_count(s));
  const Soup before = s;
  std::vector<int> fixed(s.nv(), 0);
  for (int i = 0; i < s.nv(); ++i)
    if (s.v(i).x() < 1e-9 && std::abs(s.v(i).z()) < 1e-12) fixed[i] = 1;  // the base's far edge
  const UntangleResult r = run_untangle(&s, fixed, kGap);
  EXPECT_GT(r.iterations, 0);
  EXPECT_LT(max_displacement(before, s), 3 * (tip_depth + kGap));
  for (int i = 0; i < s.nv(); ++i)
    if (fixed[i]) EXPECT_EQ(s.v(i), before.v(i));
}

TEST(ContactUntangle, CleanInputIsUnchanged) {
  Soup s;
  const Mesh m = make_rect(0.1, 0.1, 0.01);
  append(&s, m, [](const Vec3& p) { return p; });
  append(&s, m, [](const Vec3& p) { return Vec3(p.x() + 0.002, p.y(), 0.005); });
  const Soup before = s;
  int calls = 0;
  const auto all = all_triangle_pairs(s.tris, s.nv());
  const UntangleResult r = untangle(
      &s.x, s.tris, {},
      [&](const std::vector<double>&) {
        ++calls;
        return all;
      },
      kGap);
  EXPECT_EQ(r.intersecting_before, 0);
  EXPECT_EQ(r.intersecting_after, 0);
  EXPECT_EQ(r.iterations, 0);
  EXPECT_EQ(calls, 1);
  EXPECT_EQ(s.x, before.x);
}

// Random variations of six configurations: a bump through a sheet, a tilted (and turned) sheet
// through another, a skewed fold, two wavy interpenetrating sheets, a bump whose tip is gripped
// (kinematic), and a deep bump (1-4 cm over 1 cm edges).
Soup random_case(int kind, std::mt19937* rng, double* depth, std::vector<int>* fixed) {
  std::uniform_real_distribution<double> U(0, 1);
  auto u = [&] { return U(*rng); };
  Soup s;
  fixed->clear();
  const Mesh a = make_rect(0.16, 0.16, 0.01);
  if (kind == 2) {
    const double rho = 0.008 + 0.01 * u(), L = 0.1, skew = 0.1 * (u() - 0.5);
    *depth = 0.001 + 0.006 * u();
    const double flap = L - std::numbers::pi * rho, slope = (2 * rho + *depth) / flap;
    append(&s, make_rect(0.2, 0.1, 0.01), [&](const Vec3& p) {
      const double t = p.x() - L;
      if (t <= 0) return Vec3(p.x(), p.y(), 0.0);
      if (t <= std::numbers::pi * rho) return Vec3(L + rho * std::sin(t / rho), p.y(), rho * (1 - std::cos(t / rho)));
      const double w = t - std::numbers::pi * rho;
      return Vec3(L - w, p.y() + skew * w, 2 * rho - slope * w);
    });
    return s;
  }
  append(&s, a, [](const Vec3& p) { return Vec3(p.x(), p.y(), 0.0); });
  const int b0 = s.nv();
  if (kind == 1) {
    const double theta = 0.2 + 1.0 * u(), ox = 0.03 + 0.02 * u(), oy = 0.03 + 0.02 * u(), rot = 0.3 * (u() - 0.5);
    *depth = 0.002 + 0.015 * u();
    append(&s, make_rect(0.08, 0.08, 0.01), [&](const Vec3& p) {
      const Vec3 q(ox + p.x() * std::cos(theta), oy + p.y(), -*depth + p.x() * std::sin(theta));
      const double c = std::cos(rot), sn = std::sin(rot);
      return Vec3(0.08 + c * (q.x() - 0.08) - sn * (q.y() - 0.08), 0.08 + sn * (q.x() - 0.08) + c * (q.y() - 0.08), q.z());
    });
  } else if (kind == 3) {
    const double ph0 = 6.28 * u(), ph1 = 6.28 * u(), k1 = 40 + 60 * u(), k2 = 40 + 60 * u();
    *depth = 0.001 + 0.003 * u();
    append(&s, a, [&](const Vec3& p) {
      const double x = p.x() + 0.0031, y = p.y() + 0.0043;
      return Vec3(x, y, 0.0005 + *depth * std::sin(k1 * x + ph0) * std::sin(k2 * y + ph1));
    });
  } else {  // 0, 4, 5: bumps
    const double ox = 0.01 * u(), oy = 0.01 * u(), cx = 0.06 + 0.04 * u(), cy = 0.06 + 0.04 * u();
    const double sigma = kind == 5 ? 0.02 + 0.02 * u() : 0.01 + 0.02 * u(), h = 0.002 + 0.006 * u();
    *depth = kind == 5 ? 0.01 + 0.03 * u() : 0.001 + 0.008 * u();
    append(&s, a, [&](const Vec3& p) {
      const double x = p.x() + ox, y = p.y() + oy, r2 = (x - cx) * (x - cx) + (y - cy) * (y - cy);
      return Vec3(x, y, h - (h + *depth) * std::exp(-r2 / (2 * sigma * sigma)));
    });
    if (kind == 4) {  // the bump's tip is held by a grip
      fixed->assign(s.nv(), 0);
      for (int i = b0; i < s.nv(); ++i)
        if (s.v(i).z() < -0.5 * *depth) (*fixed)[i] = 1;
    }
  }
  return s;
}

TEST(ContactUntangle, RandomisedCasesResolve) {
  std::mt19937 rng(7);
  int resolved = 0;
  for (int trial = 0; trial < 12; ++trial) {
    double depth;
    std::vector<int> fixed;
    Soup s = random_case(trial % 6, &rng, &depth, &fixed);
    const Soup before = s;
    const UntangleResult r = run_untangle(&s, fixed, kGap);
    EXPECT_GT(r.intersecting_before, 0) << trial;
    EXPECT_LT(max_displacement(before, s), 4 * (depth + kGap)) << trial;
    for (int i = 0; i < static_cast<int>(fixed.size()); ++i)
      if (fixed[i]) EXPECT_EQ(s.v(i), before.v(i));
    resolved += r.intersecting_after == 0;
  }
  EXPECT_EQ(resolved, 12);
}

TEST(ContactUntangle, NeverReturnsMoreIntersectionsThanItWasGiven) {
  // Cut short after 1-3 passes, half-peeled regions can cross more pairs than the input did; the
  // result must then be the best state reached (at worst the input), and report what it holds.
  std::mt19937 rng(11);
  int restored = 0;
  for (int trial = 0; trial < 24; ++trial) {
    double depth;
    std::vector<int> fixed;
    Soup s = random_case(trial % 6, &rng, &depth, &fixed);
    const Soup before = s;
    const auto all = all_triangle_pairs(s.tris, s.nv());
    auto cand = [&](const std::vector<double>&) { return all; };
    const UntangleResult r = untangle(&s.x, s.tris, fixed, cand, kGap, 1 + trial % 3);
    EXPECT_LE(r.intersecting_after, r.intersecting_before) << trial;
    EXPECT_EQ(r.intersecting_after, static_cast<int>(intersecting_pairs(s.x, s.tris, all).size())) << trial;
    restored += s.x == before.x;
  }
  RecordProperty("restored_inputs", restored);
}

}  // namespace
}  // namespace gd::sim
