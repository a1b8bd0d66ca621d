// Local refinement (garments/refine.h): longest-edge bisection near given points keeps the
// garment the same surface with the same pattern, conforming and sewn, and refines only there.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <vector>

#include "garments/generator.h"
#include "garments/refine.h"
#include "sim/demand.h"
#include "test_util.h"

namespace gd::garments {
namespace {

double area3(const sim::Mesh& m, int t) {
  const auto& f = m.tris[t];
  return 0.5 * (m.x[f[1]] - m.x[f[0]]).cross(m.x[f[2]] - m.x[f[0]]).norm();
}

double uv_area(const sim::Mesh& m, int t) {
  const Vec2 a = sim::corner_uv(m, t, 0), b = sim::corner_uv(m, t, 1), c = sim::corner_uv(m, t, 2);
  return 0.5 * std::abs((b - a).x() * (c - a).y() - (b - a).y() * (c - a).x());
}

double min_angle(const sim::Mesh& m, int t) {
  const auto& f = m.tris[t];
  double best = M_PI;
  for (int k = 0; k < 3; ++k) {
    const Vec3 u = m.x[f[(k + 1) % 3]] - m.x[f[k]], v = m.x[f[(k + 2) % 3]] - m.x[f[k]];
    best = std::min(best, std::acos(std::clamp(u.dot(v) / (u.norm() * v.norm()), -1.0, 1.0)));
  }
  return best;
}

double longest_edge(const sim::Mesh& m, int t) {
  const auto& f = m.tris[t];
  double l = 0;
  for (int k = 0; k < 3; ++k) l = std::max(l, (m.x[f[k]] - m.x[f[(k + 1) % 3]]).norm());
  return l;
}

double distance_to(const std::vector<Vec3>& centres, const Vec3& p) {
  double d = 1e9;
  for (const Vec3& c : centres) d = std::min(d, (p - c).norm());
  return d;
}

// The T-shirt at 1000 vertices (edges of ~3.5 cm) refined to 6 mm within 5 cm of its grasp
// points: the same surface (3D area and every panel's pattern area), the old vertices where they
// were, a conforming, consistently oriented mesh whose seams, creases and elastic edges are still
// edges, triangles near the points at most 6 mm long and the far ones untouched.
TEST(RefineNear, AddsVerticesOnlyNearThePointsAndKeepsTheSurfaceAndItsSeams) {
  const Garment before = make_garment("tshirt", 1000);
  Garment g = before;
  RefineRegion region;
  region.centres = grasp_landmarks(g.landmarks, /*fold=*/true);
  region.radius = 0.05;
  region.edge = 0.006;
  const int added = refine_near(g, region);
  EXPECT_EQ(added, static_cast<int>(g.mesh.x.size() - before.mesh.x.size()));
  EXPECT_GT(added, 4 * 150) << "four patches of ~pi 5^2 cm^2 in 6 mm triangles, both layers";
  EXPECT_LT(added, 4 * 2000);
  for (size_t i = 0; i < before.mesh.x.size(); ++i) ASSERT_EQ(g.mesh.x[i], before.mesh.x[i]) << i;
  EXPECT_EQ(g.landmarks.left_shoulder_vertex, before.landmarks.left_shoulder_vertex);

  double a0 = 0, a1 = 0;
  std::map<int, double> uv0, uv1;  // pattern area per panel
  double min0 = M_PI, min1 = M_PI;
  for (int t = 0; t < static_cast<int>(before.mesh.tris.size()); ++t) {
    a0 += area3(before.mesh, t);
    uv0[before.triangle_panel[t]] += uv_area(before.mesh, t);
    min0 = std::min(min0, min_angle(before.mesh, t));
  }
  ASSERT_EQ(g.triangle_panel.size(), g.mesh.tris.size());
  ASSERT_EQ(g.mesh.uv_tris.size(), g.mesh.tris.size());
  for (int t = 0; t < static_cast<int>(g.mesh.tris.size()); ++t) {
    a1 += area3(g.mesh, t);
    uv1[g.triangle_panel[t]] += uv_area(g.mesh, t);
    min1 = std::min(min1, min_angle(g.mesh, t));
    const auto& f = g.mesh.tris[t];
    const Vec3 c = (g.mesh.x[f[0]] + g.mesh.x[f[1]] + g.mesh.x[f[2]]) / 3.0;
    if (distance_to(region.centres, c) <= region.radius) EXPECT_LE(longest_edge(g.mesh, t), region.edge + 1e-12) << t;
  }
  EXPECT_NEAR(a1, a0, 1e-12 * a0);
  for (const auto& [panel, area] : uv0) EXPECT_NEAR(uv1[panel], area, 1e-12 * area) << "panel " << panel;
  EXPECT_GE(min1, 0.5 * min0 - 1e-9) << "longest-edge bisection at most halves the smallest angle";

  // Far triangles are the original ones: keeping the mesh conforming bisects a few neighbours
  // beyond the radius (each bisection's neighbour across a longer edge first), not many.
  auto far_count = [&](const sim::Mesh& m, double d) {
    int n = 0;
    for (int t = 0; t < static_cast<int>(m.tris.size()); ++t) {
      bool far = true;
      for (int k = 0; k < 3; ++k) far = far && distance_to(region.centres, m.x[m.tris[t][k]]) >= d;
      n += far;
    }
    return n;
  };
  // Measured: all corners beyond 10 cm, 1658 -> 1670 triangles (6 bisected); beyond 15 cm none.
  EXPECT_LE(far_count(g.mesh, 0.10) - far_count(before.mesh, 0.10), 0.02 * far_count(before.mesh, 0.10));
  EXPECT_GT(far_count(before.mesh, 0.15), 500);
  EXPECT_EQ(far_count(g.mesh, 0.15), far_count(before.mesh, 0.15));

  EXPECT_EQ(testing::orientation_conflicts(g.mesh), 0);
  const auto edges = testing::edge_counts(g.mesh);
  for (const auto& [e, n] : edges) ASSERT_LE(n, 2) << "manifold";
  auto is_edge = [&](int a, int b) { return edges.count({std::min(a, b), std::max(a, b)}) > 0; };
  size_t seam_vertices = 0;
  for (const SeamInfo& s : g.seams) {
    for (size_t i = 0; i + 1 < s.vertices.size(); ++i) EXPECT_TRUE(is_edge(s.vertices[i], s.vertices[i + 1])) << s.name;
    seam_vertices += s.vertices.size();
  }
  size_t seam_before = 0;
  for (const SeamInfo& s : before.seams) seam_before += s.vertices.size();
  EXPECT_GT(seam_vertices, seam_before) << "the shoulder seams run through the refined patches";
  for (const sim::ElasticEdge& e : g.mesh.elastic_edges) EXPECT_TRUE(is_edge(e.a, e.b));
  for (const sim::Crease& c : g.mesh.creases) EXPECT_TRUE(is_edge(c.a, c.b));
  // Refining again to the same edge adds nothing.
  EXPECT_EQ(refine_near(g, region), 0);
}

TEST(RefineNear, RefusesARegionItCannotRefine) {
  Garment g = make_garment("towel", 300);
  RefineRegion region;
  region.centres = {g.landmarks.left_shoulder};
  region.edge = 5e-4;
  EXPECT_THROW(refine_near(g, region), sim::InputError) << "an edge below 1 mm";
  region.edge = 0.01;
  region.radius = -1;
  EXPECT_THROW(refine_near(g, region), sim::InputError) << "a negative radius";
  region.radius = 0.05;
  region.centres.clear();
  EXPECT_EQ(refine_near(g, region), 0) << "no point, nothing refined";
}

TEST(RefineNear, StopsAtItsVertexBudget) {
  const Garment coarse = make_garment("towel", 300);
  const long n = static_cast<long>(coarse.mesh.x.size());
  RefineRegion region;
  region.centres = {coarse.landmarks.left_shoulder};
  region.edge = 0.005;
  Garment g = coarse;
  const int added = refine_near(g, region);  // no budget
  ASSERT_GT(added, 20);
  region.max_vertices = n + added;  // exactly enough
  g = coarse;
  EXPECT_EQ(refine_near(g, region), added);
  region.max_vertices = n + added - 1;  // one short: refused, and the message says how to fix it
  g = coarse;
  try {
    refine_near(g, region);
    FAIL() << "expected TooManyVertices";
  } catch (const TooManyVertices& e) {
    EXPECT_NE(std::string(e.what()).find("larger edge"), std::string::npos) << e.what();
  }
  region.max_vertices = n - 1;  // the garment alone is over it
  g = coarse;
  EXPECT_THROW(refine_near(g, region), TooManyVertices);
}

// How finely the cloth round the grasp points is meshed (robot mode's check of the pads against the
// mesh): the 1000-vertex T-shirt's shoulders at centimetres, refined to 6 mm there at most 6 mm,
// and nothing near a point off the garment.
TEST(EdgeNear, TheMedianEdgeRoundThePointsFollowsTheRefinement) {
  const Garment coarse = make_garment("tshirt", 1000);
  const std::vector<Vec3> shoulders = grasp_landmarks(coarse.landmarks, /*fold=*/false);
  const Real before = edge_near(coarse, shoulders, 0.03);
  EXPECT_GT(before, 0.02);
  EXPECT_LT(before, 0.06);
  Garment fine = coarse;
  RefineRegion region;
  region.centres = shoulders;
  region.radius = 0.05;
  region.edge = 0.006;
  refine_near(fine, region);
  EXPECT_LE(edge_near(fine, shoulders, 0.03), 0.006);
  EXPECT_EQ(edge_near(coarse, {Vec3(10, 10, 10)}, 0.03), 0.0);
}

}  // namespace
}  // namespace gd::garments
