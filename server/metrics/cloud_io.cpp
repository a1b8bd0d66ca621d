#include "metrics/cloud_io.h"

#include <pcl/PCLPointCloud2.h>
#include <pcl/console/print.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "sim/demand.h"
#include "sim/log.h"
#include "sim/mesh.h"

namespace gd::metrics {
namespace {

using sim::InputError;

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

/// Reads one coordinate stored as float32 or float64 at `p`.
double read_scalar(const uint8_t* p, uint8_t datatype) {
  if (datatype == pcl::PCLPointField::FLOAT64) {
    double v;
    std::memcpy(&v, p, sizeof v);
    return v;
  }
  float v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

/// Copies the x, y, z fields of a PCL blob into a Cloud (non-finite points are kept here).
Cloud xyz_from_blob(const pcl::PCLPointCloud2& blob, const std::string& path) {
  const pcl::PCLPointField* f[3] = {nullptr, nullptr, nullptr};
  const char* names[3] = {"x", "y", "z"};
  for (const auto& field : blob.fields)
    for (int k = 0; k < 3; ++k)
      if (field.name == names[k]) f[k] = &field;
  for (int k = 0; k < 3; ++k) {
    if (!f[k])
      throw InputError(fmt::format("point cloud '{}' has no '{}' field; expected fields x y z",
                                   path, names[k]));
    if (f[k]->datatype != pcl::PCLPointField::FLOAT32 &&
        f[k]->datatype != pcl::PCLPointField::FLOAT64)
      throw InputError(fmt::format(
          "point cloud '{}': field '{}' is not float32 or float64 (PCL datatype {})", path,
          names[k], int(f[k]->datatype)));
  }
  const size_t n = size_t(blob.width) * blob.height;
  const size_t need = n == 0 ? 0 : size_t(blob.height - 1) * blob.row_step + size_t(blob.width) * blob.point_step;
  if (blob.data.size() < need)
    throw InputError(fmt::format("point cloud '{}' is truncated ({} bytes of data for {} points)",
                                 path, blob.data.size(), n));
  Cloud out;
  out.reserve(n);
  for (uint32_t r = 0; r < blob.height; ++r) {
    for (uint32_t c = 0; c < blob.width; ++c) {
      const uint8_t* p = blob.data.data() + size_t(r) * blob.row_step + size_t(c) * blob.point_step;
      out.emplace_back(float(read_scalar(p + f[0]->offset, f[0]->datatype)),
                       float(read_scalar(p + f[1]->offset, f[1]->datatype)),
                       float(read_scalar(p + f[2]->offset, f[2]->datatype)));
    }
  }
  return out;
}

/// PCL maps binary PCD data without checking that the file is long enough, so a truncated file
/// would crash it: check the header's sizes against the file size first.
void check_pcd_size(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw InputError(fmt::format("cannot open point cloud file '{}'", path));
  std::string line;
  size_t point_size = 0, points = 0, width = 0, height = 1;
  bool has_points = false;
  std::vector<size_t> sizes, counts;
  while (std::getline(f, line)) {
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    if (key == "SIZE") {
      for (size_t v; ls >> v;) sizes.push_back(v);
    } else if (key == "COUNT") {
      for (size_t v; ls >> v;) counts.push_back(v);
    } else if (key == "WIDTH") {
      ls >> width;
    } else if (key == "HEIGHT") {
      ls >> height;
    } else if (key == "POINTS") {
      ls >> points;
      has_points = true;
    } else if (key == "DATA") {
      std::string kind;
      ls >> kind;
      if (kind == "ascii") return;  // PCL parses ascii line by line
      for (size_t i = 0; i < sizes.size(); ++i) point_size += sizes[i] * (i < counts.size() ? counts[i] : 1);
      if (!has_points) points = width * height;
      const auto start = f.tellg();
      f.seekg(0, std::ios::end);
      const size_t avail = size_t(f.tellg() - start);
      size_t need = points * point_size;
      if (kind == "binary_compressed") {
        need = 8;
        if (avail >= 8) {
          f.seekg(start);
          uint32_t compressed = 0;
          f.read(reinterpret_cast<char*>(&compressed), 4);
          need = 8 + size_t(compressed);
        }
      }
      if (avail < need)
        throw InputError(fmt::format("point cloud file '{}' is truncated: {} bytes of {} data "
                                     "where the header needs {}",
                                     path, avail, kind, need));
      return;
    }
  }
  throw InputError(fmt::format("point cloud file '{}' has no PCD header (no DATA line)", path));
}

Cloud load_obj_vertices(const std::string& path) {
  const sim::Mesh m = sim::read_obj(path);
  if (m.x.empty()) throw InputError(fmt::format("OBJ file '{}' has no vertices (no 'v x y z' lines)", path));
  Cloud out;
  out.reserve(m.x.size());
  for (const sim::Vec3& v : m.x) out.push_back(v.cast<float>());
  return out;
}

pcl::PointCloud<pcl::PointXYZ> to_pcl(const Cloud& cloud) {
  pcl::PointCloud<pcl::PointXYZ> pc;
  pc.resize(cloud.size());
  bool dense = true;
  for (size_t i = 0; i < cloud.size(); ++i) {
    pc[i] = pcl::PointXYZ(cloud[i].x(), cloud[i].y(), cloud[i].z());
    dense = dense && cloud[i].allFinite();
  }
  pc.width = uint32_t(cloud.size());
  pc.height = 1;
  pc.is_dense = dense;
  return pc;
}

}  // namespace

Cloud load_cloud(const std::string& path) {
  namespace fs = std::filesystem;
  // PCL's readers print warnings for harmless things (a PLY's face element); keep errors only.
  static const bool quiet = [] {
    pcl::console::setVerbosityLevel(pcl::console::L_ERROR);
    return true;
  }();
  (void)quiet;
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    throw InputError(fmt::format("point cloud file '{}' does not exist or is not a file", path));
  const std::string ext = lower_extension(path);
  Cloud raw;
  if (ext == ".obj") {
    raw = load_obj_vertices(path);
  } else if (ext == ".pcd" || ext == ".ply") {
    pcl::PCLPointCloud2 blob;
    int rc = -1;
    if (fs::file_size(path, ec) == 0) {
      rc = -1;
    } else if (ext == ".pcd") {
      check_pcd_size(path);
      pcl::PCDReader reader;
      rc = reader.read(path, blob);
    } else {
      pcl::PLYReader reader;
      rc = reader.read(path, blob);
    }
    if (rc < 0)
      throw InputError(fmt::format("cannot parse point cloud file '{}' (broken or unsupported {} "
                                   "file; PCL error code {})",
                                   path, ext, rc));
    raw = xyz_from_blob(blob, path);
  } else {
    throw InputError(fmt::format(
        "point cloud file '{}' has extension '{}'; expected .pcd, .ply or .obj", path, ext));
  }
  Cloud out;
  out.reserve(raw.size());
  for (const auto& p : raw)
    if (p.allFinite()) out.push_back(p);
  const size_t dropped = raw.size() - out.size();
  if (dropped > 0)
    gd::log().info("load_cloud: '{}': dropped {} non-finite of {} points", path, dropped,
                   raw.size());
  else
    gd::log().debug("load_cloud: '{}': {} points", path, out.size());
  return out;
}

void save_pcd(const std::string& path, const Cloud& cloud, PcdEncoding encoding) {
  const auto pc = to_pcl(cloud);
  pcl::PCDWriter writer;
  int rc = 0;
  if (cloud.empty()) {
    // PCL refuses to write empty clouds; write the header by hand.
    std::ofstream f(path);
    f << "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n"
         "TYPE F F F\nCOUNT 1 1 1\nWIDTH 0\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 0\n"
         "DATA ascii\n";
    rc = f ? 0 : -1;
  } else {
    switch (encoding) {
      case PcdEncoding::kAscii: rc = writer.writeASCII(path, pc, 9); break;
      case PcdEncoding::kBinary: rc = writer.writeBinary(path, pc); break;
      case PcdEncoding::kBinaryCompressed: rc = writer.writeBinaryCompressed(path, pc); break;
    }
  }
  if (rc < 0) throw InputError(fmt::format("cannot write PCD file '{}'", path));
}

void save_pcd(const std::string& path, const Cloud& cloud, bool binary) {
  save_pcd(path, cloud, binary ? PcdEncoding::kBinary : PcdEncoding::kAscii);
}

void save_ply(const std::string& path, const Cloud& cloud, bool binary) {
  std::ofstream f(path, std::ios::binary);
  if (!f) throw InputError(fmt::format("cannot write PLY file '{}'", path));
  f << "ply\nformat " << (binary ? "binary_little_endian" : "ascii")
    << " 1.0\ncomment written by GarmentDynamics gd_metrics\nelement vertex " << cloud.size()
    << "\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
  if (binary) {
    static_assert(std::endian::native == std::endian::little, "binary PLY writer assumes LE");
    for (const auto& p : cloud) f.write(reinterpret_cast<const char*>(p.data()), 3 * sizeof(float));
  } else {
    for (const auto& p : cloud) f << fmt::format("{} {} {}\n", p.x(), p.y(), p.z());
  }
  if (!f) throw InputError(fmt::format("error while writing PLY file '{}'", path));
}

Cloud transform_cloud(const Cloud& cloud, const Eigen::Matrix4d& T) {
  const Eigen::Matrix3d R = T.topLeftCorner<3, 3>();
  const Eigen::Vector3d t = T.topRightCorner<3, 1>();
  Cloud out(cloud.size());
  for (size_t i = 0; i < cloud.size(); ++i)
    out[i] = (R * cloud[i].cast<double>() + t).cast<float>();
  return out;
}

}  // namespace gd::metrics
