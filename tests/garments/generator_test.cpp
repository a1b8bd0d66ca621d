#include "garments/generator.h"
#include "garments/mesher.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <set>

#include "garments/test_util.h"
#include "sim/demand.h"

namespace gd::garments {
namespace {

using testing::boundary_loops;
using testing::edge_counts;

struct Expect {
  std::string type;
  int loops;
  std::vector<std::string> seams;
  bool creases, elastic;
};

const std::vector<Expect>& expectations() {
  static const std::vector<Expect> e = {
      {"towel", 1, {}, false, false},
      {"tshirt", 4, {"left_shoulder", "right_shoulder", "left_side", "right_side", "left_sleeve_under",
                     "right_sleeve_under", "left_sleeve_top", "left_armhole_front", "right_armhole_back"}, false, false},
      {"long_sleeve", 4, {"left_shoulder", "right_side", "left_sleeve_under", "right_sleeve_top"}, false, true},
      {"dress", 4, {"left_shoulder", "right_shoulder", "left_side", "right_side"}, false, false},
      {"skirt", 2, {"left_side", "right_side"}, false, true},
      {"pleat_skirt", 2, {"left_side", "right_side"}, true, true},
      {"cake_skirt", 2, {"left_side_tier0", "right_side_tier2", "tier1_front", "tier2_back"}, false, true},
      {"hoodie", 4, {"left_shoulder", "left_side", "left_sleeve_under", "hood_left_side", "hood_right_side",
                     "hood_front_neck", "hood_back_neck"}, false, true},
      {"coat", 3, {"left_shoulder", "right_shoulder", "left_side", "right_side", "left_sleeve_under",
                   "right_sleeve_under"}, false, false},
  };
  return e;
}

TEST(Generator, TypesAreListed) {
  std::vector<std::string> names;
  for (const Expect& e : expectations()) names.push_back(e.type);
  EXPECT_EQ(garment_types(), names);
}

class EveryType : public ::testing::TestWithParam<Expect> {};

TEST_P(EveryType, GeneratesAValidSewnGarment) {
  const Expect& ex = GetParam();
  const Garment g = make_garment(ex.type, 1000);
  const sim::Mesh& m = g.mesh;
  EXPECT_EQ(g.type, ex.type);
  ASSERT_NO_THROW(sim::validate_mesh(m));
  ASSERT_NO_THROW(sim::build_topology(m));
  EXPECT_NEAR(double(m.x.size()), 1000.0, 200.0);

  // Manifold with consistent orientation, every vertex used.
  for (const auto& [e, n] : edge_counts(m)) ASSERT_TRUE(n == 1 || n == 2) << e.first << "-" << e.second;
  EXPECT_EQ(testing::orientation_conflicts(m), 0);
  std::vector<int> used(m.x.size(), 0);
  for (const auto& f : m.tris)
    for (int k = 0; k < 3; ++k) used[f[k]] = 1;
  EXPECT_EQ(std::count(used.begin(), used.end(), 0), 0);

  // Openings are separate boundary loops.
  bool simple = false;
  EXPECT_EQ(boundary_loops(m, &simple), ex.loops);
  EXPECT_TRUE(simple) << "a boundary vertex is pinched";

  // The claimed seams exist and join two panels at every vertex.
  std::set<std::string> names;
  for (const SeamInfo& s : g.seams) names.insert(s.name);
  for (const std::string& s : ex.seams) EXPECT_TRUE(names.count(s)) << "missing seam " << s;
  ASSERT_EQ(g.triangle_panel.size(), m.tris.size());
  std::vector<std::set<int>> panels_at(m.x.size());
  for (size_t t = 0; t < m.tris.size(); ++t)
    for (int k = 0; k < 3; ++k) panels_at[m.tris[t][k]].insert(g.triangle_panel[t]);
  auto ec = edge_counts(m);
  for (const SeamInfo& s : g.seams) {
    EXPECT_GE(s.vertices.size(), 2u) << s.name;
    for (int v : s.vertices) EXPECT_GE(panels_at[v].size(), 2u) << s.name << " vertex " << v;
    for (size_t k = 0; k + 1 < s.vertices.size(); ++k)  // consecutive seam vertices form an interior edge
      EXPECT_EQ((ec[std::make_pair(std::min(s.vertices[k], s.vertices[k + 1]), std::max(s.vertices[k], s.vertices[k + 1]))]), 2)
          << s.name;
  }

  // No coincident vertices; flat, in the garment frame.
  EXPECT_GT(testing::min_vertex_distance(m), 1e-3);
  Vec3 lo = m.x[0], hi = lo;
  for (const Vec3& p : m.x) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
  EXPECT_NEAR(lo.x(), 0, 1e-12);
  EXPECT_NEAR(lo.z(), 0, 1e-12);
  EXPECT_LE(hi.z(), 0.0051);
  EXPECT_NEAR(lo.y() + hi.y(), 0, 1e-9);  // centred on y = 0
  EXPECT_NEAR(g.length, hi.x() - lo.x(), 1e-12);
  EXPECT_NEAR(g.width, hi.y() - lo.y(), 1e-12);

  // The pattern is the flat shape: uv areas match 3D areas.
  ASSERT_EQ(m.uv_tris.size(), m.tris.size());
  double a2 = 0, a3 = 0;
  int tilted = 0;
  for (size_t t = 0; t < m.tris.size(); ++t) {
    const Vec2 u = sim::corner_uv(m, int(t), 1) - sim::corner_uv(m, int(t), 0);
    const Vec2 v = sim::corner_uv(m, int(t), 2) - sim::corner_uv(m, int(t), 0);
    const double uv_area = 0.5 * (u.x() * v.y() - u.y() * v.x());
    const Eigen::Vector3i& f = m.tris[t];
    const double area = 0.5 * (m.x[f[1]] - m.x[f[0]]).cross(m.x[f[2]] - m.x[f[0]]).norm();
    EXPECT_GT(uv_area, 0) << "uv triangle " << t << " is clockwise";
    // Triangles touching a seam tilt from the seam (between the layers) up or down to their
    // layer, so their 3D area is a little larger than the pattern's.
    EXPECT_LE(uv_area / area, 1.0 + 1e-9) << "triangle " << t;
    EXPECT_GT(uv_area / area, 0.75) << "triangle " << t;
    if (uv_area / area < 0.95) ++tilted;
    a2 += uv_area, a3 += area;
  }
  EXPECT_LT(tilted, 0.02 * m.tris.size());
  EXPECT_NEAR(a2 / a3, 1.0, 0.01);

  // Feature edges.
  EXPECT_EQ(!m.creases.empty(), ex.creases);
  EXPECT_EQ(!m.elastic_edges.empty(), ex.elastic);

  // Landmarks on the mesh, grasp points near the small-x end on the top layer, hems far.
  const Landmarks& lm = g.landmarks;
  ASSERT_GE(lm.left_shoulder_vertex, 0);
  ASSERT_GE(lm.right_shoulder_vertex, 0);
  EXPECT_EQ(lm.left_shoulder, m.x[lm.left_shoulder_vertex]);
  EXPECT_EQ(lm.right_shoulder, m.x[lm.right_shoulder_vertex]);
  EXPECT_GT(lm.left_shoulder.y(), 0.05);
  EXPECT_LT(lm.right_shoulder.y(), -0.05);
  EXPECT_LT(lm.left_shoulder.x(), 0.45 * g.length);
  EXPECT_NEAR(lm.left_shoulder.z(), hi.z(), 1e-12);
  EXPECT_GT(lm.left_hem.x(), 0.9 * g.length);
  EXPECT_GT(lm.left_hem.y(), 0.1);
  EXPECT_LT(lm.right_hem.y(), -0.1);
}

INSTANTIATE_TEST_SUITE_P(Garments, EveryType, ::testing::ValuesIn(expectations()),
                         [](const auto& info) { return info.param.type; });

TEST(Generator, TshirtMatchesRgbenchSize) {
  const Garment g = make_garment("tshirt", 1000);
  EXPECT_NEAR(g.length, 0.77, 0.03);
  EXPECT_NEAR(g.width, 0.98, 0.03);
}

TEST(Generator, VertexCountFollowsTheTarget) {
  for (int target : {500, 5000}) {
    const Garment g = make_garment("tshirt", target);
    EXPECT_NEAR(double(g.mesh.x.size()) / target, 1.0, 0.2) << target;
  }
  const Garment towel = make_garment("towel", 2000);
  EXPECT_NEAR(double(towel.mesh.x.size()) / 2000, 1.0, 0.2);
}

TEST(Generator, PleatFoldsAreCreasesAndWarpFollowsTheGrain) {
  GarmentParams p;
  p.pleats = 6;
  p.fold_bend_scale = 0.2;
  const Garment g = make_garment("pleat_skirt", 1500, p);
  ASSERT_FALSE(g.mesh.creases.empty());
  for (const sim::Crease& c : g.mesh.creases) {
    EXPECT_DOUBLE_EQ(c.bend_scale, 0.2);
    // A fold runs from waist to hem: its edges point mostly along x.
    const Vec3 d = (g.mesh.x[c.a] - g.mesh.x[c.b]).normalized();
    EXPECT_GT(std::abs(d.x()), 0.9);
  }
  // The body grain runs along x: uv axis 0 differences follow x differences on the front panel.
  const sim::Mesh& m = g.mesh;
  for (size_t t = 0; t < 20; ++t) {
    const Vec2 du = sim::corner_uv(m, int(t), 1) - sim::corner_uv(m, int(t), 0);
    const Vec3 dx = m.x[m.tris[t][1]] - m.x[m.tris[t][0]];
    EXPECT_NEAR(du.x(), dx.x(), 1e-9);
  }
}

TEST(Generator, HoodieHasHoodLandmarksAndAHemBandAtItsRelaxedWidth) {
  GarmentParams p;
  p.hood_length = 0.30;
  const Garment g = make_garment("hoodie", 1500, p);
  const Landmarks& lm = g.landmarks;
  ASSERT_TRUE(lm.has_hood);
  // The face corners are the small-x end; the hood meets the neck 0.30 m further along +x.
  EXPECT_LT(lm.left_hood.x(), 0.02);
  EXPECT_NEAR(lm.left_hood.y(), 0.12, 0.02);
  EXPECT_NEAR(lm.right_hood.y(), -0.12, 0.02);
  EXPECT_NEAR(lm.hood_fold_x, 0.30, 1e-9);
  EXPECT_GT(lm.left_shoulder.x(), lm.hood_fold_x);
  // The hem band lies at 0.8 of the 0.60 m chest; the side runs full width to 0.15 m above the
  // hem, then tapers into the 6 cm band.
  EXPECT_NEAR(lm.left_hem.y(), 0.24, 1e-6);
  EXPECT_NEAR(lm.right_hem.y(), -0.24, 1e-6);
  const Pattern pat = make_pattern("hoodie", p);
  bool found = false;
  for (const auto& c : pat.curves)
    if (c.name == "left_side") {
      found = true;
      ASSERT_EQ(c.points.size(), 4u);  // armpit, taper start, band top, hem corner
      EXPECT_NEAR(c.points[1].y(), 0.30, 1e-12);
      EXPECT_NEAR(c.points[2].y(), 0.24, 1e-12);
      EXPECT_NEAR(c.points[3].x() - c.points[2].x(), 0.06, 1e-12);
      EXPECT_NEAR(c.points[2].x() - c.points[1].x(), 0.09, 1e-12);
    }
  EXPECT_TRUE(found);
  const double hem_x = g.length;
  // Its elastic edges are the cuffs only: none lies near the hem.
  ASSERT_FALSE(g.mesh.elastic_edges.empty());
  for (const auto& e : g.mesh.elastic_edges) EXPECT_LT(g.mesh.x[e.a].x(), hem_x - 0.1);
  // Other tops have no hood.
  EXPECT_FALSE(make_garment("tshirt", 500).landmarks.has_hood);
}

TEST(Generator, CoatFrontPanelsHaveAGap) {
  GarmentParams p;
  p.front_gap = 0.04;
  const Garment g = make_garment("coat", 1500, p);
  // No front-layer vertex lies in the gap (|y| < 0.02 - eps) below the neckline.
  const double z_top = g.landmarks.left_shoulder.z();
  int in_gap = 0;
  for (const Vec3& x : g.mesh.x)
    if (std::abs(x.z() - z_top) < 1e-9 && std::abs(x.y()) < 0.02 - 1e-9 && x.x() > 0.1) ++in_gap;
  EXPECT_EQ(in_gap, 0);
}

TEST(Generator, BadInputIsRejectedWithAClearMessage) {
  try {
    make_garment("poncho", 1000);
    FAIL() << "no error";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("poncho"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("cake_skirt"), std::string::npos);
  }
  EXPECT_THROW(make_garment("tshirt", 100), sim::InputError);
  EXPECT_THROW(make_garment("tshirt", 300000), sim::InputError);
  GarmentParams bad;
  bad.length = -1;
  EXPECT_THROW(make_garment("skirt", 1000, bad), sim::InputError);
  GarmentParams narrow;
  narrow.neck_width = 0.7;
  EXPECT_THROW(make_garment("tshirt", 1000, narrow), sim::InputError);
}

// A towel 1e9 m long at 200 vertices kept CGAL refining for minutes at ~300 MB (a service
// request that never answered): sizes are bounded, and the message names the parameter and the
// bound; within the bound, a panel too narrow for its length stops at the mesher's point budget
// instead of running on.
TEST(GarmentGenerator, AbsurdSizesAreRefusedBeforeMeshing) {
  GarmentParams huge;
  huge.length = 1e9;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    make_garment("towel", 200, huge);
    FAIL() << "no error";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("length"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("5 m"), std::string::npos) << e.what();
  }
  GarmentParams hood;
  hood.hood_width = 6;
  EXPECT_THROW(make_garment("hoodie", 1000, hood), sim::InputError);
  GarmentParams largest;  // the bound itself is allowed
  largest.length = kMaxGarmentSize;
  largest.width = 0.5;
  EXPECT_GT(make_garment("towel", 400, largest).length, 4.9);

  // Straight to the mesher: a 1 km by 1 mm strip meshed at 10 m edges needs ~1e6 points to
  // keep its angles; it stops at the budget (20,000 here) with a message saying what to change.
  const std::vector<Vec2> strip = {{0, 0}, {1000, 0}, {1000, 0.001}, {0, 0.001}};
  EXPECT_LT(mesher_point_budget(strip, 10), 30000);
  try {
    mesh_panel(strip, {}, 10);
    FAIL() << "no error";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("too far apart in scale"), std::string::npos) << e.what();
  }
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 20.0);
  // A sane panel is far inside its budget.
  const std::vector<Vec2> square = {{0, 0}, {0.5, 0}, {0.5, 0.5}, {0, 0.5}};
  EXPECT_LT(10 * static_cast<long>(mesh_panel(square, {}, 0.02).points.size()), mesher_point_budget(square, 0.02));
}

TEST(MeshingCancellation, TheInnermostScopeStopsTheMesherAndLeavingItLetsMeshingGoOn) {
  const std::vector<Vec2> square = {{0, 0}, {0.5, 0}, {0.5, 0.5}, {0, 0.5}};
  const size_t points = mesh_panel(square, {}, 0.01).points.size();  // ~3000 points: several checks
  ASSERT_GT(points, size_t(4 * kMesherCancelCheckPoints));
  int asked = 0;
  {
    const MeshingCancellation never([&] { return ++asked, false; });
    EXPECT_EQ(mesh_panel(square, {}, 0.01).points.size(), points);  // asked, not stopped: same mesh
    EXPECT_GT(asked, 2);
    const MeshingCancellation now([] { return true; });  // nested: the innermost is asked
    EXPECT_THROW(mesh_panel(square, {}, 0.01), MeshingCancelled);
    EXPECT_THROW(make_garment("tshirt", 3000), MeshingCancelled);  // through the generators too
  }
  int later = 0;  // after its first answers, the flag turns: the mesher stops at the next check
  {
    const MeshingCancellation after_two([&] { return ++later > 2; });
    EXPECT_THROW(mesh_panel(square, {}, 0.01), MeshingCancelled);
    EXPECT_EQ(later, 3);
  }
  EXPECT_EQ(mesh_panel(square, {}, 0.01).points.size(), points);  // no scope left: meshes in full
}

TEST(GarmentParamsByName, EveryNameSetsItsSizeAndTheGarmentFollows) {
  GarmentParams p;
  set_garment_param(p, "length", 0.9);
  set_garment_param(p, "hood_length", 0.2);
  set_garment_param(p, "tiers", 2);
  EXPECT_DOUBLE_EQ(p.length, 0.9);
  EXPECT_DOUBLE_EQ(p.hood_length, 0.2);
  EXPECT_EQ(p.tiers, 2);
  // Every listed name is settable, and each sets a different field.
  for (const std::string& name : garment_param_names()) {
    GarmentParams q;
    ASSERT_NO_THROW(set_garment_param(q, name, 3)) << name;
  }
  EXPECT_EQ(garment_param_names().size(), 20u);
  // A longer T-shirt is generated longer; the default is RGBench's 0.77 m.
  GarmentParams longer;
  set_garment_param(longer, "length", 0.9);
  EXPECT_NEAR(make_garment("tshirt", 600, longer).length, 0.9 + 0.01, 0.02);
  EXPECT_NEAR(make_garment("tshirt", 600).length, 0.77, 0.03);
}

TEST(GarmentParamsByName, BadNamesAndValuesSayWhatToFix) {
  GarmentParams p;
  try {
    set_garment_param(p, "sleeve_lenght", 0.5);
    FAIL() << "no error";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("sleeve_lenght"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("sleeve_length"), std::string::npos);  // the known names
  }
  EXPECT_THROW(set_garment_param(p, "length", std::nan("")), sim::InputError);
  EXPECT_THROW(set_garment_param(p, "width", INFINITY), sim::InputError);
  EXPECT_THROW(set_garment_param(p, "pleats", 2.5), sim::InputError);
  EXPECT_EQ(p.pleats, 0);  // untouched by the refused values
  EXPECT_DOUBLE_EQ(p.length, 0);
}

}  // namespace
}  // namespace gd::garments

namespace gd::garments {
namespace {

// Sizes and timings for the docs: gd_garments_tests --gtest_also_run_disabled_tests
// --gtest_filter='*PrintStats*' (GD_GARMENT_OBJ_DIR=dir also writes the meshes as OBJ).
TEST(Generator, DISABLED_PrintStats) {
  for (int target : {1000, 5000, 40000, 200000}) {
    for (const std::string& type : garment_types()) {
      const auto t0 = std::chrono::steady_clock::now();
      const Garment g = make_garment(type, target);
      const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
      double min_angle = 180;
      for (const auto& f : g.mesh.tris)
        for (int k = 0; k < 3; ++k) {
          const Vec2 a = g.mesh.x[f[(k + 1) % 3]].head<2>() - g.mesh.x[f[k]].head<2>();
          const Vec2 b = g.mesh.x[f[(k + 2) % 3]].head<2>() - g.mesh.x[f[k]].head<2>();
          min_angle = std::min(min_angle, std::acos(std::clamp(a.normalized().dot(b.normalized()), -1.0, 1.0)) * 180 / M_PI);
        }
      std::printf("%-12s target %6d: %6zu vertices %6zu triangles %2zu seams %2d loops %4zu creases %4zu elastic  %.3f x %.3f m  spacing %.4f  min angle %.1f  min dist %.4f  %7.1f ms\n",
                  type.c_str(), target, g.mesh.x.size(), g.mesh.tris.size(), g.seams.size(), testing::boundary_loops(g.mesh),
                  g.mesh.creases.size(), g.mesh.elastic_edges.size(), g.length, g.width, g.spacing, min_angle,
                  testing::min_vertex_distance(g.mesh), ms);
      if (const char* dir = std::getenv("GD_GARMENT_OBJ_DIR"); dir && target == 1000)
        sim::write_obj(g.mesh, {}, std::string(dir) + "/" + type + ".obj");
    }
  }
}

}  // namespace
}  // namespace gd::garments
