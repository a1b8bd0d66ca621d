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
  std::vector<double> mass;  ///< per sample: the mass its barrier is scaled by, kg (its corners' mean)
  double spacing = 0;        ///< m, what they were built for (0: none)
  int size() const { return static_cast<int>(tri.size()); }
};

/// Samples at most `spacing` (m, > 0) apart over the triangles `tris` of the mesh at positions x
/// (3 per vertex) whose longest edge L is longer than `wider_than` (m, >= 0; a collider that thick
/// cannot pass between the vertices of a narrower one): such a triangle gets the interior points of
/// its subdivision into k = ceil(L / spacing) parts per edge (barycentric (i, j, k - i - j) / k, all
/// three > 0), and each of its edges longer than the spacing its own interior points
/// (ceil(len / spacing) parts), on the first such triangle that holds it. k is capped at
/// kMaxSampleDivisions (a sliver longer than that many spacings is sampled coarser). A sample's
/// barrier is scaled by the mean of its corners' masses (`vertex_mass`, kg, one per vertex), as
/// stiff as theirs: a pad pressing on samples alone, between the vertices of a coarse triangle,
/// pushes the cloth as it would by its vertices (scaled by the area a sample stands for, a
/// sixtieth of a vertex's on a 2 cm mesh, a pad stalled on a pinned sheet or pressed the samples to
/// within a micrometre). The vertices themselves are not samples. Throws InputError for a spacing
/// that is not a positive finite number, a negative or non-finite `wider_than`, a mass per vertex
/// missing or not positive and finite, or a bad index.
SurfaceSamples sample_surface(const std::vector<double>& x, const std::vector<int>& tris,
                              const std::vector<double>& vertex_mass, double spacing, double wider_than = 0);

/// The most parts sample_surface cuts one edge into.
inline constexpr int kMaxSampleDivisions = 12;

}  // namespace gd::sim
