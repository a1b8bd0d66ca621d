#pragma once
/// \file
/// Fabric materials in SI units and the named material library read from JSON
/// (data/materials.json; format and unit conversions in docs/materials.md).

#include <map>
#include <string>
#include <vector>

#include "sim/types.h"

namespace gd::sim {

/// One fabric's mechanical parameters, SI units. Warp is uv axis 0, weft uv axis 1.
struct Material {
  std::string name;
  Real stretch_warp = 0;  ///< membrane stretch stiffness along warp, N/m
  Real stretch_weft = 0;  ///< membrane stretch stiffness along weft, N/m
  Real shear = 0;         ///< in-plane shear stiffness, N/m
  /// Flexural rigidity per unit width, N·m/rad, of a strip whose long side runs along the warp
  /// (curvature along warp; ASTM D1388 "warp" specimen).
  Real bend_warp = 0;
  Real bend_weft = 0;  ///< the same for a strip along the weft, N·m/rad
  Real density = 0;    ///< areal density, kg/m²
  Real thickness = 0;  ///< m
  Real friction = 0;   ///< cloth-cloth Coulomb friction coefficient
  /// κn, 1/m: bending moment = G κ (1 + (κ/κn)²), so at κ = κn the tangent stiffness has grown
  /// by 3G (to 4G). The loader sets it to 1/thickness when the file omits it; code that builds a
  /// Material by hand must set it too.
  Real bend_kappa_n = 0;
  /// Internal friction in bending (sim/energy/bending_friction.h): the limit moment per unit
  /// width, N (half of KES's bending hysteresis 2HB), of a strip along the warp / the weft;
  /// 0 (the default): none.
  Real bend_friction_warp = 0;
  Real bend_friction_weft = 0;
  /// The change of curvature, 1/m, over which the friction moment builds up after a reversal
  /// (the friction element's spring is bend_friction / this).
  Real bend_slip_curvature = 20;

  /// Throws InputError naming the offending field: non-finite values, non-positive stiffness,
  /// density, thickness, bend_kappa_n or bend_slip_curvature, negative friction or bending friction.
  void validate() const;
};

/// Named materials. Names are case-sensitive; adding an existing name replaces it.
class MaterialLibrary {
 public:
  /// Reads a material JSON file. Throws InputError (with the path and material name) if the file
  /// is missing, not valid JSON, or a material is incomplete or invalid.
  static MaterialLibrary load(const std::string& path);
  /// load(data_dir() + "/materials.json"): the built-in fabrics.
  static MaterialLibrary load_default();

  /// Adds the materials of another file with the same schema; a name already present is
  /// replaced by the file's version.
  void merge_file(const std::string& path);
  /// Validates `m` and adds it, replacing a material of the same name.
  void add(Material m);
  /// The material called `name`; throws InputError listing the available names.
  const Material& get(const std::string& name) const;
  bool has(const std::string& name) const;
  /// All names, sorted.
  std::vector<std::string> names() const;

 private:
  std::map<std::string, Material> materials_;
};

/// `base` with some of its parameters replaced, given by the material file's field names and
/// catalogue units (docs/materials.md): stretch_g_s2, shear_g_s2, poisson, bending_g_mm2_s2_rad,
/// areal_density_g_m2, thickness_mm, friction, bend_kappa_n_per_m, bending_2hb_gf_cm_cm,
/// bend_slip_curvature_per_m (one number sets warp and weft alike). A new stretch or poisson derives the shear again (from the poisson given, else
/// 0.35) unless shear_g_s2 is given too;
/// a new thickness resets κn to 1/thickness unless bend_kappa_n_per_m is given. The result is
/// named "<base> with params". Throws InputError naming an unknown parameter or an invalid value.
Material with_catalogue_params(const Material& base, const std::map<std::string, double>& params);

/// The data directory: $GD_DATA_DIR when set and non-empty, else the build's source data/
/// directory (the compile-time GD_DEFAULT_DATA_DIR).
std::string data_dir();

}  // namespace gd::sim
