#include "array_files.h"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "metrics/cloud_io.h"
#include "sim/demand.h"

namespace gd::cli {

namespace {

static_assert(std::endian::native == std::endian::little, "the .npy writer assumes a little-endian host");

std::string lower_extension(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

void write_npy(const std::string& path, const std::vector<float>& positions) {
  std::string header = "{'descr': '<f4', 'fortran_order': False, 'shape': (" +
                       std::to_string(positions.size() / 3) + ", 3), }";
  // Magic (6) + version (2) + header length (2) + header, padded with spaces to a multiple of 64
  // and ended by a newline (NumPy format 1.0).
  const size_t unpadded = 10 + header.size() + 1;
  header.append((64 - unpadded % 64) % 64, ' ');
  header.push_back('\n');
  std::string out = "\x93NUMPY";
  out.push_back('\x01');
  out.push_back('\x00');
  out.push_back(static_cast<char>(header.size() & 0xFF));
  out.push_back(static_cast<char>(header.size() >> 8));
  out += header;
  out.append(reinterpret_cast<const char*>(positions.data()), positions.size() * sizeof(float));
  write_file(path, out);
}

}  // namespace

void write_positions(const std::string& path, const std::vector<float>& positions) {
  if (positions.size() % 3 != 0)
    throw sim::InputError("positions hold " + std::to_string(positions.size()) + " floats, not 3 per vertex");
  const std::string ext = lower_extension(path);
  if (ext == ".npy") {
    write_npy(path, positions);
  } else if (ext == ".ply") {
    metrics::Cloud cloud(positions.size() / 3);
    for (size_t i = 0; i < cloud.size(); ++i)
      cloud[i] = Eigen::Vector3f(positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]);
    const auto parent = std::filesystem::path(path).parent_path();
    if (!parent.empty()) std::filesystem::create_directories(parent);
    metrics::save_ply(path, cloud);
  } else {
    throw sim::InputError("cannot write positions to '" + path + "': use a .npy or .ply file name");
  }
}

void write_file(const std::string& path, const std::string& data) {
  const auto parent = std::filesystem::path(path).parent_path();
  std::error_code ec;
  if (!parent.empty()) std::filesystem::create_directories(parent, ec);
  std::ofstream f(path, std::ios::binary);
  f.write(data.data(), static_cast<std::streamsize>(data.size()));
  if (!f) throw sim::InputError("cannot write '" + path + "'");
}

std::string read_file(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  if (!f) throw sim::InputError("cannot read '" + path + "'");
  std::ostringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

}  // namespace gd::cli
