#pragma once
/// \file
/// Sewing a flat pattern into a simulation mesh: every curve is sampled once (so both sides of a
/// seam get the same vertices), every panel is meshed with CGAL, the panels are merged at their
/// shared curves and lifted to their layer heights.

#include "garments/garment.h"
#include "garments/pattern.h"

namespace gd::garments {

/// Meshes and sews `pattern` at vertex spacing `spacing` (m). Heights: with two layers the back
/// panels lie at z = 0, the front ones at z = layer_gap and vertices on curves shared by a front
/// and a back panel (the seams joining the layers) at z = layer_gap / 2; a single-layer pattern
/// lies at z = 0. Returns the garment in layout coordinates (mesh with per-corner pattern uvs,
/// creases, elastic edges; seams; panels); landmarks, length and width are left to the caller.
/// The mesh passes sim::validate_mesh. Constrained segments the mesher split are added to the
/// curve's sampling and the affected panels are meshed again until no seam is split.
Garment sew_pattern(Pattern pattern, Real spacing, Real layer_gap);

}  // namespace gd::garments
