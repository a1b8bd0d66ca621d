#include "metrics/cloud_io.h"

#include <gtest/gtest.h>
#include <spdlog/fmt/fmt.h>

#include <Eigen/Geometry>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>

#include "metrics/test_util.h"

namespace gd::metrics {
namespace {

namespace fs = std::filesystem;
using testing::expect_input_error;
using testing::random_cloud;
using testing::temp_dir;

void expect_same(const Cloud& a, const Cloud& b, float tol) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) EXPECT_LE((a[i] - b[i]).norm(), tol) << "point " << i;
}

/// An ascii PCD as Open3D writes it: x y z plus a packed rgb field, one NaN point.
std::string open3d_ascii_pcd(const Cloud& c, size_t nan_at) {
  std::string s =
      "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\n"
      "TYPE F F F F\nCOUNT 1 1 1 1\nWIDTH " +
      std::to_string(c.size()) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " +
      std::to_string(c.size()) + "\nDATA ascii\n";
  for (size_t i = 0; i < c.size(); ++i) {
    if (i == nan_at)
      s += "nan nan nan 4.2108e+06\n";
    else
      s += fmt::format("{:.9g} {:.9g} {:.9g} 4.2108e+06\n", c[i].x(), c[i].y(), c[i].z());
  }
  return s;
}

TEST(CloudIo, PcdRoundTripsInEveryEncoding) {
  const std::string d = temp_dir("pcd");
  const Cloud c = random_cloud(500, 3);
  for (auto enc : {PcdEncoding::kAscii, PcdEncoding::kBinary, PcdEncoding::kBinaryCompressed}) {
    const std::string p = d + "/c" + std::to_string(int(enc)) + ".pcd";
    save_pcd(p, c, enc);
    expect_same(load_cloud(p), c, 1e-6f);
  }
  save_pcd(d + "/default.pcd", c);
  std::ifstream f(d + "/default.pcd");
  std::string text((std::istreambuf_iterator<char>(f)), {});
  EXPECT_NE(text.find("DATA binary\n"), std::string::npos);
}

TEST(CloudIo, DropsNanPointsOfAsciiOpen3dPcd) {
  const std::string d = temp_dir("nan");
  const Cloud c = random_cloud(20, 4);
  std::ofstream(d + "/o3d.pcd") << open3d_ascii_pcd(c, 7);
  Cloud expect = c;
  expect.erase(expect.begin() + 7);
  expect_same(load_cloud(d + "/o3d.pcd"), expect, 1e-6f);
}

TEST(CloudIo, DropsNanPointsOfBinaryPcdWithDoubleFields) {
  // Binary, x y z as float64 plus an rgb float: the layout Open3D uses for double clouds.
  const std::string d = temp_dir("bin");
  const Cloud c = random_cloud(30, 5);
  std::ofstream f(d + "/b.pcd", std::ios::binary);
  f << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 8 8 8 4\n"
       "TYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 30\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 30\n"
       "DATA binary\n";
  for (size_t i = 0; i < c.size(); ++i) {
    double xyz[3] = {c[i].x(), c[i].y(), c[i].z()};
    if (i == 0 || i == 29) xyz[1] = NAN;
    const float rgb = 1.0f;
    f.write(reinterpret_cast<const char*>(xyz), sizeof xyz);
    f.write(reinterpret_cast<const char*>(&rgb), sizeof rgb);
  }
  f.close();
  const Cloud got = load_cloud(d + "/b.pcd");
  expect_same(got, Cloud(c.begin() + 1, c.begin() + 29), 1e-6f);
}

TEST(CloudIo, PlyRoundTripAndAsciiPlyWithFaces) {
  const std::string d = temp_dir("ply");
  const Cloud c = random_cloud(300, 6);
  save_ply(d + "/b.ply", c, true);
  expect_same(load_cloud(d + "/b.ply"), c, 0);
  save_ply(d + "/a.ply", c, false);
  expect_same(load_cloud(d + "/a.ply"), c, 1e-6f);
  std::ofstream(d + "/mesh.ply")
      << "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
         "property double z\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n"
         "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
         "0 0 0 255 0 0\n1 0 0.5 0 255 0\n0 1 0.25 0 0 255\n3 0 1 2\n";
  expect_same(load_cloud(d + "/mesh.ply"),
              Cloud{{0, 0, 0}, {1, 0, 0.5f}, {0, 1, 0.25f}}, 0);
}

TEST(CloudIo, ObjVerticesInOrder) {
  const std::string d = temp_dir("obj");
  std::ofstream(d + "/m.OBJ") << "# t\nv 0 0 0\nv 1 0 0.1\nvt 0 0\nv 0 1 0.2\nf 1 2 3\n";
  expect_same(load_cloud(d + "/m.OBJ"), Cloud{{0, 0, 0}, {1, 0, 0.1f}, {0, 1, 0.2f}}, 0);
}

TEST(CloudIo, BrokenFilesAreInputErrorsNamingTheFile) {
  const std::string d = temp_dir("broken");
  expect_input_error([&] { load_cloud(d + "/missing.pcd"); }, "missing.pcd");
  std::ofstream(d + "/garbage.pcd") << "this is not a point cloud\n";
  expect_input_error([&] { load_cloud(d + "/garbage.pcd"); }, "garbage.pcd");
  std::ofstream(d + "/empty.ply");
  expect_input_error([&] { load_cloud(d + "/empty.ply"); }, "empty.ply");
  std::ofstream(d + "/trunc.pcd")
      << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 100\nHEIGHT 1\n"
         "POINTS 100\nDATA binary\nabc";
  expect_input_error([&] { load_cloud(d + "/trunc.pcd"); }, "trunc.pcd");
  std::ofstream(d + "/noxyz.pcd") << "VERSION 0.7\nFIELDS a b c\nSIZE 4 4 4\nTYPE F F F\n"
                                     "COUNT 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n1 2 3\n";
  expect_input_error([&] { load_cloud(d + "/noxyz.pcd"); }, "no 'x' field");
  std::ofstream(d + "/c.xyz") << "1 2 3\n";
  expect_input_error([&] { load_cloud(d + "/c.xyz"); }, ".pcd, .ply or .obj");
  std::ofstream(d + "/bad.obj") << "v 1 2 3\nf 0 1 1\n";  // OBJ indices start at 1
  expect_input_error([&] { load_cloud(d + "/bad.obj"); }, "bad.obj");
  std::ofstream(d + "/text.obj") << "this is not an OBJ file\n";
  expect_input_error([&] { load_cloud(d + "/text.obj"); }, "text.obj");
}

TEST(CloudIo, TransformCloudAppliesRigidTransform) {
  Eigen::Matrix4d T = Eigen::Matrix4d::Identity();
  T.topLeftCorner<3, 3>() = Eigen::AngleAxisd(0.5, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  T.topRightCorner<3, 1>() = Eigen::Vector3d(1, 2, 3);
  const Cloud c = random_cloud(10, 9);
  const Cloud t = transform_cloud(c, T);
  for (size_t i = 0; i < c.size(); ++i) {
    const Eigen::Vector3d e = T.topLeftCorner<3, 3>() * c[i].cast<double>() + T.topRightCorner<3, 1>();
    EXPECT_LE((t[i].cast<double>() - e).norm(), 1e-6);
  }
}

}  // namespace
}  // namespace gd::metrics
