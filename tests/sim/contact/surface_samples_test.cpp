// Points sampled over the cloth's triangles (sim/contact/surface_samples.h): no point of a triangle
// farther from a sample or a corner than the spacing, each edge's samples once, barycentric
// weights on the triangle, a barrier as stiff as its corners', bad input refused.
#include "sim/contact/surface_samples.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <vector>

#include "sim/demand.h"
#include "sim/mesh.h"

namespace gd::sim {
namespace {

std::vector<double> flat(const std::vector<Vec3>& x) {
  std::vector<double> out;
  for (const Vec3& p : x) out.insert(out.end(), {p.x(), p.y(), p.z()});
  return out;
}
std::vector<int> flat(const std::vector<Eigen::Vector3i>& tris) {
  std::vector<int> out;
  for (const Eigen::Vector3i& t : tris) out.insert(out.end(), {t[0], t[1], t[2]});
  return out;
}

/// Masses for the vertices of x (flat): 0.1 g, 0.2 g and 0.3 g in turn.
std::vector<double> masses(const std::vector<double>& x) {
  std::vector<double> m(x.size() / 3);
  for (size_t i = 0; i < m.size(); ++i) m[i] = 1e-4 * (1 + i % 3);
  return m;
}

Vec3 sample(const SurfaceSamples& s, const std::vector<double>& x, const std::vector<int>& tris, int k) {
  Vec3 p = Vec3::Zero();
  for (int a = 0; a < 3; ++a) {
    const int v = tris[3 * s.tri[k] + a];
    p += s.w[3 * k + a] * Vec3(x[3 * v], x[3 * v + 1], x[3 * v + 2]);
  }
  return p;
}

// A sheet meshed at 1.7 cm (the small towel's) sampled 4 mm apart (a Piper pad's half thickness):
// every point of every triangle (a grid of 15 x 15 per triangle) lies within the spacing of a
// sample or a corner, so a pad as thick as twice the spacing cannot stand in a triangle between them.
TEST(SurfaceSamples, NoPointOfATriangleIsFartherThanTheSpacingFromASample) {
  const Mesh m = make_rect(0.12, 0.09, 0.017);
  const std::vector<double> x = flat(m.x);
  const std::vector<int> tris = flat(m.tris);
  const double spacing = 0.004;
  const SurfaceSamples s = sample_surface(x, tris, masses(x), spacing);
  ASSERT_EQ(s.tri_ptr.size(), m.tris.size() + 1);
  EXPECT_GT(s.size(), 5 * static_cast<int>(m.x.size()));
  double worst = 0;
  for (size_t t = 0; t < m.tris.size(); ++t) {
    std::vector<Vec3> near;  // this triangle's and its neighbours' samples, and the corners
    for (const Vec3& p : m.x) near.push_back(p);
    for (int k = 0; k < s.size(); ++k) near.push_back(sample(s, x, tris, k));
    const Vec3 a = m.x[m.tris[t][0]], b = m.x[m.tris[t][1]], c = m.x[m.tris[t][2]];
    for (int i = 0; i <= 14; ++i)
      for (int j = 0; i + j <= 14; ++j) {
        const Vec3 p = a + (b - a) * (i / 14.0) + (c - a) * (j / 14.0);
        double best = INFINITY;
        for (const Vec3& q : near) best = std::min(best, (p - q).norm());
        worst = std::max(worst, best);
      }
    if (t >= 12) break;  // a dozen triangles of each orientation: the mesh is regular
  }
  EXPECT_LT(worst, spacing);
}

TEST(SurfaceSamples, EachEdgesSamplesOnceWeightsOnTheTriangleBarrierAsStiffAsItsCorners) {
  const Mesh m = make_rect(0.1, 0.08, 0.02);
  const std::vector<double> x = flat(m.x);
  const std::vector<int> tris = flat(m.tris);
  const double spacing = 0.005;
  const std::vector<double> m_v = masses(x);
  const SurfaceSamples s = sample_surface(x, tris, m_v, spacing);
  EXPECT_EQ(s.spacing, spacing);
  std::set<std::vector<long>> seen;  // each sample's position, rounded to a micrometre: no two alike
  for (int k = 0; k < s.size(); ++k) {
    const double* w = s.w.data() + 3 * k;
    EXPECT_NEAR(w[0] + w[1] + w[2], 1.0, 1e-12);
    EXPECT_TRUE(w[0] >= 0 && w[1] >= 0 && w[2] >= 0 && w[0] < 1 && w[1] < 1 && w[2] < 1);
    EXPECT_GE(k, s.tri_ptr[s.tri[k]]);
    EXPECT_LT(k, s.tri_ptr[s.tri[k] + 1]);
    const Vec3 p = sample(s, x, tris, k);
    EXPECT_TRUE(seen.insert({std::lround(p.x() * 1e6), std::lround(p.y() * 1e6), std::lround(p.z() * 1e6)}).second)
        << "sample " << k << " at " << p.transpose() << " twice";
    const int* v = tris.data() + 3 * s.tri[k];
    EXPECT_NEAR(s.mass[k], (m_v[v[0]] + m_v[v[1]] + m_v[v[2]]) / 3, 1e-15);  // its barrier as stiff as its corners'
  }
  // 2 cm legs (3 samples each) and 2.8 cm diagonals (6 parts: 10 interior points, 5 on the
  // diagonal): per pair of triangles 2 x 10 + 5 + 2 x 3 on the edges they own, about.
  const int pairs = static_cast<int>(m.tris.size()) / 2;
  EXPECT_GT(s.size(), 25 * pairs);
  EXPECT_LT(s.size(), 36 * pairs);
}

TEST(SurfaceSamples, TrianglesShorterThanTheSpacingGetNone) {
  const Mesh m = make_rect(0.05, 0.05, 0.005);
  const SurfaceSamples s = sample_surface(flat(m.x), flat(m.tris), masses(flat(m.x)), 0.008);  // 7 mm diagonals
  EXPECT_EQ(s.size(), 0);
  EXPECT_EQ(s.tri_ptr.back(), 0);
}

// Only triangles wider than `wider_than` (the pad's thickness) are sampled, and their edges: of two
// sheets, one meshed at 2 cm and one at 5 mm, sampled 4 mm apart for an 8 mm pad, only the coarse
// one gets samples.
TEST(SurfaceSamples, OnlyTrianglesWiderThanThePadIsThickGetThem) {
  Mesh coarse = make_rect(0.06, 0.06, 0.02);
  const Mesh fine = make_rect(0.06, 0.06, 0.005);
  const int nc = static_cast<int>(coarse.x.size()), ntc = static_cast<int>(coarse.tris.size());
  for (const Vec3& p : fine.x) coarse.x.push_back(p + Vec3(0.1, 0, 0));  // apart: two meshes in one
  for (const Eigen::Vector3i& t : fine.tris) coarse.tris.push_back(t + Eigen::Vector3i::Constant(nc));
  const std::vector<double> x = flat(coarse.x), m = masses(x);
  const SurfaceSamples s = sample_surface(x, flat(coarse.tris), m, 0.004, 0.008);
  EXPECT_GT(s.size(), 0);
  for (int k = 0; k < s.size(); ++k) EXPECT_LT(s.tri[k], ntc);
  EXPECT_EQ(s.tri_ptr.back(), s.size());
  EXPECT_THROW(sample_surface(x, flat(coarse.tris), m, 0.004, -1.0), InputError);
  // without the width every triangle of the coarse half has more than the fine half's
  EXPECT_GT(sample_surface(x, flat(coarse.tris), m, 0.004).size(), s.size());
}

TEST(SurfaceSamples, BadSpacingMassOrIndexIsRefused) {
  const std::vector<double> x = {0, 0, 0, 1, 0, 0, 0, 1, 0}, m = {1e-4, 1e-4, 1e-4};
  EXPECT_THROW(sample_surface(x, {0, 1, 2}, m, 0.0), InputError);
  EXPECT_THROW(sample_surface(x, {0, 1, 2}, m, NAN), InputError);
  EXPECT_THROW(sample_surface(x, {0, 1, 2}, {1e-4, -1e-4, 1e-4}, 0.1), InputError);
  EXPECT_THROW(sample_surface(x, {0, 1, 2}, {1e-4, 1e-4}, 0.1), InputError);
  EXPECT_THROW(sample_surface(x, {0, 1, 3}, m, 0.1), InputError);
  const SurfaceSamples s = sample_surface(x, {0, 1, 2}, m, 0.1);
  EXPECT_GT(s.size(), 0);
  // A sliver longer than kMaxSampleDivisions spacings is cut into that many parts per edge.
  const SurfaceSamples capped = sample_surface(x, {0, 1, 2}, m, 1e-4);
  const int k = kMaxSampleDivisions;
  EXPECT_EQ(capped.size(), (k - 1) * (k - 2) / 2 + 3 * (k - 1));
}

}  // namespace
}  // namespace gd::sim
