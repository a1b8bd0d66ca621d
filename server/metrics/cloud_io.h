#pragma once
/// \file
/// Point clouds for the sim-to-real metrics: the container and readers/writers for PCD (ascii,
/// binary and binary_compressed, as Open3D and PCL write them), PLY and OBJ vertices. Units are
/// whatever the file holds (RGBench: metres). PCL is used inside the .cpp only.

#include <Eigen/Core>
#include <string>
#include <vector>

namespace gd::metrics {

/// An unordered point set (or a mesh's vertices in index order, which sim_stab relies on).
using Cloud = std::vector<Eigen::Vector3f>;

/// Loads the points of a .pcd, .ply or .obj file (extension, case-insensitive, decides; OBJ: the
/// `v` lines in order, faces ignored). Fields x, y, z may be float32 or float64; other fields
/// (rgb, normals) are ignored. Non-finite points (Open3D PCDs can hold NaN) are dropped and
/// counted in one log line. Throws InputError naming the file when it is missing, has an unknown
/// extension, cannot be parsed or has no x/y/z fields.
Cloud load_cloud(const std::string& path);

/// PCD encodings.
enum class PcdEncoding { kAscii, kBinary, kBinaryCompressed };

/// Writes `cloud` as a PCD v0.7 file with float fields x y z. Throws InputError if it cannot be
/// written.
void save_pcd(const std::string& path, const Cloud& cloud, PcdEncoding encoding);
/// Same, binary (the default, as Open3D writes) or ascii.
void save_pcd(const std::string& path, const Cloud& cloud, bool binary = true);

/// Writes `cloud` as a PLY file with a single `vertex` element of float x y z, binary little
/// endian or ascii. Throws InputError if it cannot be written.
void save_ply(const std::string& path, const Cloud& cloud, bool binary = true);

/// Applies a rigid (or any affine) 4x4 transform to every point, in double precision.
Cloud transform_cloud(const Cloud& cloud, const Eigen::Matrix4d& T);

}  // namespace gd::metrics
