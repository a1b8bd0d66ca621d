/// \file
/// gd-demo: a square of fabric (cotton by default, 0.5 m) hanging from its two top corners.
///
///   gd-demo --out DIR [--seconds 2] [--spacing 0.01] [--material cotton] [--side 0.5]
///           [--backend cpu|cuda|auto] [--threads N]
///
/// The square is meshed by make_rect in the plane z = 0.6 m; the vertices within 3 cm (clips) of the two
/// corners on its top edge (y = side) are pinned and the rest falls and swings under gravity at
/// the SceneOptions defaults (dt = 1/200 s). Writes
///   DIR/initial.obj, DIR/final.obj      the mesh at t = 0 and at the end
///   DIR/timeseries.csv                  t,kinetic,stretch,bending,gravity,total,max_strain,
///                                       newton_iters,pcg_iters,ms (one row for t = 0, one per step;
///                                       energies in J, max_strain as a fraction, ms = wall time)
///   DIR/summary.json                    vertices, steps, seconds_simulated, wall_seconds, ...
/// shows a progress bar on stderr and prints a short summary on stdout.

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "experiment/progress.h"
#include "sim/demand.h"
#include "sim/log.h"
#include "sim/material.h"
#include "sim/mesh.h"
#include "sim/scene.h"
#include "sim/solver/options.h"

namespace {

using gd::sim::Mesh;
using gd::sim::Real;
using gd::sim::Scene;
using gd::sim::SceneOptions;
using gd::sim::Vec3;
using Clock = std::chrono::steady_clock;

/// Total energy growth per step above this (J) counts as an energy increase.
constexpr double kEnergyIncreaseTol = 1e-9;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }


struct Row {
  double t, kinetic, stretch, bending, gravity, total, max_strain;
  int newton_iters, pcg_iters;
  double ms;
};

Row row_of(const Scene& s, int newton, int pcg, double ms) {
  const auto e = s.energies();
  return {s.time(), e.kinetic, e.stretch, e.bending, e.gravity, e.total(), s.max_strain(), newton, pcg, ms};
}

void write_csv(const std::vector<Row>& rows, const std::filesystem::path& path) {
  std::ofstream f(path);
  if (!f) throw gd::sim::InputError("cannot write " + path.string());
  f << "t,kinetic,stretch,bending,gravity,total,max_strain,newton_iters,pcg_iters,ms\n";
  char buf[512];
  for (const Row& r : rows) {
    std::snprintf(buf, sizeof buf, "%.6f,%.10e,%.10e,%.10e,%.10e,%.10e,%.8e,%d,%d,%.4f\n", r.t, r.kinetic, r.stretch,
                  r.bending, r.gravity, r.total, r.max_strain, r.newton_iters, r.pcg_iters, r.ms);
    f << buf;
  }
  if (!f) throw gd::sim::InputError("error writing " + path.string());
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"gd-demo: a fabric square hanging from two pinned corners; writes OBJ, CSV and JSON results"};
  std::string out_dir;
  double seconds = 2.0;
  double spacing = 0.01;
  double side = 0.5;
  std::string material_name = "cotton";
  std::string backend_arg = "cpu";
  int threads = 0;
  app.add_option("--out", out_dir, "Output directory (created if missing)")->required();
  app.add_option("--seconds", seconds, "Simulated time, s")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--spacing", spacing, "Mesh vertex spacing, m")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--material", material_name, "Material name from the library")->capture_default_str();
  app.add_option("--side", side, "Side of the square, m")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--backend", backend_arg, "Solver backend")
      ->check(CLI::IsMember({"cpu", "cuda", "auto"}))
      ->capture_default_str();
  app.add_option("--threads", threads, "CPU threads (0: OpenMP default)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);

  try {
    namespace fs = std::filesystem;
    const fs::path dir(out_dir);
    std::error_code ec;
    fs::create_directories(dir, ec);
    if (ec || !fs::is_directory(dir)) throw gd::sim::InputError("cannot create output directory " + out_dir);

    const auto lib = gd::sim::MaterialLibrary::load_default();
    const auto& mat = lib.get(material_name);
    SceneOptions opt;
    opt.backend = backend_arg == "cpu"    ? gd::sim::BackendKind::kCpu
                  : backend_arg == "cuda" ? gd::sim::BackendKind::kCuda
                                          : gd::sim::BackendKind::kAuto;
    opt.threads = threads;

    Mesh mesh = gd::sim::make_rect(side, side, spacing);
    for (auto& p : mesh.x) p.z() = 0.6;
    const Vec3 c0(0, side, 0.6), c1(side, side, 0.6);
    constexpr double kClip = 0.03;  // clips hold the vertices within 3 cm of each corner
    const auto pinned = gd::sim::vertices_where(
        mesh, [&](const Vec3& p) { return (p - c0).norm() <= kClip + 1e-12 || (p - c1).norm() <= kClip + 1e-12; });

    const auto t_wall = Clock::now();
    auto scene = Scene::create(mesh, mat, opt);
    scene->pin(pinned);
    const int steps = std::max(1, static_cast<int>(std::lround(seconds / opt.dt)));
    std::fprintf(stderr, "gd-demo: %s square %.2f m, %d vertices (%zu pinned), %d steps of %.4g s on %s\n",
                 material_name.c_str(), side, scene->vertex_count(), pinned.size(), steps, opt.dt,
                 scene->backend().c_str());

    gd::sim::write_obj(mesh, scene->positions(), (dir / "initial.obj").string());

    std::vector<Row> rows;
    rows.reserve(steps + 1);
    rows.push_back(row_of(*scene, 0, 0, 0.0));
    // The pins never move in this demo, so every step is one in which nothing does work on the
    // cloth from outside: with a dissipative integrator the total energy must not grow.
    const bool pins_moving = false;
    int increase_steps = 0;
    double max_increase = 0;
    double step_seconds = 0;
    int done = 0;
    gd::experiment::ProgressBar bar(steps, "steps");
    bar.update(0);
    for (int i = 0; i < steps; ++i) {
      const auto t0 = Clock::now();
      const bool ok = scene->step();
      const double dt_wall = seconds_since(t0);
      if (!ok) {
        bar.finish();
        gd::log().error("simulation failed at step {}: {}", i + 1, scene->failure());
        break;
      }
      step_seconds += dt_wall;
      ++done;
      const auto& st = scene->last_stats();
      rows.push_back(row_of(*scene, st.newton_iters, st.pcg_iters, 1e3 * dt_wall));
      const double growth = rows.back().total - rows[rows.size() - 2].total;
      if (!pins_moving && growth > kEnergyIncreaseTol) {
        ++increase_steps;
        max_increase = std::max(max_increase, growth);
      }
      bar.update(done, fmt::format("t = {:.3f} s", scene->time()));
    }
    const double wall = seconds_since(t_wall);

    gd::sim::write_obj(mesh, scene->positions(), (dir / "final.obj").string());
    write_csv(rows, dir / "timeseries.csv");
    nlohmann::json summary = {
        {"vertices", scene->vertex_count()},
        {"steps", done},
        {"seconds_simulated", scene->time()},
        {"wall_seconds", wall},
        {"ms_per_step", done > 0 ? 1e3 * step_seconds / done : 0.0},
        {"max_strain_final", rows.back().max_strain},
        {"energy_initial", rows.front().total},
        {"energy_final", rows.back().total},
        {"energy_increase_steps", increase_steps},
        {"energy_increase_max", max_increase},
        {"pinned_vertices", pinned.size()},
        {"material", material_name},
        {"spacing", spacing},
        {"dt", opt.dt},
        {"backend", scene->backend()},
        {"failed", scene->failed()},
    };
    if (scene->failed()) summary["failure"] = scene->failure();
    {
      std::ofstream f(dir / "summary.json");
      if (!f) throw gd::sim::InputError("cannot write " + (dir / "summary.json").string());
      f << summary.dump(2) << "\n";
    }

    std::printf("gd-demo: %s square %.2f m, %d vertices, %d steps (%.3f s simulated) in %.1f s wall (%.1f ms/step, %s)\n",
                material_name.c_str(), side, scene->vertex_count(), done, scene->time(), wall,
                done > 0 ? 1e3 * step_seconds / done : 0.0, scene->backend().c_str());
    std::printf("  energy  %.6g J -> %.6g J; steps with energy growth > %.0e J: %d\n", rows.front().total,
                rows.back().total, kEnergyIncreaseTol, increase_steps);
    std::printf("  max strain at the end: %.3f %%\n", 100.0 * rows.back().max_strain);
    std::printf("  wrote %s/{initial.obj,final.obj,timeseries.csv,summary.json}\n", dir.string().c_str());
    if (scene->failed()) {
      std::printf("  FAILED: %s\n", scene->failure().c_str());
      return 1;
    }
    return 0;
  } catch (const gd::sim::InputError& e) {
    std::fprintf(stderr, "gd-demo: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gd-demo: error: %s\n", e.what());
    return 1;
  }
}
