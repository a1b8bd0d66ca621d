/// \file
/// gd-bench's scenes (make_bench_scene) and `gd-bench export` (scene_export.h).

#include "scene_export.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <stdexcept>

#include "sim/scene.h"
#include "sim/types.h"

namespace gd::bench {

using gd::sim::Mesh;
using gd::sim::Real;
using gd::sim::Vec2;
using gd::sim::Vec3;

Mesh square_with_about(Real side, int target) {
  // make_rect: about side/dx columns and side/(dx √3/2) rows, so N ≈ side² · 2/(√3 dx²).
  Real dx = side * std::sqrt(2.0 / (std::sqrt(3.0) * target));
  Mesh m = gd::sim::make_rect(side, side, dx);
  const double ratio = static_cast<double>(m.x.size()) / target;
  if (std::abs(ratio - 1.0) > 0.02) m = gd::sim::make_rect(side, side, dx * std::sqrt(ratio));
  return m;
}

namespace {

std::vector<int> corner_vertices(const Mesh& m, Real side, Real radius) {
  const Vec3 a(0, side, 0), b(side, side, 0);
  return gd::sim::vertices_where(m, [&](const Vec3& p) {
    const Vec3 q(p.x(), p.y(), 0);
    return (q - a).norm() <= radius + 1e-12 || (q - b).norm() <= radius + 1e-12;
  });
}

nlohmann::json vec3_json(const Vec3& v) { return nlohmann::json::array({v.x(), v.y(), v.z()}); }

nlohmann::json flat_json(const std::vector<Vec3>& xs) {
  std::vector<double> out;
  out.reserve(3 * xs.size());
  for (const Vec3& p : xs) out.insert(out.end(), {p.x(), p.y(), p.z()});
  return out;
}

void write_text(const std::filesystem::path& path, const std::string& text) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot open '" + path.string() + "' for writing");
  out << text << '\n';
  out.close();
  if (!out) throw std::runtime_error("failed to write '" + path.string() + "'");
}

}  // namespace

BenchScene make_bench_scene(int target, Real side, bool contact) {
  BenchScene s;
  s.contact = contact;
  s.name = (contact ? "fold/" : "drape/") + std::to_string(target);
  s.mesh = square_with_about(side, target);
  for (auto& p : s.mesh.x) {
    if (!contact) {
      p.z() = 0.6;
    } else if (p.x() > 0.5 * side) {
      p = Vec3(side - p.x(), p.y(), 0.014);
    } else {
      p.z() = 0.01;
    }
  }
  if (!contact) s.pins = corner_vertices(s.mesh, side, 0.01);
  return s;
}

int parse_vertex_count(const std::string& text) {
  std::size_t pos = 0;
  long v = 0;
  try {
    v = std::stol(text, &pos);
  } catch (const std::exception&) {
    return -1;
  }
  return text.empty() || pos != text.size() || v < 4 || v > 100000000 ? -1 : static_cast<int>(v);
}

void parse_case(const std::string& name, bool& contact, int& target) {
  const auto slash = name.find('/');
  const std::string kind = name.substr(0, slash);
  if (slash == std::string::npos || (kind != "drape" && kind != "fold"))
    throw std::invalid_argument("case '" + name + "' is not drape/<N> or fold/<N>");
  const std::string num = name.substr(slash + 1);
  const int v = parse_vertex_count(num);
  if (v < 0) throw std::invalid_argument("case '" + name + "': '" + num + "' is not a vertex count (integer >= 4)");
  contact = kind == "fold";
  target = v;
}

void export_case(const ExportOptions& o) {
  bool contact = false;
  int target = 0;
  parse_case(o.case_name, contact, target);
  if (o.out_dir.empty()) throw std::invalid_argument("export: no output directory");
  const std::filesystem::path dir(o.out_dir);
  std::filesystem::create_directories(dir);

  const BenchScene s = make_bench_scene(target, o.side, contact);
  const Mesh& m = s.mesh;
  const auto lib = gd::sim::MaterialLibrary::load_default();
  const gd::sim::Material& mat = lib.get(o.material);
  gd::sim::SceneOptions opt = o.options;  // gd-bench's solver flags, self-contact per case
  opt.self_contact = contact;
  opt.validate();
  gd::sim::validate_mesh(m);

  // Rest shape: the pattern coordinates (SceneOptions::rest_from_uv, make_rect sets uv = (x, y)),
  // i.e. the flat square, also for fold/<N> whose initial shape is folded.
  std::vector<Vec3> rest(m.x.size());
  for (std::size_t i = 0; i < m.x.size(); ++i) rest[i] = Vec3(m.uv[i].x(), m.uv[i].y(), 0);
  // Lumped mass, as the solver builds it (scene_data.cpp): density x rest area / 3 per corner.
  std::vector<double> mass(m.x.size(), 0.0);
  double area = 0;
  for (const auto& t : m.tris) {
    const Vec2 a = m.uv[t[1]] - m.uv[t[0]], b = m.uv[t[2]] - m.uv[t[0]];
    const double A = 0.5 * std::abs(a.x() * b.y() - a.y() * b.x());
    area += A;
    for (int k = 0; k < 3; ++k) mass[t[k]] += mat.density * A / 3.0;
  }

  gd::sim::write_obj(m, {}, (dir / "mesh.obj").string());
  Mesh flat = m;
  flat.x = rest;
  gd::sim::write_obj(flat, {}, (dir / "rest.obj").string());

  // Continuum parameters a shell/FEM peer takes. The material's stretch (N/m) is E·t of a
  // membrane; its shear stiffness (N/m) is G·t = E·t / (2 (1 + nu)), so nu follows from
  // stretch / shear (0.35 for the library's fabrics, whose shear is derived with nu = 0.35).
  // The flexural rigidity of a Kirchhoff plate is D = E t³ / (12 (1 - nu²)); with E = stretch / t
  // it is 2.3x cotton's measured bending, so the shell-equivalent pair (t_eq, E_eq) matches
  // stretch (E_eq t_eq) and bending (D) at once.
  const double stretch = 0.5 * (mat.stretch_warp + mat.stretch_weft);
  const double bend = std::sqrt(mat.bend_warp * mat.bend_weft);
  const double nu = std::clamp(stretch / (2.0 * mat.shear) - 1.0, 0.0, 0.49);
  const double young = stretch / mat.thickness;
  const double t_eq = std::sqrt(12.0 * (1 - nu * nu) * bend / stretch);
  const double dhat = opt.contact_distance > 0 ? opt.contact_distance : std::max<Real>(mat.thickness, 1e-3);
  const double mean_edge = gd::sim::mean_edge_length(flat);

  nlohmann::json j;
  j["case"] = s.name;
  j["kind"] = contact ? "fold" : "drape";
  j["target_vertices"] = target;
  j["side"] = o.side;
  j["vertices"] = static_cast<int>(m.x.size());
  j["triangles"] = static_cast<int>(m.tris.size());
  j["mean_rest_edge"] = mean_edge;
  j["pinned"] = s.pins;
  j["dt"] = opt.dt;
  j["gravity"] = vec3_json(opt.gravity);
  j["table"] = {{"present", opt.table}, {"height", opt.table_height}, {"friction", opt.table_friction}};
  j["self_contact"] = contact;
  j["contact_distance"] = dhat;
  j["rest_shape"] = "rest.obj (the flat pattern, z = 0; mesh.obj's vt); not the initial shape for fold";
  j["files"] = {{"initial", "mesh.obj"}, {"rest", "rest.obj"}};
  j["material"] = {{"name", mat.name},
                   {"stretch_warp", mat.stretch_warp},
                   {"stretch_weft", mat.stretch_weft},
                   {"shear", mat.shear},
                   {"bend_warp", mat.bend_warp},
                   {"bend_weft", mat.bend_weft},
                   {"bend_kappa_n", mat.bend_kappa_n},
                   {"density", mat.density},
                   {"thickness", mat.thickness},
                   {"friction", mat.friction},
                   {"units", "stretch, shear N/m; bend N·m/rad (per unit width); density kg/m²; thickness m"}};
  j["derived"] = {
      {"young", young},
      {"poisson", nu},
      {"poisson_note", "nu = stretch / (2 shear) - 1 (the value the material's shear was derived with); "
                       "0.3 is the usual assumption when a fabric has no shear data"},
      {"plate_bending_D", young * std::pow(mat.thickness, 3) / (12 * (1 - nu * nu))},
      {"shell_equivalent", {{"thickness", t_eq}, {"young", stretch / t_eq}, {"poisson", nu}}},
      {"total_mass", mat.density * area},
      {"rest_area", area}};
  j["damping"] = {{"membrane", opt.membrane_damping}, {"bending", opt.bending_damping}, {"mass", opt.mass_damping}};
  j["air_drag"] = {{"air_density", opt.air_density}, {"drag_coefficient", opt.drag_coefficient}};
  j["vertex_mass"] = mass;
  write_text(dir / "scene.json", j.dump(1));
  std::fprintf(stderr, "[gd-bench] export %s: %zu vertices, %zu triangles, %zu pinned -> %s\n", s.name.c_str(),
               m.x.size(), m.tris.size(), s.pins.size(), dir.string().c_str());

  if (o.simulate_steps > 0) {
    opt.threads = 1;
    auto scene = gd::sim::Scene::create(m, mat, opt);
    if (!s.pins.empty()) scene->pin(s.pins);
    const auto t0 = std::chrono::steady_clock::now();
    const bool ok = scene->step(o.simulate_steps);
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    nlohmann::json st = {{"steps", o.simulate_steps},
                         {"ok", ok},
                         {"seconds", secs},
                         {"x", flat_json(scene->positions())},
                         {"v", flat_json(scene->velocities())}};
    if (!ok) st["error"] = scene->failure();
    write_text(dir / "ours_state.json", st.dump());
    std::fprintf(stderr, "[gd-bench] export %s: %d steps of ours in %.2f s%s\n", s.name.c_str(), o.simulate_steps,
                 secs, ok ? "" : " (FAILED)");
  }
}

}  // namespace gd::bench
