// gd-validate: runs the validation scenes and prints expected vs measured per case.
//   gd-validate            a table on stdout, progress on stderr
//   gd-validate --json     one JSON array of {name, expected, measured, rel_error, pass, ...}
//   gd-validate --only cantilever/cotton,tensile     cases whose name contains any of these
//   gd-validate --urdf piper_with_gripper.urdf --only robot    robot mode's cases (robot/fk, robot/pinch/*)
//   gd-validate --drape-spacings 0.0075,0.005 [--drape-fabric cotton]
//                          the Cusick drape at each mesh spacing (m), with and without self-contact
//   gd-validate --drape-reference [--drape-reference-file F]   the drape of fabrics measured in the
//                          literature (data/drape_reference.json) against their measured coefficients
// Exit status 0 when every case passes, 1 otherwise.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <sstream>

#include "sim/demand.h"
#include "sim/log.h"
#include "validation/cases.h"
#include "validation/drape_reference.h"

namespace {

std::vector<std::string> split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  for (std::string item; std::getline(ss, item, ',');)
    if (!item.empty()) out.push_back(item);
  return out;
}

/// A number, or null where it is not finite (JSON has no NaN).
nlohmann::json num(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json to_json(const gd::validation::CaseResult& r) {
  nlohmann::json j = {{"name", r.name},           {"expected", num(r.expected)}, {"measured", num(r.measured)},
          {"rel_error", num(r.rel_error)}, {"pass", r.pass},          {"tolerance", r.tolerance},
          {"unit", r.unit},           {"vertices", r.vertices},      {"seconds", r.seconds},
          {"detail", r.detail}};
  if (r.intersections >= 0) j["intersections"] = r.intersections;
  return j;
}

/// The drape coefficient at each spacing, self-contact off and on: how far it is from converged.
int drape_study(const gd::sim::Material& m, const std::vector<std::string>& spacings, const std::string& self_contact,
                const gd::validation::DrapeSetup& setup, bool json) {
  if (self_contact != "off" && self_contact != "on" && self_contact != "both")
    throw gd::sim::InputError("--drape-self-contact: give off, on or both (got " + self_contact + ")");
  std::vector<double> hs;  // every spacing checked before any runs
  for (const std::string& text : spacings) {
    double h = NAN;
    try {
      size_t used = 0;
      h = std::stod(text, &used);
      if (used != text.size()) h = NAN;
    } catch (const std::exception&) {
    }
    if (!(h >= 0.002 && h <= 0.03))
      throw gd::sim::InputError("--drape-spacings: each spacing must lie in [0.002, 0.03] m (got " + text + ")");
    hs.push_back(h);
  }
  nlohmann::json arr = nlohmann::json::array();
  if (!json) std::printf("%-10s %8s %13s %8s %6s %13s %8s\n", "spacing_mm", "vertices", "self_contact", "DC", "nodes",
                         "intersecting", "seconds");
  for (const double h : hs) {
    for (bool contact : {false, true}) {
      if (self_contact != "both" && contact != (self_contact == "on")) continue;
      const auto t0 = std::chrono::steady_clock::now();
      std::fprintf(stderr, "drape at %.2f mm, self-contact %s ...\n", h * 1e3, contact ? "on" : "off");
      const auto d = gd::validation::measure_drape(m, h, contact, setup);
      const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      arr.push_back({{"spacing", h}, {"vertices", d.vertices}, {"self_contact", contact}, {"coefficient", num(d.coefficient)},
                     {"nodes", d.nodes}, {"intersecting_pairs", d.intersections}, {"seconds", sec}});
      if (!json)
        std::printf("%-10.2f %8d %13s %8.3f %6d %13d %8.1f\n", h * 1e3, d.vertices, contact ? "on" : "off", d.coefficient,
                    d.nodes, d.intersections, sec);
      std::fflush(stdout);
    }
  }
  if (json) std::printf("%s\n", arr.dump(2).c_str());
  return 0;
}

/// Each fabric of a drape reference file draped as it was measured; the simulated coefficient
/// beside the measured one and the peer's.
int drape_reference_study(const std::string& path, bool self_contact, const gd::validation::DrapeSetup& setup,
                          bool json) {
  const auto refs = gd::validation::load_drape_references(path);
  nlohmann::json arr = nlohmann::json::array();
  if (!json)
    std::printf("%-40s %8s %8s %9s %6s %13s %8s\n", "fabric", "measured", "clo3d", "simulated", "nodes", "intersecting",
                "seconds");
  std::vector<double> measured, simulated;
  double worst = 0;
  for (size_t i = 0; i < refs.size(); ++i) {
    const auto& r = refs[i];
    const auto t0 = std::chrono::steady_clock::now();
    std::fprintf(stderr, "[%zu/%zu] drape of %s (5 mm, self-contact %s) ...\n", i + 1, refs.size(),
                 r.material.name.c_str(), self_contact ? "on" : "off");
    const auto d = gd::validation::measure_reference_drape(r, self_contact, setup);
    const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    measured.push_back(r.measured);
    simulated.push_back(d.coefficient);
    worst = std::max(worst, std::abs(d.coefficient - r.measured));
    arr.push_back({{"material", r.material.name}, {"measured", r.measured}, {"clo3d", num(r.peer)},
                   {"simulated", num(d.coefficient)}, {"nodes", d.nodes}, {"intersecting_pairs", d.intersections},
                   {"vertices", d.vertices}, {"self_contact", self_contact}, {"seconds", sec}});
    if (!json)
      std::printf("%-40s %8.3f %8.3f %9.3f %6d %13d %8.1f\n", r.material.name.c_str(), r.measured, r.peer,
                  d.coefficient, d.nodes, d.intersections, sec);
    std::fflush(stdout);
  }
  const double rho = gd::validation::rank_correlation(simulated, measured);
  if (json)
    std::printf("%s\n", nlohmann::json{{"fabrics", arr}, {"rank_correlation", num(rho)}, {"largest_error", num(worst)}}
                             .dump(2)
                             .c_str());
  else
    std::printf("rank correlation (Spearman) simulated vs measured %.3f, largest |simulated - measured| %.3f\n", rho,
                worst);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"GarmentDynamics validation scenes: cantilever (ASTM D1388), tensile, hang, drop, slide, Cusick drape, "
               "friction, self-contact, robot mode (with --urdf)"};
  bool json = false;
  std::string only, materials;
  app.add_flag("--json", json, "print one JSON array and nothing else on stdout");
  app.add_option("--only", only, "comma-separated name filters (substring match)");
  app.add_option("--materials", materials, "extra material file (JSON) merged into the library");
  std::string urdf;
  app.add_option("--urdf", urdf,
                 "robot arms' URDF (RGBench's piper_with_gripper.urdf): adds the robot/fk and robot/pinch/<fabric> "
                 "cases (--only robot runs just those)")
      ->check(CLI::ExistingFile);
  std::string drape_spacings, drape_fabric = "cotton";
  app.add_option("--drape-spacings", drape_spacings,
                 "comma-separated mesh spacings (m): run only the Cusick drape at each, with and without self-contact");
  app.add_option("--drape-fabric", drape_fabric, "fabric of --drape-spacings")->capture_default_str();
  std::string drape_self_contact;  // --drape-spacings: both; --drape-reference: off
  gd::validation::DrapeSetup drape_setup;
  app.add_option("--drape-self-contact", drape_self_contact,
                 "off, on or both: --drape-spacings runs both unless told, --drape-reference off (at 5 mm the folds "
                 "do not touch: docs/validation.md)");
  bool drape_reference = false;
  std::string drape_reference_file;
  app.add_flag("--drape-reference", drape_reference,
               "run only the Cusick drape of each fabric in the drape reference file and compare it with the "
               "measured coefficient");
  app.add_option("--drape-reference-file", drape_reference_file,
                 "drape reference file (default: the data directory's drape_reference.json, Petrak et al. 2025); "
                 "implies --drape-reference");
  app.add_option("--drape-waves", drape_setup.waves, "periods of the ripple that seeds the folds round the rim")
      ->check(CLI::Range(2, 30))
      ->capture_default_str();
  app.add_option("--drape-gravity-ramp", drape_setup.gravity_ramp,
                 "s over which gravity grows to full before the settling (0: dropped at once)")
      ->check(CLI::Range(0.0, 20.0))
      ->capture_default_str();
  app.add_option("--drape-settle", drape_setup.settle, "s of settling under full gravity before the relaxation")
      ->check(CLI::Range(0.0, 20.0))
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  try {
    auto lib = gd::sim::MaterialLibrary::load_default();
    if (!materials.empty()) lib.merge_file(materials);
    if (!drape_reference_file.empty()) drape_reference = true;
    // The drape's own options mean nothing to the other cases: refused there, not ignored.
    if (!drape_reference && drape_spacings.empty())
      for (const char* flag : {"--drape-self-contact", "--drape-waves", "--drape-gravity-ramp", "--drape-settle"})
        if (app.count(flag) > 0)
          throw gd::sim::InputError(std::string(flag) + " applies to --drape-spacings or --drape-reference only");
    if (drape_reference) {
      if (drape_self_contact != "" && drape_self_contact != "off" && drape_self_contact != "on")
        throw gd::sim::InputError("--drape-reference: --drape-self-contact is off or on (got " + drape_self_contact + ")");
      return drape_reference_study(
          drape_reference_file.empty() ? gd::validation::default_drape_reference_path() : drape_reference_file,
          drape_self_contact == "on", drape_setup, json);
    }
    if (!drape_spacings.empty())
      return drape_study(lib.get(drape_fabric), split(drape_spacings),
                         drape_self_contact.empty() ? "both" : drape_self_contact, drape_setup, json);
    const auto filters = split(only);
    auto keep = [&](const std::string& name) {
      if (filters.empty()) return true;
      for (const auto& f : filters)
        if (name.find(f) != std::string::npos) return true;
      return false;
    };
    std::vector<gd::validation::CaseResult> results;
    // run_all decides the cases; filtered ones are skipped by running cases lazily here.
    const auto all = gd::validation::case_list(lib, urdf);
    int total = 0;
    for (const auto& c : all) total += keep(c.name);
    if (total == 0 && urdf.empty() && only.find("robot") != std::string::npos)
      throw gd::sim::InputError("the robot cases need the arms' URDF: give --urdf PATH (RGBench's piper_with_gripper.urdf)");
    int done = 0;
    for (const auto& c : all) {
      if (!keep(c.name)) continue;
      std::fprintf(stderr, "[%d/%d] %s ...\n", ++done, total, c.name.c_str());
      results.push_back(c.run());
      const auto& r = results.back();
      std::fprintf(stderr, "        %s in %.1f s\n", r.pass ? "pass" : "FAIL", r.seconds);
    }
    bool all_pass = true;
    for (const auto& r : results) all_pass = all_pass && r.pass;
    if (json) {
      nlohmann::json arr = nlohmann::json::array();
      for (const auto& r : results) arr.push_back(to_json(r));
      std::printf("%s\n", arr.dump(2).c_str());
    } else {
      std::printf("%-24s %14s %14s %10s %6s  %s\n", "case", "expected", "measured", "rel_error", "pass", "detail");
      for (const auto& r : results)
        std::printf("%-24s %14.6g %14.6g %10.4f %6s  %s\n", r.name.c_str(), r.expected, r.measured, r.rel_error,
                    r.pass ? "yes" : "NO", r.detail.c_str());
      std::printf("%zu cases, %s\n", results.size(), all_pass ? "all pass" : "FAILURES");
    }
    return all_pass ? 0 : 1;
  } catch (const gd::sim::InputError& e) {
    std::fprintf(stderr, "gd-validate: %s\n", e.what());
    return 2;
  }
}
