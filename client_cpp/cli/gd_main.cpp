/// \file
/// gd: the GarmentDynamics command line.
///
///   gd run --garment G --material M --task grasp|fold|fling [--mode pseudo|fixed_point|robot --urdf F]
///          [--vertices N] [--capture DIR] [--trajectory FILE] --out DIR [...]
///       one experiment, locally, with a progress bar (server/experiment/experiment.h lists the
///       files it writes); prints a short summary.
///   gd metrics --sim A --real B [--json] [--surface N]
///       RGBench's seven sim-to-real metrics between two clouds (PCD, PLY or OBJ vertices); with
///       --surface, two OBJ meshes also compared as surfaces (N points of each).
///   gd synth-capture --garment G --task T --out DIR [...]
///       a synthetic capture in RGBench's layout filmed from a reference simulation (for
///       trying `gd run --capture` without the real dataset).
///   gd converge --garment G --task T --vertices 1000,2000,4000,8000 --out DIR [...]
///       a mesh-convergence study: the same run at each resolution, each shape's distance to the
///       finest run's (server/experiment/convergence.h lists the files it writes); --draws K
///       runs K meshes of nearly each resolution and reports their spread beside it; --jobs J
///       runs J of the runs at once; --dts 0.01,0.005,0.0025 with one vertex count studies the
///       time step instead (each shape's distance to the smallest step's run).
///
///
/// With `--server HOST:PORT` the same `gd run` is submitted to a gd-server as a job (progress
/// bar from WatchJob, report files fetched into --out), and the remote-only commands work:
/// info, garments, materials, create, step, report, reports, destroy, upload
/// (cli/remote_commands.h; client_cpp/README.md).
///
/// Exit codes: 0 success, 1 the simulation (job, scene) failed, 2 bad input, 3 server
/// unreachable or another RPC error (with a message on stderr).

#include <CLI/CLI.hpp>

#include <cctype>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <sstream>
#include <nlohmann/json.hpp>
#include <string>

#include "experiment/convergence.h"
#include "experiment/experiment.h"
#include "experiment/progress.h"
#include "experiment/synthetic_capture.h"
#include "garments/generator.h"
#include "metrics/cloud_io.h"
#include "metrics/cloud_metrics.h"
#include "remote_commands.h"
#include "run_summary.h"
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
  gd::cli::print_run_summary(s, cfg.out_dir);
  if (s["failed"].get<bool>()) {
    std::fprintf(stderr, "gd: the simulation failed: %s\n", s["failure"].get<std::string>().c_str());
    return 1;
  }
  return 0;
}

/// RGBench's seven metrics between the clouds at `sim` and `real`; with `surface` > 0 (both OBJ
/// meshes with faces) also their Euclidean distances as surfaces, that many area-sampled points of
/// each to the other's nearest triangle (experiment::surface_distance): what two meshings of one
/// shape (a garment refined under the pads, or at another resolution) agree on, where the vertex
/// clouds weigh each region by how finely it is meshed.
int cmd_metrics(const std::string& sim, const std::string& real, bool json, int surface) {
  const gd::metrics::Metrics m = gd::metrics::compute_metrics(gd::metrics::load_cloud(sim), gd::metrics::load_cloud(real));
  nlohmann::json j = gd::metrics::to_json(m);
  if (surface > 0) {
    for (const std::string* p : {&sim, &real}) {
      std::string ext = std::filesystem::path(*p).extension().string();
      for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      if (ext != ".obj")
        throw gd::sim::InputError("gd metrics --surface compares two OBJ meshes; " + *p + " is not an .obj file");
    }
    const gd::sim::Mesh a = gd::sim::read_obj(sim), b = gd::sim::read_obj(real);
    for (const auto& [mesh, path] : {std::pair{&a, &sim}, std::pair{&b, &real}})
      if (mesh->tris.empty())
        throw gd::sim::InputError("gd metrics --surface needs faces; " + *path + " has only vertices");
    const gd::experiment::SurfaceDistance d = gd::experiment::surface_distance(a, b, surface);
    j["surface_cd_s2r"] = d.cd_ab, j["surface_cd_r2s"] = d.cd_ba;
    j["surface_hd_s2r"] = d.hd_ab, j["surface_hd_r2s"] = d.hd_ba;
  }
  if (json) {
    std::printf("%s\n", j.dump().c_str());
  } else {
    for (const auto& n : gd::metrics::kMetricNames) std::printf("%-10s %.6f\n", n.key, m.*n.field);
    for (const char* k : {"surface_cd_s2r", "surface_cd_r2s", "surface_hd_s2r", "surface_hd_r2s"})
      if (j.contains(k)) std::printf("%-14s %.6f\n", k, j[k].get<double>());
  }
  return 0;
}

/// The numbers of a comma-separated list, each read whole by `parse` (empty text: none); an
/// InputError that starts with `what` and quotes the text otherwise.
template <class T, class Parse>
std::vector<T> number_list(const std::string& text, Parse parse, const std::string& what) {
  std::vector<T> out;
  std::stringstream list(text);
  for (std::string item; !text.empty() && std::getline(list, item, ',');) {
    try {
      size_t used = 0;
      out.push_back(parse(item, &used));
      if (used != item.size()) throw std::invalid_argument(item);
    } catch (const std::exception&) {
      throw gd::sim::InputError(what + " (got '" + text + "')");
    }
  }
  return out;
}

int cmd_converge(const gd::experiment::ConvergenceConfig& cfg, bool quiet) {
  std::unique_ptr<gd::experiment::ProgressBar> bar;
  int bar_run = -1;
  std::vector<double> run_time;  // with jobs: each run's simulated time so far, one bar for them all
  auto progress = [&](int run, int runs, int vertices, double t, double end) {
    if (quiet) return;
    if (cfg.jobs > 1) {
      if (!bar) {
        std::fprintf(stderr, "%d runs, %d at a time (simulated seconds summed over the runs)\n", runs,
                     std::min(cfg.jobs, runs));
        bar = std::make_unique<gd::experiment::ProgressBar>(runs * end, "s");
        run_time.assign(runs, 0.0);
      }
      run_time[run] = t;
      int done = 0;
      for (int k = 0; k < runs; ++k) done += run_time[k] >= end;
      double sum = 0;
      for (double x : run_time) sum += x;
      bar->update(sum, fmt::format("runs done {}/{}", done, runs));
      return;
    }
    if (run != bar_run) {
      if (bar) bar->finish();
      std::fprintf(stderr, "run %d/%d: %d vertices\n", run + 1, runs, vertices);
      bar = std::make_unique<gd::experiment::ProgressBar>(end, "s");
      bar_run = run;
    }
    bar->update(t);
  };
  const auto result = gd::experiment::run_convergence(cfg, progress);
  if (bar) bar->finish();
  const bool by_dt = !cfg.dts.empty();
  if (by_dt)
    std::printf("distance to the run at the smallest time step (%g ms, %d vertices), symmetric, mm:\n",
                1e3 * result.summary["reference_dt"].get<double>(), result.summary["reference_vertices"].get<int>());
  else
    std::printf("distance to the finest run (%d vertices), symmetric, mm:\n",
                result.summary["reference_vertices"].get<int>());
  const bool floors = cfg.draws > 1;
  const char* level = by_dt ? "dt (ms)" : "vertices";
  if (floors) {
    std::printf("(means over %d draws per %s; floor: between two draws of the run's, ref floor: of the reference)\n",
                cfg.draws, by_dt ? "time step (meshes 2.5%, 5%... apart)" : "resolution");
    std::printf("%9s %9s %10s %10s %14s %14s\n", level, "t (s)", "chamfer", "hausdorff", "chamfer floor", "ref floor");
  } else {
    std::printf("%9s %9s %10s %10s\n", level, "t (s)", "chamfer", "hausdorff");
  }
  for (const auto& r : result.rows) {
    const std::string t = r.final ? std::string("final") : fmt::format("{:.2f}", r.t);
    const std::string at = by_dt ? fmt::format("{:g}", 1e3 * r.dt) : std::to_string(r.vertices);
    if (floors)
      std::printf("%9s %9s %10.2f %10.2f %14.2f %14.2f\n", at.c_str(), t.c_str(), 1e3 * r.cd, 1e3 * r.hd,
                  1e3 * r.cd_floor, 1e3 * r.ref_cd_floor);
    else
      std::printf("%9s %9s %10.2f %10.2f\n", at.c_str(), t.c_str(), 1e3 * r.cd, 1e3 * r.hd);
  }
  const bool png = std::filesystem::exists(cfg.base.out_dir + "/convergence.png");
  std::printf("files in %s: convergence.csv, convergence.json%s, %s/ per run\n", cfg.base.out_dir.c_str(),
              png ? ", convergence.png" : "", by_dt ? "dt<ms>ms" : "v<N>");
  for (const auto& run : result.summary["runs"])
    if (run.value("failed", false)) {
      std::fprintf(stderr, "gd: the run at %d vertices failed: %s\n", run.value("vertices", 0),
                   run.value("failure", std::string("?")).c_str());
      return 1;
    }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"gd: GarmentDynamics command line (local runs and metrics; with --server, a gd-server's scenes and jobs)"};
  app.require_subcommand(1);
  std::string server;
  app.add_option("--server", server, "HOST:PORT of a gd-server: `run` becomes a job there; needed by the remote commands");
  gd::cli::ConnectionFlags connection;
  app.add_option("--token-file", connection.token_file,
                 "with --server: a file whose first line is the bearer token (default: $GD_TOKEN_FILE)");
  app.add_option("--tls-ca", connection.tls_ca, "with --server: connect over TLS, trusting this PEM CA or certificate");
  app.add_flag("--tls", connection.tls, "with --server: connect over TLS, trusting the system's CAs");
  app.add_option("--tls-cert", connection.tls_cert, "with --server: PEM client certificate (mutual TLS)");
  app.add_option("--tls-key", connection.tls_key, "with --server: PEM key of --tls-cert");

  ExperimentConfig cfg;
  bool quiet = false, no_self_contact = false, no_plots = false;
  std::vector<int> shoulders;
  std::string backend = "cpu";
  auto* run = app.add_subcommand("run", "run one Grasp/Fold/Fling experiment locally (with --server: as a job there)");
  run->add_option("--garment", cfg.garment,
                  "garment type (" + [] {
                    std::string s;
                    for (const auto& t : gd::garments::garment_types()) s += (s.empty() ? "" : ", ") + t;
                    return s;
                  }() + ") or an .obj path")
      ->capture_default_str();
  run->add_option("--material", cfg.material, "fabric from the material library")->capture_default_str();
  run->add_option("--task", cfg.task, "grasp | fold | fling")->capture_default_str();
  run->add_option("--mode", cfg.mode,
                  "pseudo (jaw-radius grasp) | fixed_point (RGBench's) | robot (URDF arms holding the cloth by "
                  "finger contact and friction; needs --urdf, or with --server the server's --robot-urdf)")
      ->capture_default_str();
  run->add_option("--urdf", cfg.robot.urdf,
                  "robot mode: the arms' URDF (RGBench's piper_with_gripper.urdf); a capture's pos_1..pos_6 drive "
                  "its joints, other trajectories go through inverse kinematics");
  run->add_option("--grip-force", cfg.robot.grip_force,
                  "robot mode: squeeze at which the closing fingers stop, N (< 0: the URDF's finger effort limit)")
      ->capture_default_str();
  std::vector<std::string> grip_schedule;
  run->add_option("--grip-force-schedule", grip_schedule,
                  "robot mode: the squeeze limit over time, knots T:N (s, N; linear between, held beyond), e.g. "
                  "8.5:10 14.5:0.1 lowers it over a hold: summary.json's lost_at and grip_force_at_loss_n say when "
                  "each hand let go and at what limit (docs/robot.md, \"The force a grip needs\")");
  run->add_option("--finger-friction", cfg.robot.finger_friction,
                  "robot mode: friction of the finger pads on the cloth (< 0: the material's)")
      ->capture_default_str();
  run->add_option("--pad-stiffness", cfg.robot.pad_stiffness,
                  "robot mode: a hand the cloth stops short goes on in the solve, pulled along its step by "
                  "this stiffness, N/m (0: its pads wait where the cloth stopped them; docs/robot.md, \"Pads in "
                  "the solve\")")
      ->capture_default_str();
  double lift_max_tilt_deg = cfg.robot.lift_max_tilt * 180 / M_PI;
  run->add_option("--lift-max-tilt", lift_max_tilt_deg,
                  "robot mode: a generated grasp's lift or fling's height left to its default is lowered to the "
                  "highest the arms follow with no hand tilted more than this from pointing down, degrees "
                  "(docs/robot.md, \"Within reach\")")
      ->check(CLI::Range(0.0, 180.0))
      ->capture_default_str();
  run->add_option("--urdf-package-path", cfg.robot.arm.package_paths,
                  "robot mode: a directory where the URDF's package://NAME/... meshes are found (DIR/NAME/... or DIR "
                  "named NAME); the links with collision geometry found collide with the cloth (repeatable)");
  run->add_flag("!--independent-pads", cfg.robot.rigid_hands,
                "robot mode: each finger pad yields to the cloth on its own, not with its hand's other pad "
                "(for comparison; docs/robot.md, \"Pads that stop together\")");
  run->add_flag("!--no-link-colliders", cfg.robot.link_colliders,
                "robot mode: the finger pads alone collide with the cloth, not the arms' links");
  run->add_flag("--pad-samples,!--no-pad-samples", cfg.robot.pad_samples,
                "robot mode: the pads keep points sampled over the cloth's triangles out too, not only its vertices "
                "(the default; --no-pad-samples keeps out the vertices alone, and cloth meshed coarser than a pad is "
                "thick then stands threaded on the pads; docs/robot.md, \"Surface samples\")");
  run->add_option("--vertices", cfg.vertices, "target vertex count of a generated garment")->capture_default_str();
  std::vector<double> garment_position;
  run->add_option("--garment-position", garment_position,
                  "X Y Z: where the garment frame's origin goes in the world, m (RGBench's init_pose; default 0.1 0 "
                  "0.01, the collar end 10 cm in front of the arms' bases)")
      ->expected(3);
  run->add_flag("--place-within-reach", cfg.place_within_reach,
                "robot mode, generated tasks: move the garment up to 30 cm farther from the arms' bases or 10 cm "
                "nearer, to where "
                "they lift it highest within --lift-max-tilt (a given height, or a fold they follow there: where "
                "the hands tilt least; a fold they follow nowhere: where the narrowest put-down margin brings it "
                "within reach); docs/robot.md, \"Placed within reach\"");
  run->add_option("--refine-grasp", cfg.refine_grasp_edge,
                  "EDGE: refine the mesh to EDGE m near the grasp points (shoulders; the fold's hem corners too), "
                  "e.g. 0.006 for robot mode's 2 x 4 cm pads (docs/robot.md, \"Finer cloth under the pads\"); 0: off")
      ->capture_default_str();
  run->add_option("--refine-grasp-radius", cfg.refine_grasp_radius, "m round each grasp point that --refine-grasp refines")
      ->capture_default_str();
  std::vector<std::string> garment_params;
  run->add_option("--garment-param", garment_params,
                  "a size of a generated garment, NAME=VALUE (repeatable; e.g. hood_length=0.25; names in docs/garments.md)");
  std::vector<std::string> material_params;
  run->add_option("--material-param", material_params,
                  "a parameter of the material replaced, NAME=VALUE in catalogue units (repeatable; e.g. "
                  "bending_g_mm2_s2_rad=1000; names in docs/materials.md)");
  run->add_option("--capture", cfg.capture_dir, "RGBench capture directory to compare with");
  run->add_option("--experiment-library", cfg.experiment_library, "RGBench experiment_library.yaml (capture timing)");
  run->add_option("--trajectory", cfg.trajectory_file, "end-effector trajectory (CSV or JSON, docs/tasks.md)");
  run->add_option("--out", cfg.out_dir, "output directory")->required();
  run->add_option("--dt", cfg.scene.dt, "time step, s")->capture_default_str();
  run->add_option("--time-scale", cfg.task_params.time_scale, "speed factor of generated tasks' slow parts")
      ->capture_default_str();
  std::vector<std::string> task_params;
  run->add_option("--task-param", task_params,
                  "a parameter of the generated task, NAME=VALUE (repeatable; e.g. fold_duration=5; names in docs/tasks.md)");
  run->add_option("--settle", cfg.settle_after, "seconds simulated after the trajectory ends")->capture_default_str();
  run->add_option("--shoulder-index", shoulders, "fixed-point fling pins: LEFT RIGHT vertex indices")->expected(2);
  run->add_option("--backend", backend, "cpu | cuda | auto")->capture_default_str();
  run->add_option("--threads", cfg.scene.threads, "CPU threads (0: all)");
  run->add_flag("--deterministic", cfg.scene.deterministic,
                "CUDA: assembly in a fixed order instead of atomic adds (the same steps bit for bit on every run; "
                "slower); the CPU backend is deterministic either way");
  std::string contact_hessian = gd::sim::contact_hessian_name(cfg.scene.contact_hessian);
  run->add_option("--contact-hessian", contact_hessian, "self-contact Hessian: auto (termwise without colliders, projected with them) | termwise | projected | "
                  "gauss-newton")
      ->capture_default_str();
  run->add_option("--newton-rtol", cfg.scene.newton_rtol,
                  "Newton stops when the next correction is below this fraction of the first (0: off)")
      ->capture_default_str();
  run->add_option("--newton-max", cfg.scene.newton_max_iters,
                  "Newton iterations at most per step (a step that reaches it goes on from where it stopped)")
      ->check(CLI::Range(1, 1000))
      ->capture_default_str();
  std::string preconditioner = "auto";
  run->add_option("--preconditioner", preconditioner,
                  "PCG preconditioner: auto (MAS without self-contact, block-Jacobi with it) | mas | block-jacobi")
      ->capture_default_str();
  std::string broad_phase = "auto";
  run->add_option("--broad-phase", broad_phase,
                  "self-contact broad phase, the same pairs by either: auto (lbvh, on the CPU or on the device with "
                  "CUDA) | lbvh | embree (Embree's BVH collide on the CPU)")
      ->capture_default_str();
  run->add_option("--compression-ratio", cfg.scene.compression_ratio,
                  "compressive / tensile stretch stiffness (0, 1]; 1: no buckling model")
      ->capture_default_str();
  double grip_force_limit = cfg.scene.grip_force_limit;
  run->add_option("--grip-force-limit", grip_force_limit,
                  "most a grip pulls on one held vertex, N (0: no limit)")
      ->capture_default_str();
  run->add_option("--jaw-radius", cfg.grippers.jaw_radius,
                  "pseudo mode: a closing gripper takes the vertices within this distance, m (at least the nearest)")
      ->capture_default_str();
  run->add_flag("--icp", cfg.icp, "refine the capture's camera transform by ICP on the first frame");
  run->add_flag("--no-self-contact", no_self_contact, "turn cloth self-contact off (faster, may interpenetrate)");
  run->add_flag("--no-plots", no_plots, "do not draw the PNG plots");
  run->add_option("--mesh-every", cfg.mesh_interval, "write OUT/meshes/t_<ms>.obj every S seconds (0: none)")
      ->capture_default_str();
  run->add_flag("--quiet", quiet, "no progress bar");
  std::string label;
  run->add_option("--label", label, "with --server: free text kept with the job's report");

  std::string sim_path, real_path;
  bool json = false;
  auto* met = app.add_subcommand("metrics", "RGBench's sim-to-real metrics between two point clouds");
  met->add_option("--sim", sim_path, "simulated cloud (PCD, PLY or OBJ; vertex order matters for sim_stab)")
      ->required();
  met->add_option("--real", real_path, "real cloud (PCD, PLY or OBJ), same frame")->required();
  met->add_flag("--json", json, "print one JSON object");
  int surface_samples = 0;
  met->add_option("--surface", surface_samples,
                  "also compare two OBJ meshes as surfaces (Euclidean, m): this many area-sampled points of each to "
                  "the other's nearest triangle (surface_cd_s2r/r2s, surface_hd_s2r/r2s); for meshes refined "
                  "differently, whose vertices weigh the finer regions more")
      ->check(CLI::Range(0, 5000000));

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

  gd::experiment::ConvergenceConfig conv;
  std::string conv_vertices = "1000,2000,4000", conv_dts;
  bool conv_quiet = false, conv_no_plots = false;
  auto* cvg = app.add_subcommand("converge", "mesh-convergence study: one task at several resolutions (or time "
                                             "steps, --dts), shapes compared with the finest run's");
  cvg->add_option("--garment", conv.base.garment, "garment type (generated at each vertex count)")->capture_default_str();
  cvg->add_option("--material", conv.base.material, "fabric")->capture_default_str();
  cvg->add_option("--task", conv.base.task, "grasp | fold | fling")->capture_default_str();
  cvg->add_option("--vertices", conv_vertices, "comma-separated target vertex counts; the largest is the reference")
      ->capture_default_str();
  cvg->add_option("--snapshot-every", conv.snapshot_interval,
                  "also compare the shapes every S seconds along the runs (0: final shapes only)")
      ->capture_default_str();
  cvg->add_option("--samples", conv.samples, "surface points sampled per shape")->capture_default_str();
  cvg->add_option("--draws", conv.draws,
                  "meshes per resolution: draws 1, 2, 3, 4... at 2.5% more, 2.5% fewer, 5% more, 5% fewer... "
                  "vertices; > 1 also measures the spread between meshes of one resolution (the floor of a "
                  "multi-stable outcome)")
      ->capture_default_str();
  cvg->add_option("--jobs", conv.jobs,
                  "runs at once, each on its own threads (--threads each; by default the cores divided among "
                  "the jobs); the results are those of one run after another")
      ->capture_default_str();
  cvg->add_option("--dt", conv.base.scene.dt, "time step, s")->capture_default_str();
  cvg->add_option("--dts", conv_dts,
                  "comma-separated time steps, s: a time-step study instead, one vertex count (--vertices N) at "
                  "each step, compared with the smallest step's run");
  cvg->add_option("--time-scale", conv.base.task_params.time_scale, "speed factor of the task's slow parts")
      ->capture_default_str();
  cvg->add_option("--settle", conv.base.settle_after, "seconds simulated after the trajectory ends")->capture_default_str();
  cvg->add_option("--compression-ratio", conv.base.scene.compression_ratio,
                  "compressive / tensile stretch stiffness (0, 1]; 1: no buckling model")
      ->capture_default_str();
  cvg->add_option("--jaw-radius", conv.base.grippers.jaw_radius,
                  "pseudo mode: a closing gripper holds the cloth within this distance, m")
      ->capture_default_str();
  cvg->add_option("--threads", conv.base.scene.threads, "CPU threads (0: all)");
  cvg->add_option("--out", conv.base.out_dir, "output directory")->required();
  cvg->add_flag("--no-plots", conv_no_plots, "do not draw the PNG plots");
  cvg->add_flag("--quiet", conv_quiet, "no progress bars");

  gd::cli::RemoteCommands remote(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help (0) as CLI11 has it; a flag or value it refuses is bad input, exit 2 like the rest
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    gd::log();  // the logger reads GD_LOG_LEVEL
    for (const std::string& kv : garment_params) cfg.garment_params.insert(gd::cli::parse_name_value(kv, "--garment-param"));
    for (const std::string& kv : material_params)
      cfg.material_params.insert(gd::cli::parse_name_value(kv, "--material-param"));
    cfg.robot.lift_max_tilt = lift_max_tilt_deg * M_PI / 180;
    for (const std::string& knot : grip_schedule)
      cfg.robot.grip_force_schedule.push_back(gd::cli::parse_knot(knot, "--grip-force-schedule"));
    std::map<std::string, double> task_param_values;
    for (const std::string& kv : task_params) {
      const auto [name, value] = gd::cli::parse_name_value(kv, "--task-param");
      gd::tasks::set_task_param(cfg.task_params, name, value);  // an unknown name is refused here
      task_param_values[name] = value;
    }
    if (!server.empty() && *run) {
      for (const char* local_only : {"--experiment-library", "--shoulder-index", "--backend", "--threads", "--deterministic", "--garment-position",
                                     "--contact-hessian", "--preconditioner", "--broad-phase", "--newton-rtol", "--newton-max", "--no-plots", "--mesh-every",
                                     "--compression-ratio", "--grip-force-limit", "--jaw-radius", "--urdf-package-path",
                                     "--no-link-colliders", "--grip-force-schedule", "--independent-pads",
                                     "--pad-samples", "--no-pad-samples"})
        if (run->count(local_only) > 0)
          throw gd::sim::InputError(std::string(local_only) + " is not available with --server (the server decides)");
      gd::cli::RemoteRun r;
      const bool obj = cfg.garment.size() > 4 && cfg.garment.substr(cfg.garment.size() - 4) == ".obj";
      (obj ? r.garment_obj : r.job.garment) = cfg.garment;
      r.job.material = cfg.material;
      r.job.task = cfg.task;
      r.job.mode = cfg.mode;
      if (!cfg.robot.urdf.empty()) {  // robot mode: the local URDF's text goes with the job
        std::ifstream f(cfg.robot.urdf, std::ios::binary);
        if (!f) throw gd::sim::InputError("--urdf: cannot read '" + cfg.robot.urdf + "'");
        r.job.robot.urdf.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
      }
      if (run->count("--grip-force") > 0) r.job.robot.grip_force = cfg.robot.grip_force;
      if (run->count("--finger-friction") > 0) r.job.robot.finger_friction = cfg.robot.finger_friction;
      if (run->count("--pad-stiffness") > 0) r.job.robot.pad_stiffness = cfg.robot.pad_stiffness;
      if (run->count("--lift-max-tilt") > 0) r.job.robot.lift_max_tilt_deg = lift_max_tilt_deg;
      if (cfg.place_within_reach) r.job.robot.place_within_reach = true;
      r.job.vertices = cfg.vertices;
      r.job.garment_params = cfg.garment_params;
      r.job.task_params = task_param_values;
      r.job.material_params = cfg.material_params;
      r.job.capture = cfg.capture_dir;
      r.job.icp = cfg.icp;
      r.job.label = label;
      if (run->count("--dt") > 0) r.job.dt = cfg.scene.dt;
      if (run->count("--time-scale") > 0) r.job.time_scale = cfg.task_params.time_scale;
      if (run->count("--settle") > 0) r.job.settle = cfg.settle_after;
      if (run->count("--refine-grasp") > 0) r.job.refine_grasp_edge = cfg.refine_grasp_edge;
      if (run->count("--refine-grasp-radius") > 0) r.job.refine_grasp_radius = cfg.refine_grasp_radius;
      if (no_self_contact) r.job.self_contact = false;
      r.trajectory_file = cfg.trajectory_file;
      r.out_dir = cfg.out_dir;
      r.quiet = quiet;
      return gd::cli::run_remote(server, gd::cli::client_options(connection), r);
    }
    if (remote.selected()) {
      if (server.empty()) throw gd::sim::InputError("this command talks to a server: give --server HOST:PORT");
      return remote.execute(server, gd::cli::client_options(connection), connection);
    }
    if (!server.empty()) throw gd::sim::InputError("--server goes with run or a remote command, not this one");
    if (*run) {
      if (no_self_contact) cfg.scene.self_contact = false;
      if (no_plots) cfg.plots = false;
      cfg.scene.grip_force_limit = grip_force_limit == 0 ? INFINITY : grip_force_limit;  // < 0: validate() says
      if (shoulders.size() == 2) cfg.shoulder_vertices = {shoulders[0], shoulders[1]};
      if (!gd::sim::contact_hessian_from_name(contact_hessian, &cfg.scene.contact_hessian))
        throw gd::sim::InputError("unknown --contact-hessian '" + contact_hessian +
                                  "'; use auto, termwise, projected or gauss-newton");
      if (preconditioner == "mas") cfg.scene.preconditioner = gd::sim::PreconditionerKind::kMas;
      else if (preconditioner == "block-jacobi") cfg.scene.preconditioner = gd::sim::PreconditionerKind::kBlockJacobi;
      else if (preconditioner == "auto") cfg.scene.preconditioner = gd::sim::PreconditionerKind::kAuto;
      else throw gd::sim::InputError("unknown --preconditioner '" + preconditioner + "'; use auto, mas or block-jacobi");
      if (broad_phase == "embree") cfg.scene.broad_phase = gd::sim::BroadPhaseKind::kEmbree;
      else if (broad_phase == "lbvh") cfg.scene.broad_phase = gd::sim::BroadPhaseKind::kLbvh;
      else if (broad_phase == "auto") cfg.scene.broad_phase = gd::sim::BroadPhaseKind::kAuto;
      else throw gd::sim::InputError("unknown --broad-phase '" + broad_phase + "'; use auto, embree or lbvh");
      if (garment_position.size() == 3)
        cfg.garment_position = gd::sim::Vec3(garment_position[0], garment_position[1], garment_position[2]);
      if (backend == "cpu") cfg.scene.backend = gd::sim::BackendKind::kCpu;
      else if (backend == "cuda") cfg.scene.backend = gd::sim::BackendKind::kCuda;
      else if (backend == "auto") cfg.scene.backend = gd::sim::BackendKind::kAuto;
      else throw gd::sim::InputError("unknown backend '" + backend + "'; use cpu, cuda or auto");
      return cmd_run(cfg, quiet);
    }
    if (*cvg) {
      conv.vertices = number_list<int>(conv_vertices, [](const std::string& v, size_t* used) { return std::stoi(v, used); },
                                       "--vertices takes comma-separated integers");
      conv.dts = number_list<double>(conv_dts, [](const std::string& v, size_t* used) { return std::stod(v, used); },
                                     "--dts takes comma-separated time steps in seconds");
      if (conv_no_plots) conv.base.plots = false;
      return cmd_converge(conv, conv_quiet);
    }
    if (*syn) {
      if (ref_no_self_contact) ref.scene.self_contact = false;
      ref.out_dir = syn_out;
      const auto c = gd::experiment::make_synthetic_capture(ref, sco, syn_out);
      std::printf("wrote %d frames (%.2f s) to %s\n", c.frames, c.duration, c.dir.c_str());
      return 0;
    }
    return cmd_metrics(sim_path, real_path, json, surface_samples);
  } catch (const gd::ClientError& e) {
    return gd::cli::report_client_error(e);
  } catch (const gd::sim::InputError& e) {
    std::fprintf(stderr, "gd: error: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gd: error: %s\n", e.what());
    return 2;
  }
}
