#pragma once
/// \file
/// The collision geometry a URDF gives its links (`<link><collision>`), as shapes the cloth can
/// collide with in robot mode (docs/robot.md, "The arm's links"):
///   box -> a box; sphere -> a sphere; cylinder -> a 32-sided prism; mesh -> the convex hull of
///   the mesh file's vertices (read by assimp: STL, OBJ, COLLADA, ...; hulled by CGAL), as
///   MuJoCo and PyBullet collide with a mesh's convex hull.
/// Mesh files are found from their URI: `package://NAME/rest` under each directory of the
/// package path (DIR/NAME/rest, or DIR/rest where DIR itself is the package NAME), `file://PATH`,
/// or a path relative to the URDF's directory (none for a URDF given as text).
///
///   std::vector<std::string> skipped;
///   auto shapes = gd::robot::read_link_shapes(*model, "/path/arm.urdf", {"/opt/ros/share"}, &skipped);

#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <vector>

namespace urdf {
class ModelInterface;
}

namespace gd::robot {

/// One collision element of a link.
struct LinkShape {
  enum class Kind { kBox, kSphere, kConvexMesh };
  std::string link;                                  ///< the URDF link it belongs to
  Eigen::Isometry3d origin = Eigen::Isometry3d::Identity();  ///< the element's frame in the link's
  Kind kind = Kind::kBox;
  Eigen::Vector3d half_extents = Eigen::Vector3d::Zero();  ///< kBox, m
  double radius = 0;                                 ///< kSphere, m
  /// kConvexMesh: a closed convex triangle mesh in the element's frame (m), triangles facing out.
  std::vector<Eigen::Vector3d> vertices;
  std::vector<Eigen::Vector3i> triangles;
  std::string source;  ///< "box", "sphere", "cylinder" or the mesh file's path
};

/// Resolves a URDF mesh URI to an existing file, or "" when none is found (see the file comment).
/// `urdf_dir`: the URDF's directory ("" when it came from a string).
std::string resolve_mesh_uri(const std::string& uri, const std::string& urdf_dir,
                             const std::vector<std::string>& package_paths);

/// The convex hull of the vertices of every mesh in the file at `path` (node transforms applied),
/// each vertex scaled per axis by `scale`. Throws sim::InputError naming the file when it cannot
/// be read or its points span no volume.
void read_mesh_hull(const std::string& path, const Eigen::Vector3d& scale, std::vector<Eigen::Vector3d>* vertices,
                    std::vector<Eigen::Vector3i>* triangles);

/// The convex hull of `points` as a closed, outward-facing triangle mesh. Throws sim::InputError
/// (naming `what`) when they span no volume.
void convex_hull(const std::vector<Eigen::Vector3d>& points, const std::string& what,
                 std::vector<Eigen::Vector3d>* vertices, std::vector<Eigen::Vector3i>* triangles);

/// Every link's collision shapes, in the model's link order. A mesh whose file is not found (or
/// any mesh, without `read_meshes`) is left out and its URI appended to *skipped (the URDFs of ROS
/// packages name meshes a user may not have; RGBench's Piper does); a file that is found but
/// cannot be read throws sim::InputError.
std::vector<LinkShape> read_link_shapes(const urdf::ModelInterface& model, const std::string& urdf_dir,
                                        const std::vector<std::string>& package_paths,
                                        std::vector<std::string>* skipped, bool read_meshes = true);

}  // namespace gd::robot
