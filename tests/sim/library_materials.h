#pragma once
/// \file
/// Fabrics of the project's material library (data/materials.json) for tests that need a real one.

#include "sim/material.h"

namespace gd::sim::test {

/// The library's cotton (the paper's woven cotton).
inline Material cotton() { return MaterialLibrary::load_default().get("cotton"); }

}  // namespace gd::sim::test
