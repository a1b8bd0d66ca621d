// Link collision shapes from a URDF: convex hulls, mesh URIs resolved on the package path, mesh
// files read from disk (a real STL written here), and the errors a user gets for unusable geometry.
#include "robot/link_shapes.h"

#include <gtest/gtest.h>

#include <unistd.h>

#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>

#include "robot/arm_model.h"
#include "robot/urdf_test_util.h"
#include "sim/demand.h"

namespace gd::robot {
namespace {

namespace fs = std::filesystem;

double hull_volume(const std::vector<Eigen::Vector3d>& v, const std::vector<Eigen::Vector3i>& t) {
  double vol = 0;
  for (const Eigen::Vector3i& f : t) vol += v[f[0]].dot(v[f[1]].cross(v[f[2]])) / 6;
  return vol;
}

/// A fresh directory under the test's temporary directory.
fs::path temp_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("gd_link_shapes_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

TEST(LinkShapes, ConvexHullOfACubesPointsIsTwelveOutwardTriangles) {
  std::vector<Eigen::Vector3d> pts;
  for (int i = 0; i < 8; ++i) pts.emplace_back(i & 1 ? 1 : 0, i & 2 ? 1 : 0, i & 4 ? 1 : 0);
  pts.emplace_back(0.5, 0.5, 0.5);  // inside: not on the hull
  pts.emplace_back(0.2, 0.7, 0.4);
  std::vector<Eigen::Vector3d> v;
  std::vector<Eigen::Vector3i> t;
  convex_hull(pts, "cube", &v, &t);
  EXPECT_EQ(v.size(), 8u);
  EXPECT_EQ(t.size(), 12u);
  EXPECT_NEAR(hull_volume(v, t), 1.0, 1e-12);  // outward faces enclose +1
  for (const Eigen::Vector3i& f : t) {         // each face's normal points away from the centre
    const Eigen::Vector3d n = (v[f[1]] - v[f[0]]).cross(v[f[2]] - v[f[0]]);
    EXPECT_GT(n.dot(v[f[0]] - Eigen::Vector3d(0.5, 0.5, 0.5)), 0);
  }
}

TEST(LinkShapes, PointsSpanningNoVolumeAreRefusedWithAMessage) {
  std::vector<Eigen::Vector3d> v;
  std::vector<Eigen::Vector3i> t;
  std::vector<Eigen::Vector3d> flat;
  for (int i = 0; i < 5; ++i) flat.emplace_back(std::cos(i), std::sin(i), 0.3);
  for (const auto& pts : {flat, std::vector<Eigen::Vector3d>(3, Eigen::Vector3d::Zero())}) {
    try {
      convex_hull(pts, "plate", &v, &t);
      ADD_FAILURE() << "no InputError";
    } catch (const sim::InputError& e) {
      EXPECT_NE(std::string(e.what()).find("plate"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("volume"), std::string::npos) << e.what();
    }
  }
}

TEST(LinkShapes, MeshUrisResolveUnderThePackagePathAndTheUrdfsDirectory) {
  const fs::path d = temp_dir("uri");
  fs::create_directories(d / "share" / "arm_description" / "meshes");
  const fs::path mesh = d / "share" / "arm_description" / "meshes" / "l1.stl";
  testing::write_box_stl(mesh, Eigen::Vector3d(0.01, 0.01, 0.01));
  const std::string uri = "package://arm_description/meshes/l1.stl";
  EXPECT_EQ(resolve_mesh_uri(uri, "", {(d / "elsewhere").string(), (d / "share").string()}), mesh.string());
  EXPECT_EQ(resolve_mesh_uri(uri, "", {(d / "share" / "arm_description").string()}), mesh.string());  // DIR named NAME
  EXPECT_EQ(resolve_mesh_uri(uri, "", {}), "");
  EXPECT_EQ(resolve_mesh_uri("package://arm_description/meshes/none.stl", "", {(d / "share").string()}), "");
  EXPECT_EQ(resolve_mesh_uri("package://no_slash", "", {(d / "share").string()}), "");
  EXPECT_EQ(resolve_mesh_uri("file://" + mesh.string(), "", {}), mesh.string());
  EXPECT_EQ(resolve_mesh_uri("meshes/l1.stl", (d / "share" / "arm_description").string(), {}),
            (d / "share" / "arm_description" / "meshes" / "l1.stl").string());
  EXPECT_EQ(resolve_mesh_uri("meshes/l1.stl", "", {}), "");  // a URDF given as text has no directory
  fs::remove_all(d);
}

/// The test arm (robot/urdf_test_util.h) with every kind of URDF collision geometry on its links.
std::string geometry_urdf(const std::string& finger_mesh) {
  return testing::two_joint_arm_urdf(R"(
  <link name="base_link"/>
  <link name="l1"><collision><origin xyz="0.15 0 0" rpy="0 0 1.5707963267948966"/>
    <geometry><box size="0.1 0.2 0.3"/></geometry></collision></link>
  <link name="l2"><collision><origin xyz="0.1 0 0" rpy="0 1.5707963267948966 0"/>
    <geometry><cylinder radius="0.02" length="0.2"/></geometry></collision></link>
  <link name="hand"><collision><geometry><sphere radius="0.03"/></geometry></collision></link>
  <link name="fa"><collision><geometry><mesh filename="package://testpkg/meshes/pad.stl" scale="2 2 2"/></geometry></collision></link>
  <link name="fb"><collision><geometry><mesh filename=")" + finger_mesh + R"("/></geometry></collision></link>)");
}

ArmModelOptions geometry_options(const fs::path& packages) {
  ArmModelOptions o;
  o.ee_link = "hand";
  o.finger_joints = {"fj1", "fj2"};
  o.package_paths = {packages.string()};
  return o;
}

TEST(LinkShapes, UrdfCollisionGeometryBecomesLinkShapes) {
  const fs::path d = temp_dir("urdf");
  fs::create_directories(d / "testpkg" / "meshes");
  testing::write_box_stl(d / "testpkg" / "meshes" / "pad.stl", Eigen::Vector3d(0.01, 0.005, 0.02));
  const ArmModel arm =
      ArmModel::from_string(geometry_urdf("package://missing_pkg/meshes/fb.stl"), "shapes", geometry_options(d));
  ASSERT_EQ(arm.link_shapes().size(), 4u);  // fb's mesh is nowhere on the package path
  ASSERT_EQ(arm.skipped_meshes().size(), 1u);
  EXPECT_EQ(arm.skipped_meshes()[0], "package://missing_pkg/meshes/fb.stl");
  std::map<std::string, const LinkShape*> by_link;
  for (const LinkShape& s : arm.link_shapes()) by_link[s.link] = &s;
  ASSERT_EQ(by_link.count("l1") + by_link.count("l2") + by_link.count("hand") + by_link.count("fa"), 4u);

  const LinkShape& box = *by_link["l1"];
  EXPECT_EQ(box.kind, LinkShape::Kind::kBox);
  EXPECT_TRUE(box.half_extents.isApprox(Eigen::Vector3d(0.05, 0.1, 0.15)));
  EXPECT_TRUE(box.origin.translation().isApprox(Eigen::Vector3d(0.15, 0, 0)));
  EXPECT_TRUE((box.origin.linear() * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), 1e-12));  // yaw 90 deg

  const LinkShape& cyl = *by_link["l2"];  // a 32-sided prism: 2 x 30 cap triangles and 64 on the side
  EXPECT_EQ(cyl.kind, LinkShape::Kind::kConvexMesh);
  EXPECT_EQ(cyl.vertices.size(), 64u);
  EXPECT_EQ(cyl.triangles.size(), 124u);
  const double polygon = 16 * std::sin(2 * M_PI / 32) * 0.02 * 0.02;  // the 32-gon's area
  EXPECT_NEAR(hull_volume(cyl.vertices, cyl.triangles), polygon * 0.2, 1e-12);
  for (const Eigen::Vector3d& p : cyl.vertices) {
    EXPECT_NEAR(std::hypot(p.x(), p.y()), 0.02, 1e-12);
    EXPECT_NEAR(std::abs(p.z()), 0.1, 1e-12);
  }

  EXPECT_EQ(by_link["hand"]->kind, LinkShape::Kind::kSphere);
  EXPECT_DOUBLE_EQ(by_link["hand"]->radius, 0.03);

  const LinkShape& pad = *by_link["fa"];  // the STL read from disk, scaled by 2, hulled
  EXPECT_EQ(pad.kind, LinkShape::Kind::kConvexMesh);
  EXPECT_EQ(pad.source, (d / "testpkg" / "meshes" / "pad.stl").string());
  EXPECT_EQ(pad.vertices.size(), 8u);
  EXPECT_EQ(pad.triangles.size(), 12u);
  Eigen::AlignedBox3d bounds;
  for (const Eigen::Vector3d& p : pad.vertices) bounds.extend(p);
  EXPECT_TRUE(bounds.max().isApprox(Eigen::Vector3d(0.02, 0.01, 0.04), 1e-6));  // assimp reads single precision
  EXPECT_NEAR(hull_volume(pad.vertices, pad.triangles), 0.04 * 0.02 * 0.08, 1e-6 * 0.04 * 0.02 * 0.08);

  // The hand: the last arm joint's child link and everything below it.
  EXPECT_TRUE(arm.is_hand_link("l2"));
  EXPECT_TRUE(arm.is_hand_link("hand"));
  EXPECT_TRUE(arm.is_hand_link("fa"));
  EXPECT_FALSE(arm.is_hand_link("l1"));
  EXPECT_FALSE(arm.is_hand_link("base_link"));

  // A URDF a client sends to the service reads no file: its meshes are all left out.
  ArmModelOptions no_files = geometry_options(d);
  no_files.read_meshes = false;
  const ArmModel sent = ArmModel::from_string(geometry_urdf("file://" + (d / "testpkg" / "meshes" / "pad.stl").string()),
                                              "robot.urdf", no_files);
  EXPECT_EQ(sent.link_shapes().size(), 3u);  // the box, cylinder and sphere
  EXPECT_EQ(sent.skipped_meshes().size(), 2u);
  fs::remove_all(d);
}

TEST(LinkShapes, AMeshFileThatCannotBeReadIsAnInputErrorNamingIt) {
  const fs::path d = temp_dir("bad");
  fs::create_directories(d / "testpkg" / "meshes");
  testing::write_box_stl(d / "testpkg" / "meshes" / "pad.stl", Eigen::Vector3d(0.01, 0.005, 0.02));
  std::ofstream(d / "testpkg" / "meshes" / "broken.stl") << "this is not a mesh\n";
  try {
    ArmModel::from_string(geometry_urdf("package://testpkg/meshes/broken.stl"), "shapes", geometry_options(d));
    ADD_FAILURE() << "no InputError";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find("broken.stl"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("URDF shapes"), std::string::npos) << e.what();
  }
  fs::remove_all(d);
}

}  // namespace
}  // namespace gd::robot
