#include "sim/mesh.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <numbers>
#include <set>
#include <thread>
#include <utility>
#include <vector>

#include "sim/demand.h"

namespace gd::sim {
namespace {

using Eigen::Vector3i;

Real min_angle_deg(const Mesh& m) {
  Real worst = 180;
  for (const auto& f : m.tris) {
    for (int k = 0; k < 3; ++k) {
      const Vec3 u = m.x[f[(k + 1) % 3]] - m.x[f[k]], v = m.x[f[(k + 2) % 3]] - m.x[f[k]];
      worst =
          std::min(worst, std::acos(u.normalized().dot(v.normalized())) * 180 / std::numbers::pi);
    }
  }
  return worst;
}

Vec3 normal(const Mesh& m, const Vector3i& f) {
  return (m.x[f[1]] - m.x[f[0]]).cross(m.x[f[2]] - m.x[f[0]]);
}

/// Expects validate_mesh to throw an InputError whose message contains `needle`.
void expect_rejected(const Mesh& m, const std::string& needle) {
  try {
    validate_mesh(m);
    ADD_FAILURE() << "validate_mesh accepted a mesh that should fail with '" << needle << "'";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

/// Two triangles forming the unit square, with uvs.
Mesh square() {
  Mesh m;
  m.x = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(1, 1, 0), Vec3(0, 1, 0)};
  m.uv = {Vec2(0, 0), Vec2(1, 0), Vec2(1, 1), Vec2(0, 1)};
  m.tris = {Vector3i(0, 1, 2), Vector3i(0, 2, 3)};
  return m;
}

std::string temp_path(const std::string& name) {
  return (std::filesystem::temp_directory_path() /
          ("gd_" + std::to_string(::getpid()) + "_" + name))
      .string();
}

TEST(MeshRect, ExactDimensionsAndArea) {
  for (const auto& [sx, sy, h] : {std::tuple{1.0, 1.0, 0.05}, {0.7, 0.3, 0.04}, {2.0, 0.5, 0.1}}) {
    const Mesh m = make_rect(sx, sy, h);
    validate_mesh(m);
    Vec3 lo = m.x[0], hi = m.x[0];
    for (const Vec3& p : m.x) lo = lo.cwiseMin(p), hi = hi.cwiseMax(p);
    EXPECT_EQ(lo, Vec3(0, 0, 0));
    EXPECT_EQ(hi, Vec3(sx, sy, 0));
    EXPECT_NEAR(mesh_area(m), sx * sy, 1e-12);
    EXPECT_NEAR(mean_edge_length(m), h, 0.15 * h);
    ASSERT_EQ(m.uv.size(), m.x.size());
    for (size_t i = 0; i < m.x.size(); ++i) EXPECT_EQ(m.uv[i], m.x[i].head<2>());
  }
}

TEST(MeshRect, NearEquilateralAndFacingUp) {
  for (const auto& [sx, sy, h] : {std::tuple{1.0, 1.0, 0.05}, {0.7, 0.3, 0.04}, {0.2, 0.2, 0.1}}) {
    const Mesh m = make_rect(sx, sy, h);
    EXPECT_GT(min_angle_deg(m), 40.0) << sx << "x" << sy << " @ " << h;
    for (const auto& f : m.tris) {
      const Vec3 n = normal(m, f);
      EXPECT_GT(n.z(), 0);
      EXPECT_NEAR(n.x(), 0, 1e-15);
      EXPECT_NEAR(n.y(), 0, 1e-15);
    }
  }
}

TEST(MeshRect, QualityHoldsAcrossSizes) {
  // Any rectangle at least 3 spacings wide and tall keeps every angle at or above 40°.
  for (Real sx = 0.15; sx < 1.0; sx += 0.053) {
    for (Real sy = 0.15; sy < 1.0; sy += 0.049) {
      EXPECT_GT(min_angle_deg(make_rect(sx, sy, 0.05)), 40.0 - 1e-9) << sx << " x " << sy;
    }
  }
}

TEST(MeshRect, BoundaryVerticesLieOnTheEdges) {
  const Mesh m = make_rect(1.0, 0.6, 0.05);
  const Topology top = build_topology(m);
  auto on_edge = [](const Vec3& p) {
    return p.x() == 0 || p.x() == 1.0 || p.y() == 0 || p.y() == 0.6;
  };
  for (int v : top.boundary_vertices) EXPECT_TRUE(on_edge(m.x[v])) << m.x[v].transpose();
  EXPECT_EQ(top.boundary_vertices, vertices_where(m, on_edge));
}

TEST(Topology, EulerCharacteristicAndCounts) {
  for (const Mesh& m : {make_rect(1.0, 0.8, 0.05), make_disc(0.4, 0.03), square()}) {
    const Topology top = build_topology(m);
    const int v = int(m.x.size()), e = int(top.edges.size()), f = int(m.tris.size());
    EXPECT_EQ(v - e + f, 1);
    const int boundary_edges = e - int(top.hinges.size());
    EXPECT_EQ(3 * f, 2 * int(top.hinges.size()) + boundary_edges);
    EXPECT_EQ(int(top.boundary_vertices.size()), boundary_edges);  // one boundary loop
    EXPECT_EQ(top.hinge_tris.size(), top.hinges.size());
    for (const auto& ed : top.edges) EXPECT_LT(ed[0], ed[1]);
  }
}

TEST(Topology, HingeConvention) {
  const Mesh m = make_rect(0.5, 0.5, 0.05);
  const Topology top = build_topology(m);
  ASSERT_FALSE(top.hinges.empty());
  // Does triangle t contain a -> b in its winding, with `opp` as its third vertex?
  auto directed = [&](int t, int a, int b, int opp) {
    const Vector3i& f = m.tris[t];
    for (int k = 0; k < 3; ++k) {
      if (f[k] == a && f[(k + 1) % 3] == b) return f[(k + 2) % 3] == opp;
    }
    return false;
  };
  for (size_t h = 0; h < top.hinges.size(); ++h) {
    const auto& x = top.hinges[h];
    const auto& t = top.hinge_tris[h];
    EXPECT_TRUE(directed(t[0], x[0], x[1], x[2]));
    EXPECT_TRUE(directed(t[1], x[1], x[0], x[3]));
  }
  // The square: edge (0,2) appears as 2 -> 0 in triangle 0 = (0,1,2), so x2 = 1.
  const Topology sq = build_topology(square());
  ASSERT_EQ(sq.hinges.size(), 1u);
  EXPECT_EQ(sq.hinges[0], Eigen::Vector4i(2, 0, 1, 3));
  EXPECT_EQ(sq.hinge_tris[0], Eigen::Vector2i(0, 1));
}

TEST(Topology, InconsistentOrientationStillGivesHinge) {
  Mesh m = square();
  m.tris[1] = Vector3i(0, 3, 2);  // flipped: edge 2 -> 0 now appears in the same direction twice
  const Topology top = build_topology(m);
  ASSERT_EQ(top.hinges.size(), 1u);
  EXPECT_EQ(top.hinges[0], Eigen::Vector4i(2, 0, 1, 3));
}

TEST(MeshDisc, AreaAndQuality) {
  const Real r = 0.5;
  const Mesh m = make_disc(r, 0.04);
  validate_mesh(m);
  EXPECT_NEAR(mesh_area(m), std::numbers::pi * r * r, 0.02 * std::numbers::pi * r * r);
  EXPECT_GT(min_angle_deg(m), 30.0);
  for (const auto& f : m.tris) EXPECT_GT(normal(m, f).z(), 0);
  for (const Vec3& p : m.x) EXPECT_LE(p.norm(), r + 1e-12);
  EXPECT_NEAR(mean_edge_length(m), 0.04, 0.01);
}

TEST(MeshQueries, NearestAndWhere) {
  const Mesh m = make_rect(1.0, 1.0, 0.1);
  EXPECT_EQ(m.x[nearest_vertex(m, Vec3(1.02, 1.01, 0.3))], Vec3(1, 1, 0));
  const std::vector<int> left = vertices_where(m, [](const Vec3& p) { return p.x() == 0; });
  std::set<Real> row_ys;
  for (const Vec3& p : m.x) row_ys.insert(p.y());
  EXPECT_EQ(left.size(), row_ys.size());  // every row starts on the left edge
  EXPECT_TRUE(std::is_sorted(left.begin(), left.end()));
}

TEST(MeshValidate, AcceptsGoodMesh) { EXPECT_NO_THROW(validate_mesh(square())); }

TEST(MeshValidate, RejectsEachDefect) {
  const Real nan = std::numeric_limits<Real>::quiet_NaN();
  {
    expect_rejected(Mesh{}, "no vertices");
    Mesh m = square();
    m.tris.clear();
    expect_rejected(m, "no triangles");
  }
  {
    Mesh m = square();
    m.tris[1] = Vector3i(0, 2, 4);
    expect_rejected(m, "triangle 1 references vertex 4");
    m.tris[1] = Vector3i(-1, 2, 3);
    expect_rejected(m, "references vertex -1");
  }
  {
    Mesh m = square();
    m.x[2].y() = nan;
    expect_rejected(m, "vertex 2 has a non-finite position");
  }
  {
    Mesh m = square();
    m.uv.pop_back();
    expect_rejected(m, "3 uvs but 4 vertices");
    m = square();
    m.uv[3].x() = std::numeric_limits<Real>::infinity();
    expect_rejected(m, "uv 3 is non-finite");
  }
  {
    Mesh m = square();
    m.x.push_back(Vec3(2, 2, 0));  // collinear with 0 and 2
    m.uv.push_back(Vec2(2, 3));
    m.tris.push_back(Vector3i(0, 2, 4));
    expect_rejected(m, "triangle 2 (0, 2, 4) is degenerate: 3D area");
    m.x[4] = Vec3(2, 3, 0);
    m.uv[4] = Vec2(2, 2);  // fine in 3D, collinear in uv
    expect_rejected(m, "triangle 2 (0, 2, 4) is degenerate in uv");
    m.tris[2] = Vector3i(0, 2, 2);
    expect_rejected(m, "repeats a vertex");
  }
  {
    Mesh m = square();
    m.tris.push_back(Vector3i(2, 1, 0));
    expect_rejected(m, "triangles 0 and 2 use the same vertices (0, 1, 2)");
  }
  {
    Mesh m = square();
    m.x.push_back(Vec3(0.5, 0.5, 1));
    m.uv.push_back(Vec2(2, 3));
    m.tris.push_back(Vector3i(0, 2, 4));
    expect_rejected(m, "non-manifold edge between vertices 0 and 2");
  }
  {
    Mesh m = square();
    for (Vec3& p : m.x) p *= 1000;  // millimetres
    expect_rejected(m, "diagonal");
    m = square();
    for (Vec3& p : m.x) p *= 1e-6;
    expect_rejected(m, "mean edge length");
  }
}

TEST(Obj, RoundTripKeepsEverything) {
  const Mesh m = make_rect(0.3, 0.2, 0.05);
  const std::string path = temp_path("gd_mesh_roundtrip.obj");
  write_obj(m, {}, path);
  const Mesh r = read_obj(path);
  ASSERT_EQ(r.x.size(), m.x.size());
  ASSERT_EQ(r.uv.size(), m.uv.size());
  ASSERT_EQ(r.tris.size(), m.tris.size());
  // To the last bit or so: write_obj prints the shortest round-trip decimal, but tinyobjloader's
  // number parser is not correctly rounded (0.3 reads as 0.30000000000000004).
  for (size_t i = 0; i < m.x.size(); ++i) EXPECT_LE((r.x[i] - m.x[i]).norm(), 1e-15) << i;
  for (size_t i = 0; i < m.uv.size(); ++i) EXPECT_LE((r.uv[i] - m.uv[i]).norm(), 1e-15) << i;
  for (size_t i = 0; i < m.tris.size(); ++i) EXPECT_EQ(r.tris[i], m.tris[i]);

  std::vector<Vec3> moved = m.x;
  for (Vec3& p : moved) p.z() += 0.25;
  write_obj(m, moved, path);
  EXPECT_LE((read_obj(path).x[3] - moved[3]).norm(), 1e-15);
  std::filesystem::remove(path);
}

TEST(Obj, ReadsPolygonsAndIndexForms) {
  const std::string path = temp_path("gd_mesh_forms.obj");
  std::ofstream(path) << "# a quad and a triangle\n"
                         "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\n"
                         "vn 0 0 1\n"
                         "f 1//1 2//1 3//1 4//1\n"
                         "# relative indices\n"
                         "f -4 5 -3\n";
  const Mesh m = read_obj(path);
  EXPECT_EQ(m.x.size(), 5u);
  ASSERT_EQ(m.tris.size(), 3u);
  EXPECT_EQ(m.tris[0], Vector3i(0, 1, 2));
  EXPECT_EQ(m.tris[1], Vector3i(0, 2, 3));
  EXPECT_EQ(m.tris[2], Vector3i(1, 4, 2));
  EXPECT_TRUE(m.uv.empty());  // no vt at all

  // A uv seam (vertex 0 with two different vt) keeps the uvs per corner.
  std::ofstream(path) << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n"
                         "vt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvt 5 5\n"
                         "f 1/1 2/2 3/3\nf 1/5 3/3 4/4\n";
  const Mesh seam = read_obj(path);
  ASSERT_EQ(seam.uv.size(), 5u);
  ASSERT_EQ(seam.uv_tris.size(), 2u);
  EXPECT_EQ(seam.uv_tris[1], Vector3i(4, 2, 3));
  EXPECT_EQ(corner_uv(seam, 1, 0), Vec2(5, 5));
  EXPECT_EQ(corner_uv(seam, 0, 0), Vec2(0, 0));
  std::filesystem::remove(path);
}

TEST(Obj, RejectsMalformedNamingTheFace) {
  const std::string path = temp_path("gd_mesh_bad.obj");
  auto expect_error = [&](const std::string& text, const std::string& needle) {
    std::ofstream(path) << text;
    try {
      read_obj(path);
      ADD_FAILURE() << "accepted: " << text;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  expect_error("v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 3\nf 1 2 7\n", "face 2 uses vertex 7, out of range (the file has 3 vertices)");
  // tinyobjloader drops a face of fewer than 3 vertices; what is left is no mesh.
  std::ofstream(path) << "v 0 0 0\nv 1 0 0\nf 1 2\n";
  EXPECT_TRUE(read_obj(path).tris.empty());
  EXPECT_THROW(validate_mesh(read_obj(path)), InputError);
  expect_error("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 0 2\n", "could not be parsed");  // OBJ indices start at 1
  std::filesystem::remove(path);
  EXPECT_THROW(read_obj(path), InputError);  // missing file
  EXPECT_THROW(read_obj(std::filesystem::temp_directory_path().string()), InputError);  // a directory
  EXPECT_THROW(write_obj(square(), {}, "/nonexistent-dir/x.obj"), InputError);
}

// tinyobjloader reads what it cannot parse as 0: such files are refused with the line.
TEST(Obj, RejectsNumbersItCannotReadNamingTheLine) {
  const std::string path = temp_path("gd_mesh_numbers.obj");
  const std::string tail = "v 1 0 0\nv 0 1 0\nf 1 2 3\n";
  for (const auto& [first, needle] : std::vector<std::pair<std::string, std::string>>{
           {"v nan 0 0\n", "line 1: 'nan' in a 'v' line is not a finite number"},
           {"v inf 0 0\n", "line 1: 'inf' in a 'v' line is not a finite number"},
           {"v abc 0 0\n", "line 1: 'abc' in a 'v' line is not a finite number"},
           {"v 0.05\n", "line 1: a 'v' line needs 3 numbers, it has 1"},
           {"v 1e999 0 0\n", "'1e999' in a 'v' line is not a finite number"},
           {"v 0 0 0\nvt 0.5 x\n", "line 2: 'x' in a 'vt' line is not a finite number"}}) {
    std::ofstream(path) << first << tail;
    try {
      read_obj(path);
      ADD_FAILURE() << "accepted: " << first;
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  }
  // Comments, extra values (w, vertex colours) and CRLF line ends are fine.
  std::ofstream(path) << "v 0 0 0 1 # w\r\nv 1 0 0 0.5 0.5 0.5\r\nv 0 1 0\r\nf 1 2 3\r\n";
  EXPECT_EQ(read_obj(path).tris.size(), 1u);
  std::filesystem::remove(path);
}

// An `mtllib` line opens no file: here it names a FIFO without a writer, which would block any
// reader forever; the OBJ must still be read, promptly.
TEST(Obj, MaterialLibrariesAreNeverOpened) {
  const std::filesystem::path dir = std::filesystem::path(temp_path("gd_mesh_mtllib"));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  const std::string fifo = (dir / "trap.mtl").string();
  ASSERT_EQ(mkfifo(fifo.c_str(), 0600), 0);
  const std::string path = (dir / "m.obj").string();
  std::ofstream(path) << "mtllib trap.mtl\nmtllib " << fifo << "\nusemtl cloth\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  struct Result {
    std::atomic<bool> done{false};
    size_t tris = 0;
  };
  auto r = std::make_shared<Result>();
  std::thread([r, path] {  // detached: should read_obj block on the FIFO, the test fails, not hangs
    r->tris = read_obj(path).tris.size();
    r->done = true;
  }).detach();
  for (int i = 0; i < 100 && !r->done; ++i) std::this_thread::sleep_for(std::chrono::milliseconds(50));
  ASSERT_TRUE(r->done) << "read_obj blocked: it opened the mtllib FIFO";
  EXPECT_EQ(r->tris, 1u);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace gd::sim
