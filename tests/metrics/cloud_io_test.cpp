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

// Inputs tests/fuzz/fuzz_cloud_io found crashing or exhausting the process inside PCL; each is now
// an InputError (or, for the PLY layouts PCL's reader aborted on, a cloud).
TEST(CloudIo, PcdHeadersPclMisreadsAreInputErrors) {
  const std::string d = temp_dir("fuzz");
  const std::string body = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\n"
                           "POINTS 1\nDATA ascii\n0 0 0\n";
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(d + "/" + name, std::ios::binary) << text;
    return d + "/" + name;
  };
  // PCL ends the header at a line it does not know, then formats fields[0] of no fields (SEGV).
  const std::string unknown_first = write("unknown_first.pcd", "this is 7 - Point Cloud Data\n" + body);
  expect_input_error([&] { load_cloud(unknown_first); }, "no FIELDS line");
  // PCL allocates POINTS x point size from the header before reading (4 GiB here).
  const std::string huge_size = write("huge_size.pcd", "FIELDS x y z\nSIZE 4294967295 1 1\nTYPE U U U\n"
                                                       "POINTS 2\nDATA ascii\n1 2 3\n4 5 6\n");
  expect_input_error([&] { load_cloud(huge_size); }, "SIZE");
  const std::string huge_points = write("huge_points.pcd", "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
                                                           "POINTS 2000000000\nDATA ascii\n1 2 3\n");
  expect_input_error([&] { load_cloud(huge_points); }, "cannot hold the 2000000000 points");
  // PCL reads on after DATA while lines look like header lines: binary data starting "POINTS ...".
  std::string sneaky = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nDATA binary\nPOINTS 900000000\n";
  const std::string after_data = write("after_data.pcd", sneaky);
  expect_input_error([&] { load_cloud(after_data); }, "POINTS appears twice");
  // A compressed block whose stated size is not the points' size.
  std::string comp = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nDATA binary_compressed\n";
  const uint32_t sizes[2] = {4, 0xfffffff0u};
  comp.append(reinterpret_cast<const char*>(sizes), 8).append("abcd");
  const std::string compressed = write("compressed.pcd", comp);
  expect_input_error([&] { load_cloud(compressed); }, "compressed block holds");
  // A SIZE that does not fit its TYPE (PCL would write 8-byte doubles into 1-byte slots).
  const std::string mismatch = write("mismatch.pcd", "FIELDS x y z\nSIZE 1 1 1\nTYPE F F F\nPOINTS 1\n"
                                                     "DATA ascii\n1 2 3\n");
  expect_input_error([&] { load_cloud(mismatch); }, "does not fit SIZE");
}

TEST(CloudIo, PlyReaderTakesVerticesFromAnyLayout) {
  const std::string d = temp_dir("ply");
  // Colour properties without `red` (PCL's PLYReader failed an assert and aborted the process).
  std::ofstream(d + "/green_blue.ply")
      << "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
         "property uchar green\nproperty uchar blue\nend_header\n0 0 0 1 2\n1 0 0.5 3 4\n0 1 0.25 5 6\n";
  expect_same(load_cloud(d + "/green_blue.ply"), Cloud{{0, 0, 0}, {1, 0, 0.5f}, {0, 1, 0.25f}}, 0);
  // An element before the vertices, a list and a double among the vertex properties, big endian.
  std::string be = "ply\r\nformat binary_big_endian 1.0\r\ncomment c\r\nelement camera 1\r\nproperty uchar a\r\n"
                   "property list uchar int b\r\nelement vertex 2\r\nproperty list uchar ushort n\r\n"
                   "property double x\r\nproperty float y\r\nproperty float z\r\nelement face 0\r\n"
                   "property list uchar int vertex_indices\r\nend_header\n";
  auto put_be = [&](const void* p, size_t n) {
    const auto* b = static_cast<const char*>(p);
    for (size_t i = n; i-- > 0;) be.push_back(b[i]);
  };
  be += std::string("\x07\x02", 2);
  const int32_t ib[2] = {-1, 5};
  put_be(&ib[0], 4), put_be(&ib[1], 4);
  for (int v = 0; v < 2; ++v) {
    be += std::string("\x01", 1);
    const uint16_t n = 9;
    put_be(&n, 2);
    const double x = 0.5 + v;
    const float y = -1.25f, z = 2.0f * v;
    put_be(&x, 8), put_be(&y, 4), put_be(&z, 4);
  }
  std::ofstream(d + "/be.ply", std::ios::binary) << be;
  expect_same(load_cloud(d + "/be.ply"), Cloud{{0.5f, -1.25f, 0}, {1.5f, -1.25f, 2}}, 0);
  // Counts the data cannot hold are refused before anything of their size is allocated.
  std::ofstream(d + "/huge.ply") << "ply\nformat binary_little_endian 1.0\nelement vertex 2000000000\n"
                                    "property float x\nproperty float y\nproperty float z\nend_header\n"
                                 << std::string(24, '\0');
  expect_input_error([&] { load_cloud(d + "/huge.ply"); }, "truncated");
  std::ofstream(d + "/int_x.ply") << "ply\nformat ascii 1.0\nelement vertex 1\nproperty int x\nproperty int y\n"
                                     "property int z\nend_header\n1 2 3\n";
  expect_input_error([&] { load_cloud(d + "/int_x.ply"); }, "not float32 or float64");
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
