// Points sampled over the cloth's triangles (sim/contact/surface_samples.h): no point of a triangle
// farther from a sample or a corner than the spacing, each edge's samples once, barycentric
// weights on the triangle, the mass they stand for that of the cloth round them, bad input refused.
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
  const SurfaceSamples s = sample_surface(x, tris, 0.2, spacing);
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

TEST(SurfaceSamples, EachEdgesSamplesOnceWeightsOnTheTriangleMassOfTheClothRoundThem) {
  const Mesh m = make_rect(0.1, 0.08, 0.02);
  const std::vector<double> x = flat(m.x);
  const std::vector<int> tris = flat(m.tris);
  const double density = 0.15, spacing = 0.005;
  const SurfaceSamples s = sample_surface(x, tris, density, spacing);
  EXPECT_EQ(s.spacing, spacing);
  std::set<std::vector<long>> seen;  // each sample's position, rounded to a micrometre: no two alike
  double mass = 0, area = 0;
  for (int k = 0; k < s.size(); ++k) {
    const double* w = s.w.data() + 3 * k;
    EXPECT_NEAR(w[0] + w[1] + w[2], 1.0, 1e-12);
    EXPECT_TRUE(w[0] >= 0 && w[1] >= 0 && w[2] >= 0 && w[0] < 1 && w[1] < 1 && w[2] < 1);
    EXPECT_GE(k, s.tri_ptr[s.tri[k]]);
    EXPECT_LT(k, s.tri_ptr[s.tri[k] + 1]);
    const Vec3 p = sample(s, x, tris, k);
    EXPECT_TRUE(seen.insert({std::lround(p.x() * 1e6), std::lround(p.y() * 1e6), std::lround(p.z() * 1e6)}).second)
        << "sample " << k << " at " << p.transpose() << " twice";
    mass += s.mass[k];
  }
  for (const Eigen::Vector3i& t : m.tris) area += 0.5 * (m.x[t[1]] - m.x[t[0]]).cross(m.x[t[2]] - m.x[t[0]]).norm();
  // Samples and vertices together stand for about the cloth's mass once over: the samples about
  // (k - 1)^2 / k^2 of it for k parts per edge (k = 6 here: 2 cm diagonals over 5 mm).
  EXPECT_GT(mass, 0.5 * density * area);
  EXPECT_LT(mass, 1.2 * density * area);
}

TEST(SurfaceSamples, TrianglesShorterThanTheSpacingGetNone) {
  const Mesh m = make_rect(0.05, 0.05, 0.005);
  const SurfaceSamples s = sample_surface(flat(m.x), flat(m.tris), 0.2, 0.008);  // 7 mm diagonals
  EXPECT_EQ(s.size(), 0);
  EXPECT_EQ(s.tri_ptr.back(), 0);
}

TEST(SurfaceSamples, BadSpacingDensityOrIndexIsRefused) {
  const std::vector<double> x = {0, 0, 0, 1, 0, 0, 0, 1, 0};
  EXPECT_THROW(sample_surface(x, {0, 1, 2}, 0.2, 0.0), InputError);
  EXPECT_THROW(sample_surface(x, {0, 1, 2}, 0.2, NAN), InputError);
  EXPECT_THROW(sample_surface(x, {0, 1, 2}, -1.0, 0.1), InputError);
  EXPECT_THROW(sample_surface(x, {0, 1, 3}, 0.2, 0.1), InputError);
  const SurfaceSamples s = sample_surface(x, {0, 1, 2}, 0.2, 0.1);
  EXPECT_GT(s.size(), 0);
  // A sliver longer than kMaxSampleDivisions spacings is cut into that many parts per edge.
  const SurfaceSamples capped = sample_surface(x, {0, 1, 2}, 0.2, 1e-4);
  const int k = kMaxSampleDivisions;
  EXPECT_EQ(capped.size(), (k - 1) * (k - 2) / 2 + 3 * (k - 1));
}

}  // namespace
}  // namespace gd::sim
