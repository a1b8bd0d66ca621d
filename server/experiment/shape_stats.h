#pragma once
/// \file
/// The cloth's shape at one instant, summed up for summary.json's `initial` and `final` and the
/// timeseries: heights and extents, each vertex weighted by its lumped mass.

#include <vector>

#include "sim/types.h"

namespace gd::experiment {

/// Heights (m, world z) and horizontal extents (m) of the cloth. The mean and the 95th percentile
/// weigh each vertex by its lumped mass (the cloth's area round it), so that they are the cloth's,
/// not its vertices': a garment refined in one place (`--refine-grasp` puts a few thousand vertices
/// round the grasp points) would otherwise count that place several times over.
struct ClothShape {
  double min_z = 0, max_z = 0, mean_z = 0, extent_x = 0, extent_y = 0;
  /// Height below which 95% of the cloth (by mass) lies: how tall the bulk of a folded stack is,
  /// without the one sleeve tip that max_z follows.
  double p95_z = 0;
};

/// The shape of positions x, mass: one lumped mass per vertex (SceneData::mass, kg; any
/// positive weights). All zero for an empty x; aborts if the sizes differ.
ClothShape shape_of(const std::vector<sim::Vec3>& x, const std::vector<double>& mass);

}  // namespace gd::experiment
