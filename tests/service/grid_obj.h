#pragma once
/// A flat nx x 8 grid of triangles 3 cm apart (nx = 12: 0.33 m x 0.21 m, centred on y = 0) as
/// Wavefront OBJ text: an upload for the service tests.

#include <sstream>
#include <string>

namespace gd::service::testing {

inline std::string grid_obj(int nx = 12) {
  std::ostringstream o;
  const int ny = 8;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) o << "v " << 0.03 * i << " " << 0.03 * j - 0.105 << " 0\n";
  for (int j = 0; j + 1 < ny; ++j)
    for (int i = 0; i + 1 < nx; ++i) {
      const int a = j * nx + i + 1, b = a + 1, c = a + nx, d = c + 1;
      o << "f " << a << " " << b << " " << d << "\nf " << a << " " << d << " " << c << "\n";
    }
  return o.str();
}

}  // namespace gd::service::testing
