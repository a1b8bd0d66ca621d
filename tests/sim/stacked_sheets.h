#pragma once
// Two sheets stacked for self-contact tests: a square grid at height z and a copy of it shifted
// by `offset` (its z the gap above the first), with the same pattern coordinates.
#include <Eigen/Core>

#include "sim/mesh.h"

namespace gd::sim::test {

inline Mesh stacked_sheets(Real size, Real spacing, Real z, const Vec3& offset) {
  const Mesh bottom = make_rect(size, size, spacing);
  Mesh m = bottom;
  const int nb = static_cast<int>(bottom.x.size());
  for (Vec3& p : m.x) p.z() = z;
  for (int i = 0; i < nb; ++i) {
    m.x.push_back(bottom.x[i] + offset);
    m.uv.push_back(bottom.uv[i]);
  }
  for (const auto& t : bottom.tris) m.tris.emplace_back(t + Eigen::Vector3i::Constant(nb));
  return m;
}

}  // namespace gd::sim::test
