#include "sim/material.h"

#include <spdlog/fmt/fmt.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>

#include "sim/demand.h"

namespace gd::sim {
namespace {

using nlohmann::json;

// Catalogue units -> SI (see docs/materials.md).
constexpr Real kGramPerS2 = 1e-3;         // g/s² -> N/m
constexpr Real kGramMm2PerS2 = 1e-9;      // g·mm²/s² -> N·m
constexpr Real kGramPerM2 = 1e-3;         // g/m² -> kg/m²
constexpr Real kMillimetre = 1e-3;        // mm -> m
constexpr Real kDefaultPoisson = 0.35;    // RGBench cloth configs
constexpr Real kDefaultFriction = 0.266;  // RGBench's fitted ground_friction
constexpr Real kGramForceCmPerCm = 9.80665e-3;  // gf·cm/cm (KES 2HB) -> N·m/m = N

// The fields a material entry may have (docs/materials.md).
const std::set<std::string> kKeys{
    "name", "notes", "source", "stretch_g_s2", "shear_g_s2", "poisson", "bending_g_mm2_s2_rad",
    "areal_density_g_m2", "thickness_mm", "friction", "bend_kappa_n_per_m", "bending_2hb_gf_cm_cm",
    "bend_slip_curvature_per_m"};

/// Reads one material entry; `where` prefixes error messages ("file: material 'x'").
class EntryReader {
 public:
  EntryReader(const json& j, std::string where) : j_(j), where_(std::move(where)) {}

  bool has(const char* key) const { return j_.contains(key); }

  Real number(const char* key) const { return as_number(at(key), key); }

  /// A per-direction value: {"warp": a, "weft": b}, or one number for both directions.
  std::pair<Real, Real> warp_weft(const char* key) const {
    const json& v = at(key);
    if (v.is_number()) return {v.get<Real>(), v.get<Real>()};
    if (!v.is_object() || !v.contains("warp") || !v.contains("weft") || v.size() != 2)
      throw error(
          fmt::format("field '{}' must be a number or {{\"warp\": .., \"weft\": ..}}", key));
    return {as_number(v["warp"], key), as_number(v["weft"], key)};
  }

  InputError error(const std::string& what) const { return InputError(where_ + ": " + what); }

 private:
  const json& at(const char* key) const {
    if (!j_.contains(key)) throw error(fmt::format("missing field '{}'", key));
    return j_[key];
  }
  Real as_number(const json& v, const char* key) const {
    if (!v.is_number()) throw error(fmt::format("field '{}' must be a number", key));
    return v.get<Real>();
  }

  const json& j_;
  std::string where_;
};

Material parse_material(const json& j, const std::string& path, size_t index) {
  if (!j.is_object() || !j.contains("name") || !j["name"].is_string() ||
      j["name"].get<std::string>().empty())
    throw InputError(
        fmt::format("{}: materials[{}] needs a non-empty \"name\" string", path, index));
  Material m;
  m.name = j["name"].get<std::string>();
  const EntryReader r(j, fmt::format("{}: material '{}'", path, m.name));
  for (const auto& [key, value] : j.items()) {
    if (!kKeys.contains(key))
      throw r.error(fmt::format("unknown field '{}' (see docs/materials.md for the schema)", key));
  }
  const auto [sw, sf] = r.warp_weft("stretch_g_s2");
  const auto [bw, bf] = r.warp_weft("bending_g_mm2_s2_rad");
  m.stretch_warp = sw * kGramPerS2;
  m.stretch_weft = sf * kGramPerS2;
  if (r.has("shear_g_s2") && r.has("poisson"))
    throw r.error("give either 'shear_g_s2' or 'poisson' (to derive the shear), not both");
  if (r.has("shear_g_s2")) {
    m.shear = r.number("shear_g_s2") * kGramPerS2;
  } else {
    const Real nu = r.has("poisson") ? r.number("poisson") : kDefaultPoisson;
    if (!(nu > -1 && nu < 0.5))
      throw r.error(fmt::format("poisson must lie in (-1, 0.5), got {}", nu));
    m.shear = m.stretch_warp / (2 * (1 + nu));
  }
  m.bend_warp = bw * kGramMm2PerS2;
  m.bend_weft = bf * kGramMm2PerS2;
  m.density = r.number("areal_density_g_m2") * kGramPerM2;
  m.thickness = r.number("thickness_mm") * kMillimetre;
  m.friction = r.has("friction") ? r.number("friction") : kDefaultFriction;
  m.bend_kappa_n = r.has("bend_kappa_n_per_m") ? r.number("bend_kappa_n_per_m") : 1 / m.thickness;
  if (r.has("bending_2hb_gf_cm_cm")) {  // KES 2HB: the loop's width, twice the friction moment
    const auto [hw, hf] = r.warp_weft("bending_2hb_gf_cm_cm");
    m.bend_friction_warp = 0.5 * hw * kGramForceCmPerCm;
    m.bend_friction_weft = 0.5 * hf * kGramForceCmPerCm;
  }
  if (r.has("bend_slip_curvature_per_m")) m.bend_slip_curvature = r.number("bend_slip_curvature_per_m");
  try {
    m.validate();
  } catch (const InputError& e) {
    throw InputError(fmt::format("{}: {}", path, e.what()));
  }
  return m;
}

std::vector<Material> read_file(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw InputError(fmt::format("cannot open material file '{}'", path));
  json doc;
  try {
    doc = json::parse(in);
  } catch (const json::exception& e) {
    throw InputError(fmt::format("{}: not valid JSON: {}", path, e.what()));
  }
  if (!doc.is_object() || !doc.contains("materials") || !doc["materials"].is_array())
    throw InputError(fmt::format("{}: expected an object with a \"materials\" array", path));
  std::vector<Material> out;
  std::set<std::string> seen;
  for (size_t i = 0; i < doc["materials"].size(); ++i) {
    out.push_back(parse_material(doc["materials"][i], path, i));
    if (!seen.insert(out.back().name).second)
      throw InputError(fmt::format("{}: material '{}' is defined twice", path, out.back().name));
  }
  return out;
}

}  // namespace

Material with_catalogue_params(const Material& base, const std::map<std::string, double>& params) {
  json j;  // base as a material file entry, then the parameters over it
  j["name"] = fmt::format("{} with params", base.name);
  j["stretch_g_s2"] = {{"warp", base.stretch_warp / kGramPerS2}, {"weft", base.stretch_weft / kGramPerS2}};
  j["shear_g_s2"] = base.shear / kGramPerS2;
  j["bending_g_mm2_s2_rad"] = {{"warp", base.bend_warp / kGramMm2PerS2}, {"weft", base.bend_weft / kGramMm2PerS2}};
  j["areal_density_g_m2"] = base.density / kGramPerM2;
  j["thickness_mm"] = base.thickness / kMillimetre;
  j["friction"] = base.friction;
  j["bend_kappa_n_per_m"] = base.bend_kappa_n;
  j["bending_2hb_gf_cm_cm"] = {{"warp", 2 * base.bend_friction_warp / kGramForceCmPerCm},
                               {"weft", 2 * base.bend_friction_weft / kGramForceCmPerCm}};
  j["bend_slip_curvature_per_m"] = base.bend_slip_curvature;
  for (const auto& [key, value] : params) {
    if (!kKeys.contains(key) || key == "name" || key == "notes" || key == "source")
      throw InputError(fmt::format("unknown material parameter '{}'; use stretch_g_s2, shear_g_s2, poisson, "
                                   "bending_g_mm2_s2_rad, areal_density_g_m2, thickness_mm, friction, "
                                   "bend_kappa_n_per_m, bending_2hb_gf_cm_cm or bend_slip_curvature_per_m "
                                   "(docs/materials.md)",
                                   key));
    j[key] = value;
  }
  if ((params.contains("stretch_g_s2") || params.contains("poisson")) && !params.contains("shear_g_s2"))
    j.erase("shear_g_s2");
  if (params.contains("thickness_mm") && !params.contains("bend_kappa_n_per_m")) j.erase("bend_kappa_n_per_m");
  return parse_material(j, "material parameters", 0);
}

void Material::validate() const {
  const std::string who = fmt::format("material '{}'", name);
  if (name.empty()) throw InputError("material has no name");
  const std::pair<const char*, Real> positive[] = {
      {"stretch_warp", stretch_warp}, {"stretch_weft", stretch_weft}, {"shear", shear},
      {"bend_warp", bend_warp},       {"bend_weft", bend_weft},       {"density", density},
      {"thickness", thickness},       {"bend_kappa_n", bend_kappa_n}, {"bend_slip_curvature", bend_slip_curvature}};
  for (const auto& [field, v] : positive) {
    if (!(std::isfinite(v) && v > 0))
      throw InputError(fmt::format("{}: {} must be positive and finite (got {})", who, field, v));
  }
  if (!(std::isfinite(friction) && friction >= 0))
    throw InputError(fmt::format("{}: friction must be finite and >= 0 (got {})", who, friction));
  for (const auto& [field, v] : {std::pair<const char*, Real>{"bend_friction_warp (2HB/2)", bend_friction_warp},
                                 std::pair<const char*, Real>{"bend_friction_weft (2HB/2)", bend_friction_weft}}) {
    if (!(std::isfinite(v) && v >= 0))
      throw InputError(fmt::format("{}: {} must be finite and >= 0 (got {})", who, field, v));
  }
}

MaterialLibrary MaterialLibrary::load(const std::string& path) {
  MaterialLibrary lib;
  lib.merge_file(path);
  return lib;
}

MaterialLibrary MaterialLibrary::load_default() { return load(data_dir() + "/materials.json"); }

void MaterialLibrary::merge_file(const std::string& path) {
  for (Material& m : read_file(path)) materials_[m.name] = std::move(m);
}

void MaterialLibrary::add(Material m) {
  m.validate();
  std::string name = m.name;
  materials_[std::move(name)] = std::move(m);
}

const Material& MaterialLibrary::get(const std::string& name) const {
  const auto it = materials_.find(name);
  if (it == materials_.end()) {
    const std::vector<std::string> n = names();
    throw InputError(fmt::format("unknown material '{}'; available: {}", name,
                                 n.empty() ? "(none)" : fmt::format("{}", fmt::join(n, ", "))));
  }
  return it->second;
}

bool MaterialLibrary::has(const std::string& name) const { return materials_.contains(name); }

std::vector<std::string> MaterialLibrary::names() const {
  std::vector<std::string> out;
  for (const auto& [name, m] : materials_) out.push_back(name);
  return out;
}

std::string data_dir() {
  if (const char* d = std::getenv("GD_DATA_DIR"); d != nullptr && *d != '\0') return d;
  return GD_DEFAULT_DATA_DIR;
}

}  // namespace gd::sim
