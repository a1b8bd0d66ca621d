#include "robot/link_shapes.h"

#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Surface_mesh.h>
#include <CGAL/convex_hull_3.h>
#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <urdf_model/model.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <map>
#include <numbers>

#include "sim/demand.h"

namespace gd::robot {

using sim::InputError;
namespace fs = std::filesystem;

namespace {

constexpr int kCylinderSides = 32;

bool is_file(const fs::path& p) {
  std::error_code ec;
  return fs::is_regular_file(p, ec);
}

Eigen::Isometry3d to_eigen(const urdf::Pose& p) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::Quaterniond(p.rotation.w, p.rotation.x, p.rotation.y, p.rotation.z).normalized().toRotationMatrix();
  T.translation() = Eigen::Vector3d(p.position.x, p.position.y, p.position.z);
  return T;
}

/// The vertices of every mesh in an assimp scene, with the node transforms applied.
void collect_points(const aiScene* scene, const Eigen::Vector3d& scale, std::vector<Eigen::Vector3d>* out) {
  for (unsigned m = 0; m < scene->mNumMeshes; ++m) {
    const aiMesh* mesh = scene->mMeshes[m];
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const aiVector3D& p = mesh->mVertices[v];
      out->emplace_back(scale.x() * p.x, scale.y() * p.y, scale.z() * p.z);
    }
  }
}

}  // namespace

std::string resolve_mesh_uri(const std::string& uri, const std::string& urdf_dir,
                             const std::vector<std::string>& package_paths) {
  const std::string package = "package://", file = "file://";
  if (uri.rfind(package, 0) == 0) {
    const std::string rest = uri.substr(package.size());
    const auto slash = rest.find('/');
    if (slash == std::string::npos) return "";
    const std::string name = rest.substr(0, slash), inside = rest.substr(slash + 1);
    for (const std::string& dir : package_paths) {
      const fs::path d(dir);
      if (is_file(d / name / inside)) return (d / name / inside).string();
      if (d.filename() == name && is_file(d / inside)) return (d / inside).string();
    }
    return "";
  }
  const fs::path p = uri.rfind(file, 0) == 0 ? fs::path(uri.substr(file.size())) : fs::path(uri);
  if (p.is_absolute()) return is_file(p) ? p.string() : "";
  if (urdf_dir.empty()) return "";  // a URDF given as text has no directory
  const fs::path rel = fs::path(urdf_dir) / p;
  return is_file(rel) ? rel.string() : "";
}

void convex_hull(const std::vector<Eigen::Vector3d>& points, const std::string& what,
                 std::vector<Eigen::Vector3d>* vertices, std::vector<Eigen::Vector3i>* triangles) {
  using K = CGAL::Exact_predicates_inexact_constructions_kernel;
  using Mesh = CGAL::Surface_mesh<K::Point_3>;
  std::vector<K::Point_3> pts;
  pts.reserve(points.size());
  for (const Eigen::Vector3d& p : points) {
    if (!p.allFinite()) throw InputError(what + ": a vertex is not finite");
    pts.emplace_back(p.x(), p.y(), p.z());
  }
  if (pts.size() < 4) throw InputError(what + ": fewer than four points span no volume (a collision shape needs a solid)");
  Mesh hull;
  CGAL::convex_hull_3(pts.begin(), pts.end(), hull);
  if (hull.number_of_faces() < 4) throw InputError(what + ": its points span no volume (a collision shape needs a solid)");
  vertices->clear();
  triangles->clear();
  std::map<Mesh::Vertex_index, int> index;
  for (Mesh::Vertex_index v : hull.vertices()) {
    index[v] = static_cast<int>(vertices->size());
    const K::Point_3& p = hull.point(v);
    vertices->emplace_back(p.x(), p.y(), p.z());
  }
  for (Mesh::Face_index f : hull.faces()) {
    Eigen::Vector3i t;
    int k = 0;
    for (Mesh::Vertex_index v : CGAL::vertices_around_face(hull.halfedge(f), hull)) {
      if (k < 3) t[k] = index[v];
      ++k;
    }
    if (k != 3) throw InputError(what + ": its convex hull has a face that is not a triangle");
    triangles->push_back(t);
  }
  // Outward faces enclose a positive volume; coplanar points give a flat, doubly covered polygon.
  double volume = 0;
  for (const Eigen::Vector3i& t : *triangles)
    volume += (*vertices)[t[0]].dot((*vertices)[t[1]].cross((*vertices)[t[2]])) / 6;
  Eigen::AlignedBox3d box;
  for (const Eigen::Vector3d& v : *vertices) box.extend(v);
  if (!(volume > 1e-9 * std::pow(box.sizes().maxCoeff(), 3)))
    throw InputError(what + ": its points span no volume (a collision shape needs a solid)");
}

namespace {

/// Whether every triangle has an area well above rounding (Collider::mesh refuses slivers).
bool no_slivers(const std::vector<Eigen::Vector3d>& v, const std::vector<Eigen::Vector3i>& t) {
  Eigen::AlignedBox3d box;
  for (const Eigen::Vector3d& p : v) box.extend(p);
  const double d2 = box.diagonal().squaredNorm();
  return std::all_of(t.begin(), t.end(), [&](const Eigen::Vector3i& f) {
    return (v[f[1]] - v[f[0]]).cross(v[f[2]] - v[f[0]]).norm() > 1e-10 * d2;
  });
}

/// One point per cell of a grid of spacing h: the first of the points that fall in it, unmoved.
std::vector<Eigen::Vector3d> thinned(const std::vector<Eigen::Vector3d>& points, double h) {
  std::map<std::array<long long, 3>, Eigen::Vector3d> cells;
  for (const Eigen::Vector3d& p : points)
    cells.emplace(std::array<long long, 3>{std::llround(p.x() / h), std::llround(p.y() / h), std::llround(p.z() / h)}, p);
  std::vector<Eigen::Vector3d> out;
  for (const auto& [key, p] : cells) out.push_back(p);
  return out;
}

}  // namespace

void read_mesh_hull(const std::string& path, const Eigen::Vector3d& scale, std::vector<Eigen::Vector3d>* vertices,
                    std::vector<Eigen::Vector3i>* triangles) {
  Assimp::Importer importer;
  const aiScene* scene = importer.ReadFile(path, aiProcess_PreTransformVertices | aiProcess_JoinIdenticalVertices);
  if (scene == nullptr || scene->mNumMeshes == 0)
    throw InputError("mesh " + path + ": cannot be read (" + importer.GetErrorString() +
                     "); give a mesh file assimp reads, e.g. STL, OBJ or COLLADA");
  std::vector<Eigen::Vector3d> points;
  collect_points(scene, scale, &points);
  // A CAD mesh's hull has slivers between nearly coplanar points, and thousands of faces: its
  // points are thinned to one per cell of a 1 mm grid (or a hundredth of the mesh's size, if
  // smaller) first, a coarser grid while slivers remain.
  Eigen::AlignedBox3d box;
  for (const Eigen::Vector3d& p : points) box.extend(p);
  double h = std::min(1e-3, 0.01 * box.diagonal().norm());
  for (int attempt = 0;; ++attempt, h *= 2) {
    convex_hull(h > 0 ? thinned(points, h) : points, "mesh " + path, vertices, triangles);
    if (no_slivers(*vertices, *triangles)) return;
    if (attempt == 4) throw InputError("mesh " + path + ": its convex hull keeps degenerate faces");
  }
}

std::vector<LinkShape> read_link_shapes(const urdf::ModelInterface& model, const std::string& urdf_dir,
                                        const std::vector<std::string>& package_paths,
                                        std::vector<std::string>* skipped, bool read_meshes) {
  std::vector<LinkShape> out;
  for (const auto& [name, link] : model.links_) {
    if (!link) continue;
    std::vector<urdf::CollisionSharedPtr> elements = link->collision_array;
    if (elements.empty() && link->collision) elements.push_back(link->collision);
    for (const urdf::CollisionSharedPtr& c : elements) {
      if (!c || !c->geometry) continue;
      LinkShape s;
      s.link = name;
      s.origin = to_eigen(c->origin);
      const std::string what = "URDF link '" + name + "' collision";
      switch (c->geometry->type) {
        case urdf::Geometry::BOX: {
          const auto& box = static_cast<const urdf::Box&>(*c->geometry);
          s.kind = LinkShape::Kind::kBox;
          s.half_extents = 0.5 * Eigen::Vector3d(box.dim.x, box.dim.y, box.dim.z);
          if (!(s.half_extents.minCoeff() > 0)) throw InputError(what + ": a box needs three positive sizes");
          s.source = "box";
          break;
        }
        case urdf::Geometry::SPHERE: {
          s.kind = LinkShape::Kind::kSphere;
          s.radius = static_cast<const urdf::Sphere&>(*c->geometry).radius;
          if (!(s.radius > 0)) throw InputError(what + ": a sphere needs a positive radius");
          s.source = "sphere";
          break;
        }
        case urdf::Geometry::CYLINDER: {  // along the element's z, centred
          const auto& cyl = static_cast<const urdf::Cylinder&>(*c->geometry);
          if (!(cyl.radius > 0 && cyl.length > 0)) throw InputError(what + ": a cylinder needs a positive radius and length");
          std::vector<Eigen::Vector3d> pts;
          for (int k = 0; k < kCylinderSides; ++k) {
            const double a = 2 * std::numbers::pi * k / kCylinderSides;
            for (double z : {-0.5 * cyl.length, 0.5 * cyl.length})
              pts.emplace_back(cyl.radius * std::cos(a), cyl.radius * std::sin(a), z);
          }
          s.kind = LinkShape::Kind::kConvexMesh;
          convex_hull(pts, what, &s.vertices, &s.triangles);
          s.source = "cylinder";
          break;
        }
        case urdf::Geometry::MESH: {
          const auto& mesh = static_cast<const urdf::Mesh&>(*c->geometry);
          const std::string path = read_meshes ? resolve_mesh_uri(mesh.filename, urdf_dir, package_paths) : "";
          if (path.empty()) {
            if (skipped) skipped->push_back(mesh.filename);
            continue;
          }
          s.kind = LinkShape::Kind::kConvexMesh;
          read_mesh_hull(path, Eigen::Vector3d(mesh.scale.x, mesh.scale.y, mesh.scale.z), &s.vertices, &s.triangles);
          s.source = path;
          break;
        }
        default:
          continue;
      }
      out.push_back(std::move(s));
    }
  }
  return out;
}

}  // namespace gd::robot
