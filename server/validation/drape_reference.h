#pragma once
/// \file
/// The Cusick drape against fabrics whose drape coefficient was measured: a reference file
/// (data/drape_reference.json: Petrak et al. 2025, six woven apparel fabrics) gives each
/// fabric's parameters in the material file's schema and its measured coefficient (and a peer
/// simulator's, CLO3D's, from the same parameters). docs/validation.md, "Drape against measured
/// fabrics".

#include <string>
#include <vector>

#include "sim/material.h"
#include "validation/cases.h"

namespace gd::validation {

/// One fabric of a drape reference file.
struct DrapeReference {
  sim::Material material;
  double measured = 0;  ///< the drape coefficient measured on the fabric
  double peer = NAN;    ///< a peer simulator's coefficient from the same parameters (NaN: none)
};

/// data_dir() + "/drape_reference.json".
std::string default_drape_reference_path();

/// Reads a drape reference file: its "materials" as a material file (MaterialLibrary::load) and
/// its "drape" array of {material, measured, clo3d}. Throws InputError naming the file and what
/// is wrong (a missing or unknown material, a coefficient outside (0, 1)).
std::vector<DrapeReference> load_drape_references(const std::string& path);

/// The reference drapes run at 5 mm, the converged spacing (docs/validation.md), with the
/// default DrapeSetup (lowered over 2 s).
constexpr double kReferenceDrapeSpacing = 0.005;

/// The drape of one reference fabric (measure_drape at kReferenceDrapeSpacing); `setup` other
/// than the default only for studies of the protocol (gd-validate --drape-waves ...).
DrapeMeasurement measure_reference_drape(const DrapeReference& r, bool self_contact, const DrapeSetup& setup = {});

/// Spearman's rank correlation of two equally long series (ties get their mean rank); NaN for
/// fewer than two values or a constant series.
double rank_correlation(const std::vector<double>& a, const std::vector<double>& b);

}  // namespace gd::validation
