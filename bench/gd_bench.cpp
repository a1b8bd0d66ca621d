/// \file
/// gd-bench: step-time benchmark of the simulator on hanging cotton squares of growing size.
///
///   gd-bench [--json] [--steps N] [--sizes 5000,10000,20000,40000] [--backend cpu|cuda|auto|cpu-gpu-paths]
///            [--threads N] [--side 0.5] [--warmup 3] [--max-seconds 30] [--material cotton]
///
/// Each case ("drape/<N>") is a cotton square of side 0.5 m meshed by make_rect with a spacing
/// chosen to give about N vertices, lifted to z = 0.6 m and pinned at its two top corners (the
/// vertices within 1 cm of (0, side) and (side, side)), with SceneOptions defaults otherwise.
/// After a few warm-up steps, N timed steps give the mean wall time per step and the mean Newton
/// and PCG iterations per step (and the fraction of steps whose Newton solve converged). A case whose warm-up and timed steps run past --max-seconds
/// (default 30 s) stops early, after at least one timed step, and reports the steps it timed
/// ("steps"); this keeps the default run near 3 minutes on 2 CPU cores. --max-seconds 0 times
/// exactly N steps in every case.
///
/// Without --json: a table on stdout. With --json: exactly one JSON array on stdout. Progress
/// always goes to stderr.
///
///   gd-bench service [--json] [--scenes 16] [--vertices 5000] [--garment towel] [--threads N]
///                    [--rounds 3] [--steps 3] [--substeps 1] [--no-self-contact] [--server-binary P]
///
/// The gRPC service against its in-process core: the same batch of scenes stepped through a
/// gd-server child process on loopback and through gd::service::ScenePool in this process,
/// interleaved; prints ms per batched step of each and their ratio (service_case.h).
///
///   gd-bench load [--json] [--clients 16] [--seconds 10] [--vertices 400] [--garment towel]
///                 [--substeps 1] [--threads N] [--server HOST:PORT] [--server-binary P]
///
/// Many clients at once, each stepping its own scene on one gd-server (a child on loopback unless
/// --server): calls and scene-steps per second, latency p50/p99/max, errors by code, the server's
/// memory (load_case.h).
///
///   gd-bench export --case drape/5000|fold/5000 --out DIR [--side 0.5] [--material cotton] [--simulate K]
///
/// Writes the case's exact scene (mesh.obj, rest.obj, scene.json; scene_export.h) for the peer
/// benchmark (bench/peers); --simulate K also steps ours K steps on one thread (ours_state.json),
/// with the solver flags given before `export` (e.g. `gd-bench --pcg-newton-fraction 0 export ...`).
///
///   gd-bench stream [--json] [--megabytes 1,4.6,16,64] [--threads N] [--repeats 30]
///
/// This machine's memory reads at one thread and at N (all cores by default), per array size:
/// the most a stage that only streams that much memory can gain from threads (stream_case.h).

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "scene_export.h"
#include "stream_case.h"
#ifndef GD_BENCH_SOLVER_ONLY  // gd-bench-solver (bench/CMakeLists.txt): the solver cases alone
#include "load_case.h"
#include "service_case.h"
#endif
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

struct CaseResult {
  std::string name;
  int vertices = 0;
  int steps = 0;  ///< timed steps actually taken
  double ms_per_step = 0;
  double newton_iters = 0;
  double pcg_iters = 0;
  double converged = 0;  ///< fraction of timed steps whose Newton solve converged
  double bytes_per_vertex = 0;
  std::string backend;
  std::string preconditioner;  ///< the one the case ran with (auto resolved)
  bool deterministic = false;  ///< SceneOptions::deterministic (--deterministic)
  std::string error;  ///< non-empty when the case failed
  bool contact = false;        ///< a self-contact case (fold/<N>)
  double contacts = 0;         ///< mean active self-contact pairs per timed step
  double broad_phase_share = 0;  ///< fraction of the step time spent in the broad phase
  double energy_evals = 0;     ///< mean objective evaluations per timed step
  gd::sim::StageTimes stage;   ///< mean seconds per timed step in each solver stage
};

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// drape/<N>: a square hanging from two pinned corners. fold/<N> (contact): the square folded in
/// half (the flap 4 mm above the base), 1 cm above the table, let fall with self-contact on.
CaseResult run_case(int target, Real side, int warmup, int steps, double max_seconds, SceneOptions opt,
                    const gd::sim::Material& mat, bool contact) {
  CaseResult r;
  r.contact = contact;
  r.name = (contact ? "fold/" : "drape/") + std::to_string(target);
  const gd::bench::BenchScene bench_scene = gd::bench::make_bench_scene(target, side, contact);
  const Mesh& mesh = bench_scene.mesh;
  r.vertices = static_cast<int>(mesh.x.size());
  opt.self_contact = contact;

  const auto t_setup = Clock::now();
  auto scene = Scene::create(mesh, mat, opt);
  if (!bench_scene.pins.empty()) scene->pin(bench_scene.pins);
  r.backend = scene->backend();
  r.preconditioner = gd::sim::preconditioner_name(opt);
  r.deterministic = opt.deterministic;
  r.bytes_per_vertex = scene->bytes_per_vertex();
  std::fprintf(stderr, "[gd-bench] %s: %d vertices on %s (setup %.2f s); %d warm-up + %d timed steps\n",
               r.name.c_str(), r.vertices, r.backend.c_str(), seconds_since(t_setup), warmup, steps);

  // The --max-seconds budget covers warm-up and timed steps: warm-up stops after half of it
  // (at least one step), the timed steps once the whole is spent (at least one step).
  const auto t_case = Clock::now();
  for (int i = 0; i < warmup; ++i) {
    if (!scene->step()) {
      r.error = "scene failed during warm-up: " + scene->failure();
      return r;
    }
    if (max_seconds > 0 && seconds_since(t_case) > 0.5 * max_seconds && i + 1 < warmup) {
      std::fprintf(stderr, "[gd-bench] %s: warm-up cut to %d step(s) (--max-seconds %.0f)\n", r.name.c_str(), i + 1,
                   max_seconds);
      break;
    }
  }

  double total_s = 0, bp_s = 0, contacts = 0, evals = 0;
  gd::sim::StageTimes stage;
  long newton = 0, pcg = 0, converged = 0;
  int done = 0;
  double last_report = seconds_since(t_case);
  for (int i = 0; i < steps; ++i) {
    const auto t0 = Clock::now();
    const bool ok = scene->step();
    total_s += seconds_since(t0);
    if (!ok) {
      r.error = "scene failed at timed step " + std::to_string(i) + ": " + scene->failure();
      break;
    }
    const auto& st = scene->last_stats();
    newton += st.newton_iters;
    pcg += st.pcg_iters;
    converged += st.converged ? 1 : 0;
    contacts += st.contacts;
    bp_s += st.broad_phase_seconds;
    evals += st.energy_evals;
    stage += st.stage;
    ++done;
    const double elapsed = seconds_since(t_case);
    if (elapsed - last_report >= 10.0 && done < steps) {
      last_report = elapsed;
      std::fprintf(stderr, "[gd-bench] %s: %d/%d steps, %.1f ms/step so far\n", r.name.c_str(), done, steps,
                   1e3 * total_s / done);
    }
    if (max_seconds > 0 && elapsed > max_seconds && done < steps) {
      std::fprintf(stderr, "[gd-bench] %s: stopping after %d of %d steps (--max-seconds %.0f)\n", r.name.c_str(),
                   done, steps, max_seconds);
      break;
    }
  }
  r.steps = done;
  if (done > 0) {
    r.ms_per_step = 1e3 * total_s / done;
    r.newton_iters = static_cast<double>(newton) / done;
    r.pcg_iters = static_cast<double>(pcg) / done;
    r.converged = static_cast<double>(converged) / done;
    r.contacts = contacts / done;
    r.broad_phase_share = total_s > 0 ? bp_s / total_s : 0;
    r.energy_evals = evals / done;
    r.stage = stage;
    r.stage *= 1.0 / done;
  }
  std::fprintf(stderr,
               "[gd-bench] %s: %.2f ms/step, %.2f Newton and %.1f PCG iterations per step, %.0f%% converged%s\n",
               r.name.c_str(), r.ms_per_step, r.newton_iters, r.pcg_iters, 100.0 * r.converged,
               r.error.empty() ? "" : " (FAILED)");
  return r;
}

std::vector<int> parse_sizes(const std::string& s) {
  std::vector<int> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item.empty()) continue;
    const int v = gd::bench::parse_vertex_count(item);
    if (v < 0) throw CLI::ValidationError("--sizes", "'" + item + "' is not a vertex count (integer >= 4)");
    out.push_back(v);
  }
  if (out.empty()) throw CLI::ValidationError("--sizes", "no sizes given");
  return out;
}

/// Per-stage milliseconds (StageTimes, s) as a JSON object.
nlohmann::json stage_json(const gd::sim::StageTimes& t) {
  nlohmann::json j = nlohmann::json::object();
  t.for_each_ms([&](const char* name, double ms) { j[name] = ms; });
  return j;
}

nlohmann::json to_json(const CaseResult& r) {
  nlohmann::json j = {{"case", r.name},
                      {"vertices", r.vertices},
                      {"steps", r.steps},
                      {"ms_per_step", r.steps > 0 ? nlohmann::json(r.ms_per_step) : nlohmann::json(nullptr)},
                      {"newton_iters", r.steps > 0 ? nlohmann::json(r.newton_iters) : nlohmann::json(nullptr)},
                      {"pcg_iters", r.steps > 0 ? nlohmann::json(r.pcg_iters) : nlohmann::json(nullptr)},
                      {"converged", r.steps > 0 ? nlohmann::json(r.converged) : nlohmann::json(nullptr)},
                      {"bytes_per_vertex", r.bytes_per_vertex},
                      {"backend", r.backend},
                      {"preconditioner", r.preconditioner},
                      {"deterministic", r.deterministic},
                      {"contact", r.contact}};
  if (r.contact) {
    j["contacts"] = r.contacts;
    j["broad_phase_share"] = r.broad_phase_share;
  }
  if (r.steps > 0) {
    j["energy_evals"] = r.energy_evals;
    j["stage_ms"] = stage_json(r.stage);
  }
  if (!r.error.empty()) j["error"] = r.error;
  return j;
}

void print_table(const std::vector<CaseResult>& rs) {
  std::printf("%-14s %9s %6s %12s %9s %9s %10s %10s %9s %8s %-8s %s\n", "case", "vertices", "steps", "ms/step",
              "newton", "pcg", "converged", "bytes/vtx", "contacts", "bp share", "backend", "precond");
  for (const auto& r : rs) {
    std::printf("%-14s %9d %6d %12.2f %9.2f %9.1f %9.0f%% %10.0f %9.0f %7.0f%% %-8s %s%s\n", r.name.c_str(), r.vertices,
                r.steps, r.ms_per_step, r.newton_iters, r.pcg_iters, 100.0 * r.converged, r.bytes_per_vertex,
                r.contacts, 100.0 * r.broad_phase_share, r.backend.c_str(), r.preconditioner.c_str(),
                r.error.empty() ? "" : ("  FAILED: " + r.error).c_str());
  }
  std::printf("(ms/step: mean wall time of a step; newton, pcg: mean iterations per step, PCG summed over "
              "Newton iterations; converged: steps whose Newton solve stopped before its cap)\n");
  std::printf("\nms per step by stage:\n%-14s", "case");
  gd::sim::StageTimes{}.for_each_ms([](const char* name, double) { std::printf(" %13s", name); });
  std::printf(" %7s\n", "evals");
  for (const auto& r : rs) {
    std::printf("%-14s", r.name.c_str());
    r.stage.for_each_ms([](const char*, double ms) { std::printf(" %13.2f", ms); });
    std::printf(" %7.2f\n", r.energy_evals);
  }
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"gd-bench: step time of hanging cotton squares (drape/<N>) and of squares folded in half falling with "
               "self-contact (fold/<N>), at growing vertex counts"};
  bool json = false;
  int steps = 20;
  int warmup = 3;
  int threads = 0;
  double side = 0.5;
  double max_seconds = 30;
  std::string sizes_arg = "5000,10000,20000,40000";
  std::string backend_arg = "auto";
  std::string material_name = "cotton";
  std::string kinds = "drape,fold";
  std::string precond_arg = "default";
  int newton_max = 0, pcg_max = 0, mas_domain = 0;
  double newton_rtol = -1, newton_atol = -1, pcg_newton_fraction = -1, pcg_tol = -1, dt = -1;
  double self_friction = -1, table_friction = -1, friction_eps = -1, compression_ratio = -1;
  std::string contact_hessian_arg = "default";
  std::string bending_hessian_arg = "default";
  std::string table_cut_arg = "on";
  std::string broad_phase_arg = "auto";
  std::string linear_solver_arg = "pcg";
  app.add_flag("--json", json, "Print one JSON array of results on stdout (and nothing else)");
  app.add_option("--steps", steps, "Timed steps per case")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--warmup", warmup, "Untimed warm-up steps per case")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--sizes", sizes_arg, "Comma-separated approximate vertex counts")->capture_default_str();
  app.add_option("--backend", backend_arg,
                 "Solver backend (cpu-gpu-paths: the CPU running the CUDA backend's code paths, atomic adds)")
      ->check(CLI::IsMember({"cpu", "cuda", "auto", "cpu-gpu-paths"}))
      ->capture_default_str();
  bool deterministic = false;
  app.add_flag("--deterministic", deterministic,
               "Assembly in a fixed order on the atomic backends (cuda, cpu-gpu-paths): SceneOptions::deterministic");
  app.add_option("--threads", threads, "CPU threads (0: OpenMP default)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--side", side, "Side of the square, m")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--material", material_name, "Material name from the library")->capture_default_str();
  app.add_option("--cases", kinds, "drape (no contact), fold (self-contact), or both")
      ->check(CLI::IsMember({"drape", "fold", "drape,fold", "fold,drape"}))
      ->capture_default_str();
  app.add_option("--max-seconds", max_seconds,
                 "Time budget per case, s, warm-up included: a case stops early, reporting the steps it timed (0: no limit)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--preconditioner", precond_arg, "PCG preconditioner (default: SceneOptions' default)")
      ->check(CLI::IsMember({"default", "auto", "block-jacobi", "mas"}))
      ->capture_default_str();
  app.add_option("--mas-domain", mas_domain, "MAS nodes per domain (0: SceneOptions' default)")
      ->check(CLI::Range(0, 64));
  app.add_option("--newton-max", newton_max, "Newton iteration cap per step (0: SceneOptions' default)")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--pcg-max", pcg_max, "PCG iteration cap per Newton iteration (0: default)")->check(CLI::NonNegativeNumber);
  app.add_option("--newton-rtol", newton_rtol, "Residual stopping rule, relative (negative: default)");
  app.add_option("--pcg-tol", pcg_tol, "PCG relative residual tolerance (negative: default)");
  app.add_option("--dt", dt, "Time step, s (negative: default)");
  app.add_option("--pcg-newton-fraction", pcg_newton_fraction,
                 "With MAS: PCG stops at this fraction of the Newton rule's threshold (0: off; negative: default)");
  const CLI::Validator finite(
      [](std::string& text) {
        double v = 0;
        return CLI::detail::lexical_cast(text, v) && std::isfinite(v) ? std::string() : "must be a finite number";
      },
      "FINITE");
  app.add_option("--self-friction", self_friction, "Cloth-cloth Coulomb coefficient (negative: the material's)")->check(finite);
  app.add_option("--table-friction", table_friction, "Cloth-table Coulomb coefficient (negative: default)")->check(finite);
  app.add_option("--friction-eps", friction_eps, "Slip speed below which friction is smoothed, m/s (negative: default)")
      ->check(finite);
  app.add_option("--newton-atol", newton_atol, "Residual stopping rule, absolute, m/s (negative: default)");
  app.add_option("--compression-ratio", compression_ratio,
                 "Compressive / tensile stretch stiffness, (0, 1] (negative: default)");
  app.add_option("--contact-hessian", contact_hessian_arg, "Self-contact barrier Hessian")
      ->check(CLI::IsMember({"default", "auto", "termwise", "projected", "gauss-newton"}))
      ->capture_default_str();
  app.add_option("--broad-phase", broad_phase_arg,
                 "Self-contact broad phase (the same pairs; auto: lbvh, on the CPU or on the device with CUDA; "
                 "embree: Embree's BVH collide on the CPU)")
      ->check(CLI::IsMember({"auto", "embree", "lbvh"}))
      ->capture_default_str();
  app.add_option("--bending-hessian", bending_hessian_arg, "Bending Hessian")
      ->check(CLI::IsMember({"default", "gauss-newton", "projected-exact"}))
      ->capture_default_str();
  app.add_option("--table-cut", table_cut_arg,
                 "Landing steps limited by the table's CCD bound may cut each vertex's motion towards the table "
                 "on its own (off: the whole step scaled by the most constrained vertex)")
      ->check(CLI::IsMember({"on", "off"}))
      ->capture_default_str();
  app.add_option("--linear-solver", linear_solver_arg,
                 "Linear solver of each Newton iteration (direct: sparse LDLT, to tell the Newton iteration's own "
                 "convergence from PCG's inexactness)")
      ->check(CLI::IsMember({"pcg", "direct"}))
      ->capture_default_str();
#ifndef GD_BENCH_SOLVER_ONLY
  gd::bench::ServiceCaseOptions svc_opt;
  bool svc_json = false, svc_no_self_contact = false;
  auto* svc = app.add_subcommand("service", "gRPC service vs. its in-process core: one batched step of many scenes");
  svc->add_flag("--json", svc_json, "Print one JSON array (one object) on stdout (and nothing else)");
  svc->add_option("--scenes", svc_opt.scenes, "Scenes in the batch")->check(CLI::PositiveNumber)->capture_default_str();
  svc->add_option("--vertices", svc_opt.vertices, "Target vertices per scene")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  svc->add_option("--garment", svc_opt.garment, "Garment type")->capture_default_str();
  svc->add_option("--material", svc_opt.material, "Material name")->capture_default_str();
  svc->add_option("--threads", svc_opt.threads, "Worker threads of the server and of the in-process pool (0: all cores)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  svc->add_option("--rounds", svc_opt.rounds, "Interleaved rounds")->check(CLI::PositiveNumber)->capture_default_str();
  svc->add_option("--steps", svc_opt.steps, "Timed batched steps per side and round")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  svc->add_option("--substeps", svc_opt.substeps, "Substeps per batched step")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  svc->add_flag("--no-self-contact", svc_no_self_contact, "Scenes without cloth self-contact");
  svc->add_option("--server-binary", svc_opt.server_binary, "gd-server to start (default: the one beside gd-bench)");

  gd::bench::LoadCaseOptions load_opt;
  bool load_json = false;
  auto* load = app.add_subcommand("load", "Many clients stepping their own scenes on one gd-server at once: throughput, latency, errors, memory");
  load->add_flag("--json", load_json, "Print one JSON array (one object) on stdout (and nothing else)");
  load->add_option("--clients", load_opt.clients, "Concurrent clients, one scene and one channel each")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  load->add_option("--seconds", load_opt.seconds, "Length of the timed window")->check(CLI::PositiveNumber)->capture_default_str();
  load->add_option("--vertices", load_opt.vertices, "Target vertices per scene")->check(CLI::PositiveNumber)->capture_default_str();
  load->add_option("--garment", load_opt.garment, "Garment type")->capture_default_str();
  load->add_option("--substeps", load_opt.substeps, "Substeps per StepScenes call")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  load->add_option("--threads", load_opt.threads, "Scene workers of the started gd-server (0: all cores)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  load->add_option("--server", load_opt.server, "HOST:PORT of a running gd-server (default: start one on loopback)");
  load->add_option("--server-binary", load_opt.server_binary, "gd-server to start (default: the one beside gd-bench)");

#endif

  gd::bench::ExportOptions exp_opt;
  auto* export_cmd =
      app.add_subcommand("export", "Write a case's scene (mesh.obj, rest.obj, scene.json) for bench/peers");
  export_cmd->add_option("--case", exp_opt.case_name, "drape/<N> or fold/<N>")->capture_default_str();
  export_cmd->add_option("--out", exp_opt.out_dir, "Output directory")->required();
  export_cmd->add_option("--side", exp_opt.side, "Side of the square, m")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  export_cmd->add_option("--material", exp_opt.material, "Material name from the library")->capture_default_str();
  export_cmd
      ->add_option("--simulate", exp_opt.simulate_steps, "Also step ours this many steps (1 thread): ours_state.json")
      ->check(CLI::NonNegativeNumber);

  gd::bench::StreamCaseOptions stream_opt;
  bool stream_json = false;
  auto* stream = app.add_subcommand(
      "stream", "Memory read rate at one thread and at N, per array size: the ceiling of a memory-bound stage's scaling");
  stream->add_flag("--json", stream_json, "Print one JSON array on stdout (and nothing else)");
  stream->add_option("--megabytes", stream_opt.megabytes, "Array sizes, MB (4.6: the Hessian's blocks of RGBench's T-shirt)")
      ->delimiter(',')
      ->check(CLI::Range(0.001, 65536.0))
      ->capture_default_str();
  stream->add_option("--threads", stream_opt.threads, "Threads of the many-thread side (0: all cores)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  stream->add_option("--repeats", stream_opt.repeats, "Passes per side and size (the best counts)")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();

  CLI11_PARSE(app, argc, argv);

  // The solver flags, shared by the timed cases and export --simulate (validated).
  auto solver_options = [&] {
    SceneOptions opt;
    opt.backend = backend_arg == "cpu"             ? gd::sim::BackendKind::kCpu
                  : backend_arg == "cuda"          ? gd::sim::BackendKind::kCuda
                  : backend_arg == "cpu-gpu-paths" ? gd::sim::BackendKind::kCpuGpuPaths
                                                   : gd::sim::BackendKind::kAuto;
    opt.threads = threads;
    opt.deterministic = deterministic;
    if (precond_arg == "mas") opt.preconditioner = gd::sim::PreconditionerKind::kMas;
    if (precond_arg == "block-jacobi") opt.preconditioner = gd::sim::PreconditionerKind::kBlockJacobi;
    if (precond_arg == "auto") opt.preconditioner = gd::sim::PreconditionerKind::kAuto;
    if (mas_domain > 0) opt.mas_domain_size = mas_domain;
    if (newton_max > 0) opt.newton_max_iters = newton_max;
    if (pcg_max > 0) opt.pcg_max_iters = pcg_max;
    if (newton_rtol >= 0) opt.newton_rtol = newton_rtol;
    if (pcg_newton_fraction >= 0) opt.pcg_newton_fraction = pcg_newton_fraction;
    if (pcg_tol > 0) opt.pcg_tol = pcg_tol;
    if (dt > 0) opt.dt = dt;
    if (newton_atol >= 0) opt.newton_atol = newton_atol;
    if (compression_ratio > 0) opt.compression_ratio = compression_ratio;
    if (self_friction >= 0) opt.self_friction = self_friction;
    if (table_friction >= 0) opt.table_friction = table_friction;
    if (friction_eps > 0) opt.friction_eps_v = friction_eps;
    if (contact_hessian_arg != "default") gd::sim::contact_hessian_from_name(contact_hessian_arg, &opt.contact_hessian);
    if (bending_hessian_arg == "gauss-newton") opt.bending_hessian = gd::sim::BendingHessianKind::kGaussNewton;
    if (bending_hessian_arg == "projected-exact") opt.bending_hessian = gd::sim::BendingHessianKind::kProjectedExact;
    if (broad_phase_arg == "lbvh") opt.broad_phase = gd::sim::BroadPhaseKind::kLbvh;
    if (broad_phase_arg == "embree") opt.broad_phase = gd::sim::BroadPhaseKind::kEmbree;
    opt.table_cut = table_cut_arg == "on";
    if (linear_solver_arg == "direct") opt.linear_solver = gd::sim::LinearSolverKind::kDirect;
    opt.validate();
    return opt;
  };

  if (*export_cmd) {
    try {
      exp_opt.options = solver_options();
      gd::bench::export_case(exp_opt);
    } catch (const std::exception& e) {
      std::fprintf(stderr, "gd-bench export: %s\n", e.what());
      return 2;
    }
    return 0;
  }

  if (*stream) {
    const auto rows = gd::bench::run_stream_case(stream_opt);
    if (stream_json) {
      nlohmann::json out = nlohmann::json::array();
      for (const auto& r : rows) out.push_back(gd::bench::to_json(r));
      std::printf("%s\n", out.dump(2).c_str());
    } else {
      std::printf("%10s %8s %16s %16s %8s\n", "MB", "threads", "1 thread GB/s", "N threads GB/s", "scaling");
      for (const auto& r : rows)
        std::printf("%10.1f %8d %16.1f %16.1f %7.2fx\n", r.megabytes, r.threads, r.one_thread_gb_s, r.threads_gb_s,
                    r.scaling);
    }
    return 0;
  }

#ifndef GD_BENCH_SOLVER_ONLY
  if (*load) {
    const auto r = gd::bench::run_load_case(load_opt);
    if (load_json) {
      std::printf("%s\n", nlohmann::json::array({gd::bench::to_json(r)}).dump(2).c_str());
    } else {
      gd::bench::print_table(r);
    }
    return r.error.empty() ? 0 : 1;
  }

  if (*svc) {
    svc_opt.self_contact = !svc_no_self_contact;
    const auto r = gd::bench::run_service_case(svc_opt);
    if (svc_json) {
      std::printf("%s\n", nlohmann::json::array({gd::bench::to_json(r)}).dump(2).c_str());
    } else {
      gd::bench::print_table(r);
    }
    return r.error.empty() ? 0 : 1;
  }
#endif

  std::vector<CaseResult> results;
  try {
    const std::vector<int> sizes = parse_sizes(sizes_arg);
    SceneOptions opt = solver_options();
    const auto lib = gd::sim::MaterialLibrary::load_default();
    const auto& mat = lib.get(material_name);
    const auto t_all = Clock::now();
    std::vector<bool> modes;
    if (kinds.find("drape") != std::string::npos) modes.push_back(false);
    if (kinds.find("fold") != std::string::npos) modes.push_back(true);
    const std::size_t total = sizes.size() * modes.size();
    std::size_t k = 0;
    for (bool contact : modes)
      for (int size : sizes) {
        std::fprintf(stderr, "[gd-bench] case %zu/%zu (%.1f s elapsed)\n", ++k, total, seconds_since(t_all));
        results.push_back(run_case(size, side, warmup, steps, max_seconds, opt, mat, contact));
      }
    std::fprintf(stderr, "[gd-bench] done in %.1f s\n", seconds_since(t_all));
  } catch (const CLI::Error& e) {
    return app.exit(e);
  } catch (const gd::sim::InputError& e) {
    std::fprintf(stderr, "gd-bench: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gd-bench: error: %s\n", e.what());
    return 1;
  }

  if (json) {
    nlohmann::json arr = nlohmann::json::array();
    for (const auto& r : results) arr.push_back(to_json(r));
    std::printf("%s\n", arr.dump(2).c_str());
  } else {
    print_table(results);
  }
  for (const auto& r : results)
    if (!r.error.empty()) return 1;
  return 0;
}
