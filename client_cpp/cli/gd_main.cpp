/// \file
/// gd: the GarmentDynamics command line.
///
///   gd run --garment G --material M --task grasp|fold|fling [--mode pseudo|fixed_point]
///          [--vertices N] [--capture DIR] [--trajectory FILE] --out DIR [...]
///       one experiment, locally, with a progress bar (server/experiment/experiment.h lists the
///       files it writes); prints a short summary.
///   gd metrics --sim A --real B [--json]
///       RGBench's seven sim-to-real metrics between two clouds (PCD, PLY or OBJ vertices).
///   gd synth-capture --garment G --task T --out DIR [...]
///       a synthetic capture in RGBench's layout filmed from a reference simulation (for
///       trying `gd run --capture` without the real dataset).
///
/// Exit codes: 0 success, 1 the simulation failed, 2 bad input (with a message on stderr).

#include <CLI/CLI.hpp>

#include <cstdio>
#include <exception>
#include <nlohmann/json.hpp>
#include <string>

#include "experiment/experiment.h"
#include "experiment/progress.h"
#include "experiment/synthetic_capture.h"
#include "garments/generator.h"
#include "metrics/cloud_io.h"
#include "metrics/cloud_metrics.h"
#include "sim/demand.h"
#include "sim/log.h"

namespace {

using gd::experiment::ExperimentConfig;

int cmd_run(const ExperimentConfig& cfg, bool quiet) {
  std::unique_ptr<gd::experiment::ProgressBar> bar;
  auto progress = [&](double t, double end, const gd::sim::StepStats& st) {
    if (quiet) return;
    if (!bar) bar = std::make_unique<gd::experiment::ProgressBar>(end, "s");
    bar->update(t, fmt::format("{:4.0f} ms/step  contacts {}", 1e3 * st.seconds, st.contacts));
  };
  const auto result = gd::experiment::run_experiment(cfg, progress);
  if (bar) bar->finish();
  const auto& s = result.summary;
  std::printf("%s / %s / %s (%s): %d vertices, %d steps, %.1f s wall (%.0f ms/step), max intersecting pairs %d, "
              "untangling %d\n",
              s["garment"].get<std::string>().c_str(), cfg.material.c_str(), cfg.task.c_str(), cfg.mode.c_str(),
              s["vertices"].get<int>(), s["steps"].get<int>(), s["wall_seconds"].get<double>(),
              s["ms_per_step"].get<double>(), s["intersecting_pairs_max"].get<int>(), s["untangle_runs"].get<int>());
  if (s.contains("cd_l1_r2s"))
    std::printf("metrics (mean over %zu frames): cd_l1_r2s %.4f  cd_l1_s2r %.4f  cd_l2_s2r %.4f  hd_s2r %.4f  "
                "hd_r2s %.4f  z_err %.4f  sim_stab %.4f\n",
                s["frames_in_window"].get<size_t>(), s["cd_l1_r2s"].get<double>(), s["cd_l1_s2r"].get<double>(),
                s["cd_l2_s2r"].get<double>(), s["hd_s2r"].get<double>(), s["hd_r2s"].get<double>(),
                s["z_err"].get<double>(), s["sim_stab"].get<double>());
  std::printf("wrote %s/summary.json\n", cfg.out_dir.c_str());
  if (s["failed"].get<bool>()) {
    std::fprintf(stderr, "gd: the simulation failed: %s\n", s["failure"].get<std::string>().c_str());
    return 1;
  }
  return 0;
}

int cmd_metrics(const std::string& sim, const std::string& real, bool json) {
  const gd::metrics::Metrics m = gd::metrics::compute_metrics(gd::metrics::load_cloud(sim), gd::metrics::load_cloud(real));
  if (json) {
    std::printf("%s\n", gd::metrics::to_json(m).dump().c_str());
  } else {
    for (const auto& n : gd::metrics::kMetricNames) std::printf("%-10s %.6f\n", n.key, m.*n.field);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"gd: GarmentDynamics command line (local runs and metrics)"};
  app.require_subcommand(1);

  ExperimentConfig cfg;
  bool quiet = false, no_self_contact = false, no_plots = false;
  std::vector<int> shoulders;
  std::string backend = "cpu";
  auto* run = app.add_subcommand("run", "run one Grasp/Fold/Fling experiment locally");
  run->add_option("--garment", cfg.garment,
                  "garment type (" + [] {
                    std::string s;
                    for (const auto& t : gd::garments::garment_types()) s += (s.empty() ? "" : ", ") + t;
                    return s;
                  }() + ") or an .obj path")
      ->capture_default_str();
  run->add_option("--material", cfg.material, "fabric from the material library")->capture_default_str();
  run->add_option("--task", cfg.task, "grasp | fold | fling")->capture_default_str();
  run->add_option("--mode", cfg.mode, "pseudo (jaw-radius grasp) | fixed_point (RGBench's)")->capture_default_str();
  run->add_option("--vertices", cfg.vertices, "target vertex count of a generated garment")->capture_default_str();
  run->add_option("--capture", cfg.capture_dir, "RGBench capture directory to compare with");
  run->add_option("--experiment-library", cfg.experiment_library, "RGBench experiment_library.yaml (capture timing)");
  run->add_option("--trajectory", cfg.trajectory_file, "end-effector trajectory (CSV or JSON, docs/tasks.md)");
  run->add_option("--out", cfg.out_dir, "output directory")->required();
  run->add_option("--dt", cfg.scene.dt, "time step, s")->capture_default_str();
  run->add_option("--time-scale", cfg.task_params.time_scale, "speed factor of generated tasks' slow parts")
      ->capture_default_str();
  run->add_option("--settle", cfg.settle_after, "seconds simulated after the trajectory ends")->capture_default_str();
  run->add_option("--shoulder-index", shoulders, "fixed-point fling pins: LEFT RIGHT vertex indices")->expected(2);
  run->add_option("--backend", backend, "cpu | cuda | auto")->capture_default_str();
  run->add_option("--threads", cfg.scene.threads, "CPU threads (0: all)");
  std::string contact_hessian = "projected";
  run->add_option("--contact-hessian", contact_hessian, "self-contact Hessian: gauss-newton | projected")
      ->capture_default_str();
  run->add_flag("--icp", cfg.icp, "refine the capture's camera transform by ICP on the first frame");
  run->add_flag("--no-self-contact", no_self_contact, "turn cloth self-contact off (faster, may interpenetrate)");
  run->add_flag("--no-plots", no_plots, "do not draw the PNG plots");
  run->add_flag("--quiet", quiet, "no progress bar");

  std::string sim_path, real_path;
  bool json = false;
  auto* met = app.add_subcommand("metrics", "RGBench's sim-to-real metrics between two point clouds");
  met->add_option("--sim", sim_path, "simulated cloud (PCD, PLY or OBJ; vertex order matters for sim_stab)")
      ->required();
  met->add_option("--real", real_path, "real cloud (PCD, PLY or OBJ), same frame")->required();
  met->add_flag("--json", json, "print one JSON object");

  ExperimentConfig ref;
  gd::experiment::SyntheticCaptureOptions sco;
  bool ref_no_self_contact = false;
  auto* syn = app.add_subcommand("synth-capture",
                                 "write a synthetic capture in RGBench's layout from a reference simulation");
  syn->add_option("--garment", ref.garment, "garment type or .obj path")->capture_default_str();
  syn->add_option("--material", ref.material, "fabric")->capture_default_str();
  syn->add_option("--task", ref.task, "grasp | fold | fling")->capture_default_str();
  syn->add_option("--vertices", ref.vertices, "target vertex count of the reference")->capture_default_str();
  syn->add_option("--dt", ref.scene.dt, "reference time step, s")->capture_default_str();
  syn->add_option("--time-scale", ref.task_params.time_scale, "speed factor of the task's slow parts")
      ->capture_default_str();
  syn->add_option("--fps", sco.fps, "frames per second")->capture_default_str();
  syn->add_option("--noise", sco.noise, "point noise, m (std per coordinate)")->capture_default_str();
  syn->add_option("--dropout", sco.dropout, "fraction of points dropped")->capture_default_str();
  syn->add_option("--camera-delay", sco.camera_delay, "camera delay written to capture.json, s")->capture_default_str();
  syn->add_flag("--no-self-contact", ref_no_self_contact, "reference without self-contact");
  std::string syn_out;
  syn->add_option("--out", syn_out, "capture directory to write")->required();

  CLI11_PARSE(app, argc, argv);
  try {
    gd::log();  // the logger reads GD_LOG_LEVEL
    if (*run) {
      if (no_self_contact) cfg.scene.self_contact = false;
      if (no_plots) cfg.plots = false;
      if (shoulders.size() == 2) cfg.shoulder_vertices = {shoulders[0], shoulders[1]};
      if (contact_hessian == "projected") cfg.scene.contact_hessian = gd::sim::ContactHessianKind::kProjected;
      else if (contact_hessian != "gauss-newton")
        throw gd::sim::InputError("unknown --contact-hessian '" + contact_hessian + "'; use gauss-newton or projected");
      if (backend == "cpu") cfg.scene.backend = gd::sim::BackendKind::kCpu;
      else if (backend == "cuda") cfg.scene.backend = gd::sim::BackendKind::kCuda;
      else if (backend == "auto") cfg.scene.backend = gd::sim::BackendKind::kAuto;
      else throw gd::sim::InputError("unknown backend '" + backend + "'; use cpu, cuda or auto");
      return cmd_run(cfg, quiet);
    }
    if (*syn) {
      if (ref_no_self_contact) ref.scene.self_contact = false;
      ref.out_dir = syn_out;
      const auto c = gd::experiment::make_synthetic_capture(ref, sco, syn_out);
      std::printf("wrote %d frames (%.2f s) to %s\n", c.frames, c.duration, c.dir.c_str());
      return 0;
    }
    return cmd_metrics(sim_path, real_path, json);
  } catch (const gd::sim::InputError& e) {
    std::fprintf(stderr, "gd: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gd: error: %s\n", e.what());
    return 2;
  }
}
