#pragma once
/// \file
/// Points sampled over the cloth's triangles, held out of thin colliders as its vertices are. The
/// contact keeps a collider away from the cloth's vertices (collider.h); a gripper pad thinner than
/// the cloth's edges are long then passes between them and stands in the sheet, threaded
/// (contact/cuts.h, docs/robot.md "Pads that cut through the cloth"). Points a pad's half thickness
/// apart on every triangle and edge leave no gap a pad fits through: each is a fixed barycentric
/// combination of its triangle's three vertices, so its barrier, friction and CCD are a vertex's
/// (element_terms.h, triangle_sample_terms) mapped to the triangle by its weights, and its Hessian
/// lands in blocks the triangle already has.

#include <vector>

#include "sim/types.h"

namespace gd::sim {

/// Sample points grouped by triangle: triangle t's are [tri_ptr[t], tri_ptr[t + 1]).
struct SurfaceSamples {
  std::vector<int> tri_ptr;  ///< triangles + 1 offsets
  std::vector<int> tri;      ///< per sample: its triangle
  std::vector<double> w;     ///< per sample: 3 barycentric weights on its triangle's vertices
  std::vector<double> mass;  ///< per sample: the cloth's mass it stands for, kg (its barrier's scale)
  double spacing = 0;        ///< m, what they were built for (0: none)
  int size() const { return static_cast<int>(tri.size()); }
};

/// Samples at most `spacing` (m, > 0) apart over the triangles `tris` of the mesh at positions x
/// (3 per vertex): a triangle whose longest edge is L gets the interior points of its subdivision
/// into k = ceil(L / spacing) parts per edge (barycentric (i, j, k - i - j) / k, all three > 0), and
/// each edge longer than the spacing its own interior points (ceil(len / spacing) parts), on the
/// first triangle that holds it. k is capped at kMaxSampleDivisions (a sliver longer than that
/// many spacings is sampled coarser). A sample stands for the mass of the area around it: twice a
/// subdivision triangle's, at `density` (kg/m^2). The vertices themselves are not samples. Throws
/// InputError for a spacing or density that is not a positive finite number or a bad index.
SurfaceSamples sample_surface(const std::vector<double>& x, const std::vector<int>& tris, double density,
                              double spacing);

/// The most parts sample_surface cuts one edge into.
inline constexpr int kMaxSampleDivisions = 12;

}  // namespace gd::sim
