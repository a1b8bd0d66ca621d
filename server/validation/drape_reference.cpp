#include "validation/drape_reference.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numeric>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sim/demand.h"

namespace gd::validation {

std::string default_drape_reference_path() { return sim::data_dir() + "/drape_reference.json"; }

std::vector<DrapeReference> load_drape_references(const std::string& path) {
  const auto lib = sim::MaterialLibrary::load(path);  // the materials, checked as any material file
  std::ifstream in(path);
  nlohmann::json doc = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (!doc.contains("drape") || !doc["drape"].is_array() || doc["drape"].empty())
    throw sim::InputError(fmt::format("{}: expected a non-empty \"drape\" array of {{material, measured, clo3d}}", path));
  std::vector<DrapeReference> out;
  for (size_t i = 0; i < doc["drape"].size(); ++i) {
    const auto& e = doc["drape"][i];
    const std::string where = fmt::format("{}: drape[{}]", path, i);
    if (!e.is_object() || !e.contains("material") || !e["material"].is_string())
      throw sim::InputError(where + ": needs a \"material\" name from the file's materials");
    if (!lib.has(e["material"].get<std::string>()))
      throw sim::InputError(fmt::format("{}: material '{}' is not among the file's materials", where,
                                        e["material"].get<std::string>()));
    auto coefficient = [&](const char* key, bool required) -> double {
      if (!e.contains(key)) {
        if (required) throw sim::InputError(fmt::format("{}: missing \"{}\"", where, key));
        return NAN;
      }
      if (!e[key].is_number() || !(e[key].get<double>() > 0 && e[key].get<double>() < 1))
        throw sim::InputError(fmt::format("{}: \"{}\" must be a drape coefficient in (0, 1)", where, key));
      return e[key].get<double>();
    };
    DrapeReference r;
    r.material = lib.get(e["material"].get<std::string>());
    r.measured = coefficient("measured", true);
    r.peer = coefficient("clo3d", false);
    out.push_back(std::move(r));
  }
  return out;
}

DrapeMeasurement measure_reference_drape(const DrapeReference& r, bool self_contact, const DrapeSetup& setup) {
  return measure_drape(r.material, kReferenceDrapeSpacing, self_contact, setup);
}

namespace {
std::vector<double> ranks(const std::vector<double>& v) {
  std::vector<size_t> order(v.size());
  std::iota(order.begin(), order.end(), size_t{0});
  std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return v[a] < v[b]; });
  std::vector<double> r(v.size());
  for (size_t i = 0; i < order.size();) {
    size_t j = i;
    while (j + 1 < order.size() && v[order[j + 1]] == v[order[i]]) ++j;
    for (size_t k = i; k <= j; ++k) r[order[k]] = 0.5 * static_cast<double>(i + j) + 1;
    i = j + 1;
  }
  return r;
}
}  // namespace

double rank_correlation(const std::vector<double>& a, const std::vector<double>& b) {
  if (a.size() != b.size() || a.size() < 2) return NAN;
  const auto ra = ranks(a), rb = ranks(b);
  const double n = static_cast<double>(a.size());
  const double ma = std::accumulate(ra.begin(), ra.end(), 0.0) / n, mb = std::accumulate(rb.begin(), rb.end(), 0.0) / n;
  double sab = 0, saa = 0, sbb = 0;
  for (size_t i = 0; i < ra.size(); ++i) {
    sab += (ra[i] - ma) * (rb[i] - mb);
    saa += (ra[i] - ma) * (ra[i] - ma);
    sbb += (rb[i] - mb) * (rb[i] - mb);
  }
  if (saa == 0 || sbb == 0) return NAN;
  return sab / std::sqrt(saa * sbb);
}

}  // namespace gd::validation
