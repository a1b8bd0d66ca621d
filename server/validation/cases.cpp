#include "validation/cases.h"
#include "validation/robot_cases.h"

#include <algorithm>
#include <chrono>
#include <cmath>

#include <fmt/format.h>

#include "sim/contact/ccd.h"
#include "sim/log.h"
#include "sim/mesh.h"
#include "sim/scene.h"

namespace gd::validation {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

namespace {

using sim::Mesh;
using sim::Real;
using sim::Scene;
using sim::SceneOptions;
using sim::Vec3;

constexpr double kPi = 3.14159265358979323846;
constexpr double kAstmAngleDeg = 41.5;

CaseResult finish(CaseResult r, double tol) {
  r.rel_error = std::abs(r.measured - r.expected) / std::max(std::abs(r.expected), 1e-300);
  r.tolerance = tol;
  r.pass = std::isfinite(r.measured) && r.rel_error <= tol;
  return r;
}

/// Options for static validation solves: no table, no drag, sparse direct solves.
SceneOptions static_options() {
  SceneOptions o;
  o.table = false;
  o.air_density = 0;
  o.dt = 1.0;
  o.newton_max_iters = 40;
  o.newton_tol = 1e-7;  // m/s at dt = 1 s: 0.1 um per Newton iteration
  o.linear_solver = sim::LinearSolverKind::kDirect;
  return o;
}

std::vector<int> where(const Mesh& m, const std::function<bool(const Vec3&)>& pred) {
  std::vector<int> out;
  for (int i = 0; i < static_cast<int>(m.x.size()); ++i)
    if (pred(m.x[i])) out.push_back(i);
  return out;
}

}  // namespace

double expected_bending_length(const sim::Material& m) {
  return std::cbrt(m.bend_warp / (m.density * sim::kGravity));
}

double cantilever_angle(const sim::Material& m, double overhang, int elements_per_overhang, int* vertices,
                        double* effective_overhang) {
  const double width = 0.025;
  // Near-equilateral triangles with rows across the strip (make_rect's rows run along its x, so
  // the strip's length is laid along make_rect's y). Hinge bending on right-triangle grids is
  // biased (quads fold along their diagonals); on near-equilateral meshes it converges.
  const double spacing = overhang / elements_per_overhang, support = 2 * spacing;
  Mesh mesh = sim::make_rect(width, support + overhang, spacing);
  for (size_t i = 0; i < mesh.x.size(); ++i) {
    mesh.x[i] = Vec3(mesh.x[i].y() - support, mesh.x[i].x(), 0);
    mesh.uv[i] = sim::Vec2(mesh.uv[i].y(), mesh.uv[i].x());  // warp along the strip
  }
  for (auto& t : mesh.tris) std::swap(t[1], t[2]);  // the axis swap mirrored the winding
  for (Vec3& p : mesh.x) p.z() += 0.5;
  SceneOptions o = static_options();
  auto scene = Scene::create(mesh, m, o);
  const std::vector<int> held = where(mesh, [&](const Vec3& p) { return p.x() <= 1e-9; });
  scene->pin(held);
  // The support edge is the last held row (mesh rows need not fall on x = 0 exactly).
  double edge = -support;
  for (int i : held) edge = std::max(edge, mesh.x[i].x());
  if (vertices) *vertices = scene->vertex_count();
  if (effective_overhang) *effective_overhang = overhang - edge;
  // Load in a few increments so each Newton solve starts close to its answer.
  const int ramps = 2;
  for (int k = 1; k <= ramps; ++k) {
    // Scene options are fixed at creation, so ramp by rebuilding only the gravity force through
    // external loads: the fraction (k - ramps) of the weight pushes back up.
    std::vector<int> all(scene->vertex_count());
    std::vector<Vec3> f(scene->vertex_count());
    for (int i = 0; i < scene->vertex_count(); ++i) {
      all[i] = i;
      f[i] = Vec3(0, 0, (1.0 - double(k) / ramps) * scene->data().mass[i] * sim::kGravity);
    }
    scene->set_external_forces(all, f);
    if (scene->relax(50, 1e-7) < 0) return NAN;
  }
  const auto x = scene->positions();
  // Tip: mean of the free-end vertices; support edge at (0, z0).
  Vec3 tip = Vec3::Zero();
  int count = 0;
  for (int i = 0; i < static_cast<int>(mesh.x.size()); ++i)
    if (mesh.x[i].x() >= overhang - 1e-9) {
      tip += x[i];
      ++count;
    }
  tip /= count;
  return std::atan2(0.5 - tip.z(), tip.x() - edge) * 180.0 / kPi;
}

CantileverMeasurement measure_cantilever(const sim::Material& m, int elements_per_overhang) {
  // The operator slides the strip until the tip reaches the 41.5 degree line. Start near two
  // bending lengths and update with the small-deflection scaling tan(angle) ~ overhang^3.
  CantileverMeasurement r;
  double l = 2.0 * expected_bending_length(m);
  const double target = std::tan(kAstmAngleDeg * kPi / 180.0);
  for (int it = 0; it < 8; ++it) {
    double effective = l;
    const double a = cantilever_angle(m, l, elements_per_overhang, &r.vertices, &effective);
    ++r.evaluations;
    r.overhang = effective;
    r.angle_deg = a;
    if (!std::isfinite(a)) break;
    if (std::abs(a - kAstmAngleDeg) < 0.05) break;
    l *= std::cbrt(target / std::tan(a * kPi / 180.0));
  }
  r.bending_length = 0.5 * r.overhang;
  return r;
}

CaseResult cantilever_case(const sim::Material& m) {
  const auto t0 = std::chrono::steady_clock::now();
  CaseResult r;
  r.name = "cantilever/" + m.name;
  r.unit = "m";
  const CantileverMeasurement c = measure_cantilever(m);
  r.expected = expected_bending_length(m);
  r.measured = c.bending_length;
  r.vertices = c.vertices;
  r.detail = "overhang " + std::to_string(c.overhang * 100) + " cm at " + std::to_string(c.angle_deg) +
             " deg after " + std::to_string(c.evaluations) + " static solves";
  r.seconds = seconds_since(t0);
  return finish(r, 0.02);  // 0.0-0.9% measured (docs/validation.md)
}

CaseResult cantilever_mesh_independence_case(const sim::Material& m) {
  const auto t0 = std::chrono::steady_clock::now();
  CaseResult r;
  r.name = "cantilever-mesh/" + m.name;
  r.unit = "m";
  const CantileverMeasurement fine = measure_cantilever(m, 24);
  const CantileverMeasurement coarse = measure_cantilever(m, 12);
  r.expected = fine.bending_length;
  r.measured = coarse.bending_length;
  r.vertices = fine.vertices;
  r.detail = "bending length with 12 vs 24 elements along the overhang";
  r.seconds = seconds_since(t0);
  return finish(r, 0.015);  // 0.4% measured for cotton
}

CaseResult tensile_case(const sim::Material& m) {
  const auto t0 = std::chrono::steady_clock::now();
  CaseResult r;
  r.name = "tensile/" + m.name;
  r.unit = "m";
  // A 10 cm x 2.5 cm strip along the warp, top edge clamped, a load F on the bottom edge
  // giving about 1% strain; expected elongation F L / (W k).
  const double L = 0.10, W = 0.025, spacing = 0.0025;
  Mesh mesh = sim::make_rect(W, L, spacing);  // x across, y along the length
  for (Vec3& p : mesh.x) p.z() += 0.5;
  // Pull along the weft axis (y) of this pattern.
  const double k = m.stretch_weft;
  const double F = 0.01 * k * W;
  SceneOptions o = static_options();
  o.gravity = Vec3::Zero();
  auto scene = Scene::create(mesh, m, o);
  scene->pin(where(mesh, [&](const Vec3& p) { return p.y() >= L - 1e-9; }));
  // Bottom-edge vertices share the load by their tributary length.
  std::vector<int> bottom = where(mesh, [](const Vec3& p) { return p.y() <= 1e-9; });
  std::sort(bottom.begin(), bottom.end(), [&](int a, int b) { return mesh.x[a].x() < mesh.x[b].x(); });
  std::vector<Vec3> forces(bottom.size(), Vec3::Zero());
  for (size_t a = 0; a < bottom.size(); ++a) {
    const double left = a > 0 ? 0.5 * (mesh.x[bottom[a]].x() - mesh.x[bottom[a - 1]].x()) : 0.0;
    const double right = a + 1 < bottom.size() ? 0.5 * (mesh.x[bottom[a + 1]].x() - mesh.x[bottom[a]].x()) : 0.0;
    forces[a] = Vec3(0, -F * (left + right) / W, 0);
  }
  scene->set_external_forces(bottom, forces);
  scene->relax(50, 1e-12);
  const auto x = scene->positions();
  double disp = 0;
  for (int i : bottom) disp += mesh.x[i].y() - x[i].y();
  disp /= bottom.size();
  r.expected = F * L / (W * k);
  r.measured = disp;
  r.vertices = scene->vertex_count();
  r.detail = "load " + std::to_string(F) + " N on a 10 x 2.5 cm strip (k = " + std::to_string(k) + " N/m)";
  r.seconds = seconds_since(t0);
  return finish(r, 0.02);
}

}  // namespace gd::validation

namespace gd::validation {
namespace {

/// Projected (xy) area of a deformed mesh, by rasterising its triangles on a grid of cell
/// `cell` (m): the shadow a drape tester's light casts.
double shadow_area(const std::vector<Vec3>& x, const std::vector<Eigen::Vector3i>& tris, double cell) {
  double x0 = 1e30, y0 = 1e30, x1 = -1e30, y1 = -1e30;
  for (const Vec3& p : x) {
    x0 = std::min(x0, p.x());
    y0 = std::min(y0, p.y());
    x1 = std::max(x1, p.x());
    y1 = std::max(y1, p.y());
  }
  const int nx = static_cast<int>((x1 - x0) / cell) + 2, ny = static_cast<int>((y1 - y0) / cell) + 2;
  std::vector<char> hit(static_cast<size_t>(nx) * ny, 0);
  for (const auto& t : tris) {
    const Vec3 &a = x[t[0]], &b = x[t[1]], &c = x[t[2]];
    const int i0 = static_cast<int>((std::min({a.x(), b.x(), c.x()}) - x0) / cell);
    const int i1 = static_cast<int>((std::max({a.x(), b.x(), c.x()}) - x0) / cell) + 1;
    const int j0 = static_cast<int>((std::min({a.y(), b.y(), c.y()}) - y0) / cell);
    const int j1 = static_cast<int>((std::max({a.y(), b.y(), c.y()}) - y0) / cell) + 1;
    const double det = (b.x() - a.x()) * (c.y() - a.y()) - (c.x() - a.x()) * (b.y() - a.y());
    if (std::abs(det) < 1e-20) continue;
    for (int j = std::max(j0, 0); j <= std::min(j1, ny - 1); ++j)
      for (int i = std::max(i0, 0); i <= std::min(i1, nx - 1); ++i) {
        const double px = x0 + (i + 0.5) * cell, py = y0 + (j + 0.5) * cell;
        const double u = ((b.x() - px) * (c.y() - py) - (c.x() - px) * (b.y() - py)) / det;
        const double v = ((c.x() - px) * (a.y() - py) - (a.x() - px) * (c.y() - py)) / det;
        if (u >= 0 && v >= 0 && u + v <= 1) hit[static_cast<size_t>(j) * nx + i] = 1;
      }
  }
  double n = 0;
  for (char h : hit) n += h;
  return n * cell * cell;
}

double mechanical_energy(const sim::EnergyReport& e) { return e.kinetic + e.stretch + e.bending + e.gravity + e.contact; }

}  // namespace

DrapeMeasurement measure_drape(const sim::Material& m, double spacing, bool self_contact, const DrapeSetup& setup) {
  // Cusick drape tester: a 30 cm disc on an 18 cm support disc; DC = (A_shadow - A_support) /
  // (A_specimen - A_support).
  const double R = 0.15, r_support = 0.09;
  Mesh mesh = sim::make_disc(R, spacing);
  // A small deterministic ripple breaks the axial symmetry so that folds (nodes) can form.
  for (Vec3& p : mesh.x)
    p.z() = 0.5 + 2e-4 * std::sin(setup.waves * std::atan2(p.y(), p.x())) * (p.head<2>().norm() / R);
  SceneOptions o;
  o.table = false;
  o.dt = 1.0 / 100;
  o.self_contact = self_contact;
  o.linear_solver = sim::LinearSolverKind::kDirect;  // converged Newton steps: drape is path dependent
  auto scene = Scene::create(mesh, m, o);
  scene->pin(where(mesh, [&](const Vec3& p) { return p.head<2>().norm() <= r_support + 1e-9; }));
  DrapeMeasurement d;
  d.vertices = scene->vertex_count();
  // Lumped vertex weights, for a gravity that grows (an upward force that falls to 0).
  std::vector<int> all(mesh.x.size());
  std::vector<double> weight(mesh.x.size(), 0.0);
  for (size_t i = 0; i < all.size(); ++i) all[i] = static_cast<int>(i);
  for (const auto& t : mesh.tris) {
    const double a = 0.5 * (mesh.x[t[1]] - mesh.x[t[0]]).cross(mesh.x[t[2]] - mesh.x[t[0]]).norm();
    for (int k = 0; k < 3; ++k) weight[t[k]] += m.density * a / 3 * sim::kGravity;
  }
  const int ramp_steps = static_cast<int>(std::lround(setup.gravity_ramp / o.dt));
  std::vector<Vec3> lift(all.size());
  const int settle_steps = static_cast<int>(std::lround(setup.settle / o.dt));
  for (int s = 0; s < ramp_steps + settle_steps && !scene->failed(); ++s) {  // the ramp, then the settling
    if (s <= ramp_steps && ramp_steps > 0) {
      const double left = 1.0 - static_cast<double>(s) / ramp_steps;
      for (size_t i = 0; i < all.size(); ++i) lift[i] = Vec3(0, 0, left * weight[i]);
      scene->set_external_forces(all, lift);
    }
    scene->step();
    d.intersections = std::max(d.intersections, scene->last_stats().intersecting_pairs);
  }
  if (!scene->failed()) scene->relax(20, 1e-6);
  if (scene->failed()) {
    d.coefficient = NAN;
    return d;
  }
  const auto x = scene->positions();
  d.shadow_area = shadow_area(x, mesh.tris, 0.001);
  const double a_support = kPi * r_support * r_support, a_specimen = kPi * R * R;
  d.coefficient = (d.shadow_area - a_support) / (a_specimen - a_support);
  // Nodes: seen from above, the hanging rim reaches out once per fold; count the maxima of the
  // rim's mean distance from the axis over its polar angle (5-degree bins, smoothed over three).
  constexpr int kBins = 72;
  std::vector<double> sum(kBins, 0.0), cnt(kBins, 0.0);
  for (size_t i = 0; i < x.size(); ++i) {
    if (mesh.x[i].head<2>().norm() < R - 1.5 * spacing) continue;  // the rim: the outer ring
    const double a = std::atan2(x[i].y(), x[i].x());
    const int b = std::clamp(static_cast<int>((a + kPi) / (2 * kPi) * kBins), 0, kBins - 1);
    sum[b] += std::hypot(x[i].x(), x[i].y());
    cnt[b] += 1;
  }
  std::vector<double> r(kBins, 0.0);
  for (int b = 0; b < kBins; ++b) r[b] = cnt[b] > 0 ? sum[b] / cnt[b] : NAN;
  std::vector<double> sm(kBins, 0.0);
  for (int b = 0; b < kBins; ++b) {
    double s = 0, c = 0;
    for (int k = -1; k <= 1; ++k)
      if (std::isfinite(r[(b + k + kBins) % kBins])) s += r[(b + k + kBins) % kBins], c += 1;
    sm[b] = c > 0 ? s / c : 0;
  }
  for (int b = 0; b < kBins; ++b)
    if (sm[b] > sm[(b + kBins - 1) % kBins] && sm[b] >= sm[(b + 1) % kBins]) ++d.nodes;
  return d;
}

CaseResult drape_case(const sim::Material& m) {
  const auto t0 = std::chrono::steady_clock::now();
  CaseResult r;
  r.name = "drape/" + m.name;
  r.unit = "";
  // 5 mm: the coefficient is within 7% of the 3.75 mm one there (7.5 mm was 65% off; the study
  // `gd-validate --drape-spacings` and docs/validation.md).
  const DrapeMeasurement d = measure_drape(m, 0.005, true);
  r.expected = 0.68;
  r.measured = d.coefficient;
  r.vertices = d.vertices;
  r.intersections = d.intersections;
  r.detail = fmt::format("shadow {:.1f} cm^2 lowered over 2 s, settled 3 s and relaxed, {} nodes, self-contact on",
                         d.shadow_area * 1e4, d.nodes);
  r.seconds = seconds_since(t0);
  // The paper gives no drape data for its fabrics. The case reports the coefficient against a
  // typical cotton value (0.68) and passes when it is finite, inside the range woven fabrics span
  // (0.2 to 0.95) and no folds pass through each other; fabrics whose drape was measured are
  // compared in tests/validation/drape_reference_test.cpp (docs/validation.md).
  r = finish(r, 0.0);
  r.tolerance = NAN;
  r.pass = std::isfinite(r.measured) && r.measured >= 0.2 && r.measured <= 0.95 && d.intersections == 0;
  return r;
}

CaseResult drop_case(const sim::Material& m) {
  const auto t0 = std::chrono::steady_clock::now();
  CaseResult r;
  r.name = "drop/" + m.name;
  r.unit = "m";
  // A 30 cm square dropped flat from 10 cm: it must come to rest on the table (z = 0) at the
  // barrier's equilibrium gap dhat/2 (each vertex's weight balances the contact force there),
  // and never go through it.
  Mesh mesh = sim::make_rect(0.3, 0.3, 0.01);
  for (Vec3& p : mesh.x) p.z() = 0.1 + 0.01 * p.x();  // slightly tilted: one edge lands first
  SceneOptions o;
  o.dt = 1.0 / 200;
  auto scene = Scene::create(mesh, m, o);
  double min_z = 1e30;
  for (int s = 0; s < 200 && !scene->failed(); ++s) {
    scene->step();
    for (const Vec3& p : scene->positions()) min_z = std::min(min_z, p.z());
  }
  const auto x = scene->positions();
  const auto v = scene->velocities();
  double mean_z = 0, max_speed = 0;
  for (size_t i = 0; i < x.size(); ++i) {
    mean_z += x[i].z();
    max_speed = std::max(max_speed, v[i].norm());
  }
  mean_z /= x.size();
  const double dhat = std::max(m.thickness, 1e-3);
  r.expected = 0.5 * dhat;
  r.measured = scene->failed() ? NAN : mean_z;
  r.vertices = scene->vertex_count();
  r.detail = "min z over the fall " + std::to_string(min_z * 1e3) + " mm, final max speed " +
             std::to_string(max_speed * 1e3) + " mm/s after 1 s";
  r.seconds = seconds_since(t0);
  r = finish(r, 0.1);
  r.pass = r.pass && min_z > 0 && max_speed < 0.01;
  return r;
}

CaseResult slide_case(const sim::Material& m) {
  const auto t0 = std::chrono::steady_clock::now();
  CaseResult r;
  r.name = "slide/" + m.name;
  r.unit = "m";
  // A 20 cm square resting on the table, launched at v0 along +x: Coulomb friction stops it
  // after v0^2 / (2 mu g). No air drag, so friction alone decelerates it.
  const double v0 = 0.5;
  SceneOptions o;
  o.dt = 1.0 / 200;
  o.air_density = 0;
  const double dhat = std::max(m.thickness, 1e-3);
  Mesh mesh = sim::make_rect(0.2, 0.2, 0.01);
  for (Vec3& p : mesh.x) p.z() = 0.5 * dhat;
  auto scene = Scene::create(mesh, m, o);
  scene->relax(5, 1e-9);  // settle onto the barrier gap
  const auto x0 = scene->positions();
  scene->set_state(x0, std::vector<Vec3>(x0.size(), Vec3(v0, 0, 0)));
  double speed = v0;
  int steps = 0;
  while (speed > 1e-3 && steps < 400 && !scene->failed()) {
    scene->step();
    ++steps;
    speed = 0;
    for (const Vec3& v : scene->velocities()) speed += v.x();
    speed /= x0.size();
  }
  const auto x = scene->positions();
  double dist = 0;
  for (size_t i = 0; i < x.size(); ++i) dist += x[i].x() - x0[i].x();
  dist /= x.size();
  r.expected = v0 * v0 / (2 * o.table_friction * sim::kGravity);
  r.measured = scene->failed() ? NAN : dist;
  r.vertices = scene->vertex_count();
  r.detail = "mu " + std::to_string(o.table_friction) + ", stopped after " + std::to_string(steps * o.dt) + " s";
  r.seconds = seconds_since(t0);
  return finish(r, 0.1);
}

CaseResult hang_case(const sim::Material& m) {
  const auto t0 = std::chrono::steady_clock::now();
  CaseResult r;
  r.name = "hang/" + m.name;
  r.unit = "strain";
  // A 50 cm square held at two corners by clips (the vertices within 3 cm of each) for 2 s:
  // it must settle with the largest stretch under 1% and its mechanical energy must never grow.
  Mesh mesh = sim::make_rect(0.5, 0.5, 0.02);
  for (Vec3& p : mesh.x) p.z() = 0.6;
  SceneOptions o;
  o.dt = 1.0 / 100;
  o.table = false;
  auto scene = Scene::create(mesh, m, o);
  scene->pin(where(mesh, [](const Vec3& p) {
    return (p - Vec3(0, 0.5, 0.6)).norm() <= 0.03 + 1e-9 || (p - Vec3(0.5, 0.5, 0.6)).norm() <= 0.03 + 1e-9;
  }));
  double e_prev = mechanical_energy(scene->energies());
  int grew = 0;
  for (int s = 0; s < 200 && !scene->failed(); ++s) {
    scene->step();
    const double e = mechanical_energy(scene->energies());
    if (e > e_prev + 1e-9) ++grew;
    e_prev = e;
  }
  r.expected = 0.01;
  r.measured = scene->failed() ? NAN : scene->max_strain();
  r.vertices = scene->vertex_count();
  r.detail = "max stretch strain after 2 s (bound 1%); steps with energy growth: " + std::to_string(grew);
  r.seconds = seconds_since(t0);
  r.rel_error = r.measured / r.expected;
  r.tolerance = 1.0;
  r.pass = std::isfinite(r.measured) && r.measured < r.expected && grew == 0;
  return r;
}

std::vector<NamedCase> case_list(const sim::MaterialLibrary& lib, const std::string& robot_urdf) {
  std::vector<NamedCase> cases;
  for (const std::string& name : lib.names()) {
    const sim::Material m = lib.get(name);
    cases.push_back({"cantilever/" + name, [m] { return cantilever_case(m); }});
  }
  const sim::Material cotton = lib.get("cotton");
  cases.push_back({"cantilever-mesh/cotton", [cotton] { return cantilever_mesh_independence_case(cotton); }});
  cases.push_back({"tensile/cotton", [cotton] { return tensile_case(cotton); }});
  cases.push_back({"hang/cotton", [cotton] { return hang_case(cotton); }});
  cases.push_back({"drop/cotton", [cotton] { return drop_case(cotton); }});
  cases.push_back({"slide/cotton", [cotton] { return slide_case(cotton); }});
  cases.push_back({"drape/cotton", [cotton] { return drape_case(cotton); }});
  cases.push_back({"self/fold/cotton", [cotton] { return fold_case(cotton); }});
  cases.push_back({"slope/cotton", [cotton] { return slope_case(cotton); }});
  cases.push_back({"pinch/cotton", [cotton] { return pinch_case(cotton); }});
  cases.push_back({"self/press/cotton", [cotton] { return press_case(cotton); }});
  if (!robot_urdf.empty()) {
    cases.push_back({"robot/fk", [robot_urdf] { return robot_fk_case(robot_urdf); }});
    for (const std::string& name : lib.names()) {
      const sim::Material m = lib.get(name);
      cases.push_back({"robot/pinch/" + name, [m, robot_urdf] { return robot_pinch_case(m, robot_urdf); }});
    }
  }
  return cases;
}

}  // namespace gd::validation

namespace gd::validation {
namespace {

/// Smooth 0 -> 1 ramp over [t0, t0 + T].
double smooth(double t, double t0, double T) {
  const double s = std::clamp((t - t0) / T, 0.0, 1.0);
  return s * s * (3 - 2 * s);
}

/// A rigid motion that rotates the grip about a fold line (point c, direction axis) by
/// angle(t), lifting a little at the end so the flap lands on the layer below.
sim::PoseFn fold_motion(const Vec3& c, const Vec3& axis, double t0, double T, double lift) {
  return [=](double t) {
    const double s = smooth(t, t0, T);
    Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
    p.translate(c + Vec3(0, 0, lift * s));
    p.rotate(Eigen::AngleAxisd(kPi * s, axis.normalized()));
    p.translate(-c);
    return p;
  };
}

}  // namespace

CaseResult fold_case(const sim::Material& m) {
  const auto t0 = std::chrono::steady_clock::now();
  CaseResult r;
  r.name = "self/fold/" + m.name;
  r.unit = "pairs";
  // A 30 cm square resting on the table is folded in half (grips at two corners rotate over
  // the fold line x = 15 cm in 2 s), released, then folded again across y (both layers held),
  // released and left to settle. Cloth self-contact must keep the layers apart: zero intersecting triangle pairs
  // after every step, with the untangling fail-safe counted if it ever runs.
  const double L = 0.3, spacing = 0.015;
  sim::SceneOptions o;
  o.dt = 1.0 / 200;
  o.self_contact = true;
  const double dhat = std::max(m.thickness, 1e-3);
  Mesh mesh = sim::make_rect(L, L, spacing);
  for (Vec3& p : mesh.x) p.z() = 0.5 * dhat;
  auto scene = Scene::create(mesh, m, o);
  auto near = [&](const std::vector<Vec3>& x, const Vec3& c) {
    std::vector<int> out;
    for (int i = 0; i < static_cast<int>(x.size()); ++i)
      if ((x[i] - c).head<2>().norm() <= 0.02) out.push_back(i);
    return out;
  };
  int worst = 0, steps = 0;
  auto run = [&](double seconds) {
    const int n = static_cast<int>(std::lround(seconds / o.dt));
    for (int s = 0; s < n && !scene->failed(); ++s) {
      scene->step();
      ++steps;
      worst = std::max(worst, scene->last_stats().intersecting_pairs);
    }
  };
  // Fold 1: corners at x = L over the line x = L/2.
  auto x = scene->positions();
  std::vector<int> grip = near(x, Vec3(L, 0, 0));
  const auto g2 = near(x, Vec3(L, L, 0));
  grip.insert(grip.end(), g2.begin(), g2.end());
  // Rotating about -y carries x = L up and over onto x = 0.
  int g = scene->attach(grip, fold_motion(Vec3(L / 2, 0, 0.5 * dhat), Vec3(0, -1, 0), scene->time(), 2.0, 4 * dhat));
  run(2.1);
  scene->release(g);
  run(0.4);
  // Fold 2: the folded strip's corners at y = L over the line y = L/2 (both layers held).
  x = scene->positions();
  grip = near(x, Vec3(0, L, 0));
  const auto g3 = near(x, Vec3(L / 2, L, 0));
  grip.insert(grip.end(), g3.begin(), g3.end());
  // Rotating about +x carries y = L up and over onto y = 0.
  g = scene->attach(grip, fold_motion(Vec3(0, L / 2, 0.5 * dhat), Vec3(1, 0, 0), scene->time(), 2.0, 8 * dhat));
  run(2.1);
  scene->release(g);
  run(0.5);
  double min_z = 1e30;
  for (const Vec3& p : scene->positions()) min_z = std::min(min_z, p.z());
  r.expected = 0;
  r.measured = scene->failed() ? NAN : worst;
  r.vertices = scene->vertex_count();
  r.detail = std::to_string(steps) + " steps, untangling ran in " + std::to_string(scene->untangle_runs()) +
             " steps, lowest vertex " + std::to_string(min_z * 1e3) + " mm" +
             (scene->failed() ? ", FAILED: " + scene->failure() : "");
  r.seconds = seconds_since(t0);
  r.rel_error = r.measured;
  r.tolerance = 0;
  r.intersections = worst;
  r.pass = !scene->failed() && worst == 0 && min_z > 0;
  return r;
}

}  // namespace gd::validation

namespace gd::validation {
namespace {

/// Displacement (m, along the uphill in-plane axis; negative = downhill) of a 10 cm patch
/// resting on a plane collider tilted by `angle` (rad) with friction mu, after `seconds`.
double slope_displacement(const sim::Material& m, double angle, double mu, double seconds, int* vertices) {
  const double dhat = std::max(m.thickness, 1e-3);
  const Vec3 n(-std::sin(angle), 0, std::cos(angle)), eu(std::cos(angle), 0, std::sin(angle)), o(0, 0, 0.5);
  Mesh mesh = sim::make_rect(0.1, 0.1, 0.01);
  for (Vec3& p : mesh.x) p = o + p.x() * eu + Vec3(0, p.y(), 0) + 0.5 * dhat * n;
  SceneOptions opt;
  opt.table = false;
  opt.air_density = 0;
  opt.dt = 1.0 / 200;
  auto scene = Scene::create(mesh, m, opt);
  sim::Collider plane = sim::Collider::plane(o, n);
  plane.set_friction(mu);
  scene->add_collider(plane);
  const auto x0 = scene->positions();
  scene->step(static_cast<int>(std::lround(seconds / opt.dt)));
  if (vertices) *vertices = scene->vertex_count();
  if (scene->failed()) return NAN;
  const auto x = scene->positions();
  double d = 0;
  for (size_t i = 0; i < x.size(); ++i) d += (x[i] - x0[i]).dot(eu);
  return d / x.size();
}

/// Fall (m) of a hanging 4 x 10 cm strip whose top 2 cm are squeezed between two box pads
/// with friction mu, after `seconds`.
double pinch_fall(const sim::Material& m, double mu, double seconds, int* vertices) {
  const double dhat = std::max(m.thickness, 1e-3), W = 0.04, L = 0.10, grip = 0.02, half_gap = 0.3 * dhat;
  Mesh mesh = sim::make_rect(W, L, 0.005);
  for (Vec3& p : mesh.x) p = Vec3(p.x(), 0, 0.5 + p.y());  // hanging in the xz plane, top at z = 0.6
  SceneOptions opt;
  opt.table = false;
  opt.air_density = 0;
  opt.dt = 1.0 / 200;
  auto scene = Scene::create(mesh, m, opt);
  for (const double side : {-1.0, 1.0}) {
    sim::Collider pad = sim::Collider::box(Vec3(W, 0.005, 0.5 * grip));
    const Vec3 c(0.5 * W, side * (half_gap + 0.005), 0.5 + L - 0.5 * grip);
    pad.set_pose([c](double) { return Eigen::Isometry3d(Eigen::Translation3d(c)); });
    pad.set_friction(mu);
    scene->add_collider(pad);
  }
  const auto x0 = scene->positions();
  scene->step(static_cast<int>(std::lround(seconds / opt.dt)));
  if (vertices) *vertices = scene->vertex_count();
  if (scene->failed()) return NAN;
  const auto x = scene->positions();
  double fall = 0;
  for (size_t i = 0; i < x.size(); ++i) fall += x0[i].z() - x[i].z();
  return fall / x.size();
}

}  // namespace

CaseResult slope_case(const sim::Material& m) {
  const auto t0 = std::chrono::steady_clock::now();
  CaseResult r;
  r.name = "slope/" + m.name;
  r.unit = "deg";
  // A patch on a plane collider with friction mu: it must stay below the angle atan(mu) and
  // slide above it. Bisection on the angle for the onset of sliding (> 5 mm down in 0.5 s).
  const double mu = 0.5, critical = std::atan(mu);
  double lo = 0.8 * critical, hi = 1.2 * critical;
  const bool lo_stays = slope_displacement(m, lo, mu, 0.5, &r.vertices) > -0.005;
  const bool hi_slides = slope_displacement(m, hi, mu, 0.5, nullptr) < -0.005;
  for (int k = 0; k < 4 && lo_stays && hi_slides; ++k) {
    const double mid = 0.5 * (lo + hi);
    (slope_displacement(m, mid, mu, 0.5, nullptr) < -0.005 ? hi : lo) = mid;
  }
  r.expected = critical * 180 / kPi;
  r.measured = lo_stays && hi_slides ? 0.5 * (lo + hi) * 180 / kPi : NAN;
  r.detail = "mu " + std::to_string(mu) + ": stays at " + std::to_string(lo * 180 / kPi) + " deg, slides at " +
             std::to_string(hi * 180 / kPi) + " deg";
  r.seconds = seconds_since(t0);
  return finish(r, 0.1);
}

CaseResult pinch_case(const sim::Material& m) {
  const auto t0 = std::chrono::steady_clock::now();
  CaseResult r;
  r.name = "pinch/" + m.name;
  r.unit = "m";
  // A strip squeezed between two pads holds its weight with enough friction (mu = 1.5) and slips
  // with too little (mu = 0.1): its mean fall after 0.5 s.
  const double held = pinch_fall(m, 1.5, 0.5, &r.vertices);
  const double slipped = pinch_fall(m, 0.1, 0.5, nullptr);
  r.expected = 0;
  r.measured = held;
  r.detail = "mean fall " + std::to_string(held * 1e3) + " mm with mu 1.5, " + std::to_string(slipped * 1e3) +
             " mm with mu 0.1 (0.5 s)";
  r.seconds = seconds_since(t0);
  r.rel_error = held;
  r.tolerance = 0.005;
  r.pass = std::isfinite(held) && std::isfinite(slipped) && held < 0.005 && slipped > 0.02;
  return r;
}

}  // namespace gd::validation

namespace gd::validation {

CaseResult press_case(const sim::Material& m) {
  const auto t0 = std::chrono::steady_clock::now();
  CaseResult r;
  r.name = "self/press/" + m.name;
  r.unit = "pairs";
  // A gripper presses a 10 cm flap down into a 20 cm sheet lying on the table and drags it
  // sideways, its target ending 3 cm below the table top (a trajectory that runs into the
  // table). The cloth between grip and table cannot give way: the grip must stall at its force
  // limit, and the barriers must hold the layers apart above the CCD floor (a pair pressed below
  // it closes by half per Newton iteration until rounding decides the intersection test) and the
  // sheet above the table, with no intersecting pair found in any step. Then the grip lets go
  // and the flap rests on the sheet for 0.5 s: the barrier stiffness, raised while pressed, must
  // come back down (to at most 2 x), or a stiff barrier would keep Newton at its iteration cap.
  const double dhat = std::max(m.thickness, 1e-3);
  SceneOptions o;
  o.dt = 1.0 / 100;
  o.self_contact = true;
  Mesh lower = sim::make_rect(0.2, 0.2, 0.01);
  for (Vec3& p : lower.x) p.z() = 0.5 * dhat;
  Mesh flap = sim::make_rect(0.1, 0.1, 0.01);
  for (Vec3& p : flap.x) p += Vec3(0.05, 0.05, 3.5 * dhat);
  Mesh mesh = lower;
  const int off = static_cast<int>(lower.x.size());
  mesh.x.insert(mesh.x.end(), flap.x.begin(), flap.x.end());
  mesh.uv.insert(mesh.uv.end(), flap.uv.begin(), flap.uv.end());
  for (Eigen::Vector3i t : flap.tris) mesh.tris.push_back(t + Eigen::Vector3i::Constant(off));
  auto scene = Scene::create(mesh, m, o);
  std::vector<int> grip;
  for (int i = off; i < static_cast<int>(mesh.x.size()); ++i)
    if ((mesh.x[i] - Vec3(0.1, 0.1, 0)).head<2>().norm() <= 0.025) grip.push_back(i);
  const double start = scene->time();
  auto smooth = [](double s) { s = std::clamp(s, 0.0, 1.0); return s * s * (3 - 2 * s); };
  scene->attach(grip, [=](double t) {
    const double s = smooth((t - start) / 1.0);
    return Eigen::Isometry3d(Eigen::Translation3d(Vec3(0.04 * s, 0, -(3.5 * dhat + 0.03) * s)));
  });
  int worst = 0, found = 0, steps = 0;
  double min_z = 1e30, min_self = 1e30, max_grip = 0, max_scale = 1;
  for (; steps < 200 && !scene->failed(); ++steps) {
    if (steps == 150) scene->release_all();  // 1.5 s pressed, then 0.5 s at rest
    scene->step();
    const sim::StepStats& st = scene->last_stats();
    worst = std::max(worst, st.intersecting_pairs);
    found = std::max(found, st.intersecting_found);
    for (const Vec3& p : scene->positions()) min_z = std::min(min_z, p.z());
    min_self = std::min(min_self, st.min_self_distance);
    max_grip = std::max(max_grip, st.max_grip_force);
    max_scale = std::max(max_scale, st.barrier_scale);
  }
  const double rest_scale = scene->last_stats().barrier_scale;
  r.expected = 0;
  r.measured = scene->failed() ? NAN : found;
  r.vertices = scene->vertex_count();
  const double floor = sim::kCcdFloorFraction * dhat;
  r.detail = fmt::format("{} steps, untangling ran in {} steps, closest self-contact pair {:.2g} m (CCD floor {:.2g}), "
                         "lowest vertex {:.2g} m, largest grip pull {:.3g} N (limit {:.3g}), barrier stiffness "
                         "x{:g} while pressed, x{:g} after 0.5 s at rest",
                         steps, scene->untangle_runs(), min_self, floor, min_z, max_grip, o.grip_force_limit,
                         max_scale, rest_scale) +
             (scene->failed() ? ", FAILED: " + scene->failure() : "");
  r.seconds = seconds_since(t0);
  r.rel_error = r.measured;
  r.tolerance = 0;
  r.intersections = worst;
  r.pass = !scene->failed() && found == 0 && min_z > 0 && min_self >= floor &&
           max_grip <= o.grip_force_limit * (1 + 1e-9) && rest_scale <= 2;
  return r;
}

}  // namespace gd::validation
