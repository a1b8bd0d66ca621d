#include "garments/obj_import.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "garments/test_util.h"
#include "sim/demand.h"

namespace gd::garments {
namespace {

namespace fs = std::filesystem;

class ObjImport : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("gd_garments_obj_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  std::string write(const std::string& name, const std::string& text) {
    const fs::path p = dir_ / name;
    std::ofstream(p) << text;
    return p.string();
  }
  /// Expects load_garment_obj(path) to throw an InputError whose message contains `what` and
  /// names the file.
  void expect_error(const std::string& path, const std::string& what) {
    try {
      load_garment_obj(path);
      ADD_FAILURE() << "no error for " << path;
    } catch (const sim::InputError& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(what), std::string::npos) << msg;
      EXPECT_NE(msg.find(fs::path(path).filename().string()), std::string::npos) << msg;
    }
  }
  fs::path dir_;
};

/// A 0.3 m square of 3x3 quads (16 vertices), optionally with vt = scale * (x, y) (+ distortion).
std::string grid_obj(bool with_vt, double vt_scale = 1, bool distort = false, double pos_scale = 1) {
  std::string s = "# grid\n";
  for (int j = 0; j < 4; ++j)
    for (int i = 0; i < 4; ++i) s += "v " + std::to_string(0.1 * i * pos_scale) + " " + std::to_string(0.1 * j * pos_scale) + " 0\n";
  if (with_vt)
    for (int j = 0; j < 4; ++j)
      for (int i = 0; i < 4; ++i) {
        double u = 0.1 * i * vt_scale, v = 0.1 * j * vt_scale;
        if (distort) u = u * u * 7 + 0.05 * ((i * 7 + j * 3) % 5), v = v + 0.2 * u;
        s += "vt " + std::to_string(u) + " " + std::to_string(v) + "\n";
      }
  for (int j = 0; j < 3; ++j)
    for (int i = 0; i < 3; ++i) {
      const int a = j * 4 + i + 1, b = a + 1, c = a + 5, d = a + 4;
      if (with_vt)
        s += "f " + std::to_string(a) + "/" + std::to_string(a) + " " + std::to_string(b) + "/" + std::to_string(b) + " " +
             std::to_string(c) + "/" + std::to_string(c) + " " + std::to_string(d) + "/" + std::to_string(d) + "\n";
      else
        s += "f " + std::to_string(a) + " " + std::to_string(b) + " " + std::to_string(c) + " " + std::to_string(d) + "\n";
    }
  return s;
}

TEST_F(ObjImport, GoodMeshWithMetreUvsKeepsThem) {
  UvReport rep;
  const Garment g = load_garment_obj(write("good.obj", grid_obj(true)), {}, &rep);
  EXPECT_EQ(g.type, "mesh");
  EXPECT_EQ(g.mesh.x.size(), 16u);
  EXPECT_EQ(g.mesh.tris.size(), 18u);  // quads fan-triangulated
  EXPECT_TRUE(rep.present);
  EXPECT_EQ(rep.used, UvMode::kKeep);
  EXPECT_NEAR(rep.scale, 1, 1e-6);
  EXPECT_EQ(g.mesh.uv.size(), 16u);
  EXPECT_TRUE(g.mesh.uv_tris.empty());  // one uv per vertex: no vertex has two
  EXPECT_NEAR(g.length, 0.3, 1e-6);
  EXPECT_NEAR(g.width, 0.3, 1e-6);
  EXPECT_EQ(testing::orientation_conflicts(g.mesh), 0);
  // Vertex order is the file's.
  EXPECT_NEAR(g.mesh.x[5].x(), 0.1, 1e-6);
  EXPECT_NEAR(g.mesh.x[5].y(), 0.1, 1e-6);
}

TEST_F(ObjImport, WithoutUvsTheRestShapeIs3D) {
  UvReport rep;
  const Garment g = load_garment_obj(write("nouv.obj", grid_obj(false)), {}, &rep);
  EXPECT_FALSE(rep.present);
  EXPECT_TRUE(g.mesh.uv.empty());
  EXPECT_TRUE(g.mesh.uv_tris.empty());
  EXPECT_EQ(g.mesh.tris.size(), 18u);
}

TEST_F(ObjImport, ScaledUvsAreRescaledAndDistortedOnesDropped) {
  UvReport rep;
  Garment g = load_garment_obj(write("scaled.obj", grid_obj(true, 2.5)), {}, &rep);
  EXPECT_EQ(rep.used, UvMode::kRescale);
  EXPECT_NEAR(rep.scale, 0.4, 1e-5);
  EXPECT_NEAR((g.mesh.uv[5] - Vec2(0.1, 0.1)).norm(), 0, 1e-6);

  g = load_garment_obj(write("atlas.obj", grid_obj(true, 1, true)), {}, &rep);
  EXPECT_EQ(rep.used, UvMode::kDrop);
  EXPECT_TRUE(g.mesh.uv.empty());

  // The caller can force a mode.
  ObjImportOptions keep;
  keep.uv_mode = UvMode::kKeep;
  g = load_garment_obj(write("scaled2.obj", grid_obj(true, 2.5)), keep, &rep);
  EXPECT_EQ(rep.used, UvMode::kKeep);
  EXPECT_NEAR(g.mesh.uv[5].x(), 0.25, 1e-6);
  ObjImportOptions drop;
  drop.uv_mode = UvMode::kDrop;
  g = load_garment_obj(write("scaled3.obj", grid_obj(true, 2.5)), drop, &rep);
  EXPECT_TRUE(g.mesh.uv.empty());
}

TEST_F(ObjImport, BrokenMeshesGetSpecificErrors) {
  expect_error((dir_ / "absent.obj").string(), "does not exist");
  expect_error(write("nofaces.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\n"), "no faces");
  expect_error(write("garbage.obj", "this is not\nan OBJ file at all }{ 12 x\n"), "no faces");
  expect_error(write("nonmanifold.obj",
                     "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0 -0.1 0\nv 0 0 0.1\nf 1 2 3\nf 2 1 4\nf 1 2 5\n"),
               "non-manifold");
  expect_error(write("degenerate.obj", "v 0 0 0\nv 0.1 0 0\nv 0.2 0 0\nv 0 0.1 0\nf 1 2 3\nf 1 2 4\n"),
               "degenerate");
  expect_error(write("duplicate.obj", "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 3\nf 1 2 3\n"), "same vertices");
  expect_error(write("millimetres.obj", grid_obj(false, 1, false, 1000)), "millimetres");
  expect_error(write("unused.obj", "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 1 1 1\nf 1 2 3\n"), "used by no face");
  EXPECT_THROW(load_garment_obj(write("badindex.obj", "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nf 1 2 9\n")), sim::InputError);
}

TEST(ObjImportRgbench, LoadsTheTshirtInFileOrder) {
  // GD_SHARED_DIR, else ../shared next to the repository this file is in.
  const char* shared = std::getenv("GD_SHARED_DIR");
  const fs::path dir = shared ? fs::path(shared) : fs::path(__FILE__).parent_path() / "../../../shared";
  const fs::path path = dir / "data/rgbench/LargeT_Flat_Simple_5k.obj";
  if (!fs::exists(path)) GTEST_SKIP() << path << " not found (set GD_SHARED_DIR)";
  UvReport rep;
  const Garment g = load_garment_obj(path.string(), {}, &rep);
  const sim::Mesh& m = g.mesh;
  EXPECT_EQ(m.x.size(), 4867u);
  EXPECT_EQ(m.tris.size(), 9615u);
  // First and 16th `v` lines of the file, unchanged.
  EXPECT_NEAR((m.x[0] - Vec3(0.766343, 0.00444187, 0.00461542)).norm(), 0, 1e-6);
  EXPECT_NEAR((m.x[15] - Vec3(0.759321, -0.298589, 0.0187367)).norm(), 0, 1e-6);
  // Manifold, consistently oriented, open at neck, hem and two cuffs.
  for (const auto& [e, n] : testing::edge_counts(m)) ASSERT_LE(n, 2);
  EXPECT_EQ(testing::orientation_conflicts(m), 0);
  EXPECT_EQ(testing::boundary_loops(m), 4);
  // Its uvs are the pattern at a uniform scale (about 1.85 uv units per metre): rescaled.
  EXPECT_TRUE(rep.present);
  EXPECT_EQ(rep.used, UvMode::kRescale);
  EXPECT_NEAR(rep.scale, 0.54, 0.03);
  EXPECT_LT(rep.distortion, 0.1);
  EXPECT_NEAR(g.length, 0.77, 0.01);
  EXPECT_NEAR(g.width, 0.98, 0.01);
  EXPECT_LT(g.landmarks.left_shoulder.x(), 0.1);
  EXPECT_GT(g.landmarks.left_shoulder.y(), 0.1);
  EXPECT_LT(g.landmarks.right_shoulder.y(), -0.1);
  EXPECT_GT(g.landmarks.left_hem.x(), 0.7);
}

}  // namespace
}  // namespace gd::garments
