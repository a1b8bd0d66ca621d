#pragma once
/// \file
/// Writing a scene's positions (N*3 float32, as gd::Client returns them) for `gd step --out`.

#include <string>
#include <vector>

namespace gd::cli {

/// Writes `positions` (x y z per vertex) to `path`: .npy (float32, shape (N, 3), NumPy format
/// 1.0) or .ply (binary vertex cloud). Throws gd::sim::InputError for another extension, a
/// length that is not a multiple of 3, or a file that cannot be written.
void write_positions(const std::string& path, const std::vector<float>& positions);

/// Writes `data` to `path` as is, creating missing parent directories. Throws InputError.
void write_file(const std::string& path, const std::string& data);

/// The whole content of `path`. Throws InputError naming the file if it cannot be read.
std::string read_file(const std::string& path);

}  // namespace gd::cli
