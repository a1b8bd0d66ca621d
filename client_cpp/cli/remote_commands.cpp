#include "remote_commands.h"

#include <cstdio>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <memory>
#include <sstream>
#include <unistd.h>
#include <nlohmann/json.hpp>

#include "array_files.h"
#include "experiment/experiment.h"
#include "experiment/progress.h"
#include "run_summary.h"
#include "sim/demand.h"

namespace gd::cli {

namespace {

std::string join(const std::vector<std::string>& items, const char* sep) {
  std::string s;
  for (const auto& i : items) s += (s.empty() ? "" : sep) + i;
  return s;
}

/// Writes the report's files under `dir` (and summary.json when the server listed no such file);
/// names with an absolute path or ".." are refused. Returns how many files were written.
int write_report_files(const Report& report, const std::string& dir) {
  int written = 0;
  bool has_summary = false;
  for (const auto& f : report.files) {
    const std::filesystem::path rel(f.name);
    bool safe = !f.name.empty() && rel.is_relative();
    for (const auto& part : rel) safe = safe && part != "..";
    if (!safe) throw sim::InputError("the server sent a report file named '" + f.name + "'; refusing to write it");
    write_file((std::filesystem::path(dir) / rel).string(), f.data);
    has_summary = has_summary || f.name == "summary.json";
    ++written;
  }
  if (!has_summary && !report.summary_json.empty()) {
    write_file((std::filesystem::path(dir) / "summary.json").string(), report.summary_json);
    ++written;
  }
  return written;
}

void print_job(const JobInfo& j) {
  std::printf("%s  %-11s %5.1f%%  %s / %s / %s%s%s  created %s%s%s\n", j.id.c_str(), job_status_name(j.status),
              100.0 * j.progress, j.garment.c_str(), j.material.c_str(), j.task.c_str(),
              j.label.empty() ? "" : "  label: ", j.label.c_str(), j.created_at.c_str(),
              j.finished_at.empty() ? "" : ("  finished " + j.finished_at).c_str(),
              j.message.empty() ? "" : ("  (" + j.message + ")").c_str());
}

const char* health_name(HealthStatus h) {
  switch (h) {
    case HealthStatus::kServing: return "SERVING";
    case HealthStatus::kNotServing: return "NOT_SERVING";
    case HealthStatus::kServiceUnknown: return "SERVICE_UNKNOWN";
    default: return "UNKNOWN";
  }
}

}  // namespace

int report_client_error(const ClientError& e) {
  if (e.code() == StatusCode::kUnavailable) {
    std::fprintf(stderr, "gd: the server is unreachable (%s: %s)\n", e.rpc().c_str(), e.message().c_str());
    return kExitRpcError;
  }
  std::fprintf(stderr, "gd: error: %s\n", e.what());
  return e.code() == StatusCode::kInvalidArgument || e.code() == StatusCode::kNotFound ? kExitBadInput
                                                                                       : kExitRpcError;
}

ClientOptions client_options(const ConnectionFlags& f) {
  ClientOptions o;
  auto text = [](const std::string& path, const char* flag) {
    if (!std::filesystem::is_regular_file(path))
      throw gd::sim::InputError(std::string(flag) + ": no file '" + path + "'");
    return read_file(path);
  };
  std::string token_file = f.token_file;
  const char* flag = "--token-file";
  if (token_file.empty() && std::getenv("GD_TOKEN_FILE")) {
    token_file = std::getenv("GD_TOKEN_FILE");
    flag = "GD_TOKEN_FILE";
  }
  if (!token_file.empty()) {
    std::istringstream lines(text(token_file, flag));
    std::string line;
    while (o.token.empty() && std::getline(lines, line)) {  // the first token line, trimmed
      const auto a = line.find_first_not_of(" \t\r"), b = line.find_last_not_of(" \t\r");
      if (a != std::string::npos && line[a] != '#') o.token = line.substr(a, b - a + 1);
    }
    if (o.token.empty()) throw gd::sim::InputError(std::string(flag) + ": '" + token_file + "' holds no token");
  }
  o.tls = f.tls || !f.tls_ca.empty();
  if (!f.tls_ca.empty()) o.tls_root_certificates = text(f.tls_ca, "--tls-ca");
  if (f.tls_cert.empty() != f.tls_key.empty()) throw gd::sim::InputError("give both --tls-cert and --tls-key");
  if (!f.tls_cert.empty()) {
    o.tls = true;
    o.tls_client_certificate = text(f.tls_cert, "--tls-cert");
    o.tls_client_key = text(f.tls_key, "--tls-key");
  }
  return o;
}

int run_remote(const std::string& server, const ClientOptions& options, const RemoteRun& run) {
  Client client(server, options);
  JobSpec job = run.job;
  if (!run.garment_obj.empty()) {
    const auto mesh = client.upload_mesh(std::filesystem::path(run.garment_obj).stem().string(),
                                         read_file(run.garment_obj));
    std::fprintf(stderr, "uploaded %s as mesh %s (%d vertices)\n", run.garment_obj.c_str(), mesh.id.c_str(),
                 mesh.vertices);
    job.garment.clear();
    job.mesh_id = mesh.id;
  }
  if (!run.trajectory_file.empty()) {
    job.trajectory = read_file(run.trajectory_file);
    const auto ext = std::filesystem::path(run.trajectory_file).extension().string();
    job.trajectory_format = ext == ".json" || ext == ".JSON" ? "json" : "csv";
  }
  const std::string id = client.submit_job(job);
  std::fprintf(stderr, "job %s submitted to %s\n", id.c_str(), server.c_str());

  std::unique_ptr<experiment::ProgressBar> bar;
  const JobInfo last = client.watch_job(id, [&](const JobInfo& j) {
    if (run.quiet || j.status != JobStatus::kRunning || j.end_time <= 0) return;
    if (!bar) bar = std::make_unique<experiment::ProgressBar>(j.end_time, "s");
    bar->update(j.sim_time, "(server)");
  });
  if (bar) bar->finish();

  const Report report = client.get_report(id, /*include_files=*/true);
  const int n = write_report_files(report, run.out_dir);
  std::fprintf(stderr, "job %s %s; %d report files written to %s\n", id.c_str(), job_status_name(last.status), n,
               run.out_dir.c_str());
  if (!report.summary_json.empty()) {
    const auto summary = nlohmann::json::parse(report.summary_json, nullptr, /*allow_exceptions=*/false);
    if (!summary.is_discarded()) print_run_summary(summary, run.out_dir);
  }
  if (last.status != JobStatus::kSucceeded) {
    std::fprintf(stderr, "gd: job %s %s: %s\n", id.c_str(), job_status_name(last.status), last.message.c_str());
    return kExitFailed;
  }
  return kExitOk;
}

std::pair<std::string, double> parse_name_value(const std::string& name_value, const std::string& flag) {
  const size_t eq = name_value.find('=');
  const std::string name = name_value.substr(0, eq);
  const std::string value = eq == std::string::npos ? "" : name_value.substr(eq + 1);
  size_t used = 0;
  double v = 0;
  try {
    v = std::stod(value, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (name.empty() || value.empty() || used != value.size())
    throw sim::InputError(flag + " takes NAME=VALUE with a number, e.g. " + flag + " length=0.5 (got '" + name_value +
                          "')");
  return {name, v};
}

std::array<double, 2> parse_knot(const std::string& text, const std::string& flag) {
  const size_t colon = text.find(':');
  std::array<double, 2> knot{0, 0};
  bool ok = colon != std::string::npos && colon > 0 && colon + 1 < text.size();
  for (int k = 0; ok && k < 2; ++k) {
    const std::string part = k == 0 ? text.substr(0, colon) : text.substr(colon + 1);
    size_t used = 0;
    try {
      knot[k] = std::stod(part, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    ok = used == part.size();
  }
  if (!ok) throw sim::InputError(flag + " takes T:VALUE pairs of numbers, e.g. " + flag + " 8.5:10 14.5:0.1 (got '" + text + "')");
  return knot;
}

RemoteCommands::RemoteCommands(CLI::App& app) {
  info_ = app.add_subcommand("info", "server version, backend, limits, load and health (needs --server)");
  garments_ = app.add_subcommand("garments", "garment types and uploaded meshes of the server (needs --server)");
  materials_ = app.add_subcommand("materials", "the server's fabric library (needs --server)");

  create_ = app.add_subcommand("create", "create scenes on the server; prints their ids (needs --server)");
  create_->add_option("--garment", spec_.garment, "garment type (gd --server S garments lists them)");
  create_->add_option("--mesh", spec_.mesh_id, "an uploaded mesh id instead of a garment type");
  create_->add_option("--material", spec_.material, "fabric")->capture_default_str();
  create_->add_option("--vertices", spec_.vertices, "target vertex count")->capture_default_str();
  create_->add_option("--count", spec_.count, "identical scenes to create")->capture_default_str();
  create_->add_option("--seed", spec_.seed, "initial randomisation seed (0: none)")->capture_default_str();
  create_->add_option("--mode", spec_.mode, "pseudo | fixed_point | robot")->capture_default_str();
  create_->add_option("--urdf", urdf_, "robot mode: the arms' URDF file, sent to the server (default: the server's "
                                       "--robot-urdf)");
  create_->add_option("--dt", dt_, "time step, s (default: the server's)");
  create_->add_option("--yaw-deg", spec_.yaw_deg, "seeded yaw randomisation, degrees");
  create_->add_option("--offset", spec_.offset_m, "seeded x/y offset randomisation, m");
  create_->add_flag("--no-self-contact", no_self_contact_, "turn cloth self-contact off");
  create_->add_option("--garment-param", garment_params_,
                      "a size of a generated garment, NAME=VALUE (repeatable; names in docs/garments.md)");
  create_->add_option("--material-param", material_params_,
                      "a parameter of the material replaced, NAME=VALUE in catalogue units (repeatable; "
                      "e.g. stretch_g_s2=230000; names in docs/materials.md)");

  step_ = app.add_subcommand("step", "step scenes in one batched call (needs --server)");
  step_->add_option("--ids", ids_, "scene ids, comma-separated")->delimiter(',')->required();
  step_->add_option("--substeps", substeps_, "steps per scene")->capture_default_str();
  step_->add_option("--out", step_out_, "write the first scene's positions (.npy or .ply)");

  report_ = app.add_subcommand("report", "a job's status and summary; its files with --out (needs --server)");
  report_->add_option("job", job_id_, "job id")->required();
  report_->add_option("--out", report_out_, "directory to write the report's files into");
  report_->add_flag("--open", report_open_,
                    "also write the report as one HTML page (report.html in --out, default ./report-JOB; its "
                    "animation drawn here if the server drew none) and open it in a browser where one can show");

  cancel_ = app.add_subcommand("cancel", "cancel a queued or running job (needs --server)");
  cancel_->add_option("job", job_id_, "job id")->required();

  reports_ = app.add_subcommand("reports", "list stored job reports, newest first (needs --server)");
  reports_->add_option("--limit", limit_, "at most this many")->capture_default_str();
  reports_->add_option("--offset", offset_, "skip this many")->capture_default_str();

  destroy_ = app.add_subcommand("destroy", "destroy scenes (needs --server)");
  destroy_->add_option("--ids", ids_, "scene ids, comma-separated")->delimiter(',')->required();

  upload_ = app.add_subcommand("upload", "upload an OBJ mesh; prints its id (needs --server)");
  upload_->add_option("file", upload_file_, "Wavefront OBJ file")->required();
  upload_->add_option("--name", upload_name_, "name kept with the mesh (default: the file's stem)");

  view_ = app.add_subcommand("view", "watch scenes or a running job in a live 3D web page (needs --server and the "
                                     "Python client with its viewer extra: pip install 'garmentdynamics[viewer]'; "
                                     "docs/viewer.md)");
  auto* view_ids = view_->add_option("--ids,--scene", ids_, "scene ids, comma-separated")->delimiter(',');
  auto* view_job = view_->add_option("--job", view_job_, "a queued or running job (SubmitJob's id) instead of scenes");
  view_ids->excludes(view_job);
  view_job->excludes(view_ids);
  view_->add_option("--port", view_port_, "port of the page (0: a free one)")->capture_default_str();
  view_->add_option("--host", view_host_, "address the page is served on")->capture_default_str();
  view_->add_option("--every", view_every_, "a frame every k-th step of a scene")->capture_default_str();
  view_->add_option("--screenshot", view_screenshot_, "write a PNG of the page (headless Chromium) and exit");
  view_->add_option("--wait", view_wait_, "--screenshot: seconds of page time first")->capture_default_str();
}

bool RemoteCommands::selected() const {
  for (const CLI::App* c :
       {info_, garments_, materials_, create_, step_, report_, cancel_, reports_, destroy_, upload_, view_})
    if (c->parsed()) return true;
  return false;
}

int RemoteCommands::execute(const std::string& server, const ClientOptions& options, const ConnectionFlags& flags) {
  Client client(server, options);
  if (info_->parsed()) return do_info(client);
  if (garments_->parsed()) return do_garments(client);
  if (materials_->parsed()) return do_materials(client);
  if (create_->parsed()) return do_create(client);
  if (step_->parsed()) return do_step(client);
  if (report_->parsed()) return do_report(client);
  if (cancel_->parsed()) return do_cancel(client);
  if (reports_->parsed()) return do_reports(client);
  if (destroy_->parsed()) return do_destroy(client);
  if (upload_->parsed()) return do_upload(client);
  if (view_->parsed()) return do_view(client, server, flags);
  throw sim::InputError("no remote command given");
}

int RemoteCommands::do_view(Client& c, const std::string& server, const ConnectionFlags& flags) {
  if (ids_.empty() && view_job_.empty()) throw sim::InputError("view: give the scenes (--ids) or a job (--job)");
  // Unknown scenes: NOT_FOUND here, before a page is served (a job: the viewer's stream says why).
  if (view_job_.empty()) (void)c.get_state(ids_);
  const char* env_python = std::getenv("GD_PYTHON");
  const std::string python = env_python && *env_python ? env_python : "python3";
  std::vector<std::string> args{python, "-m", "garmentdynamics.viewer", "--server", server,
                                "--port", std::to_string(view_port_), "--host", view_host_,
                                "--every", std::to_string(view_every_)};
  for (const std::string& id : ids_) args.insert(args.end(), {"--scene", id});
  if (!view_job_.empty()) args.insert(args.end(), {"--job", view_job_});
  if (!view_screenshot_.empty()) args.insert(args.end(), {"--screenshot", view_screenshot_, "--wait", std::to_string(view_wait_)});
  if (!flags.token_file.empty()) args.insert(args.end(), {"--token-file", flags.token_file});
  if (flags.tls || !flags.tls_ca.empty()) args.emplace_back("--tls");
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  std::fflush(stdout);
  execvp(argv[0], argv.data());  // returns only on failure
  throw sim::InputError("view: cannot run " + python + " (" + std::strerror(errno) +
                        "); set GD_PYTHON to a Python with the client installed: pip install 'garmentdynamics[viewer]'");
}

int RemoteCommands::do_info(Client& c) {
  const ServerInfo s = c.server_info();
  std::printf("server %s: GarmentDynamics %s, backend %s, %d threads\n", c.target().c_str(), s.version.c_str(),
              s.backend.c_str(), s.threads);
  std::printf("scenes %d / %d, max vertices per scene %d, jobs running %d, health %s\n", s.scenes, s.max_scenes,
              s.max_vertices, s.jobs_running, health_name(c.health()));
  return kExitOk;
}

int RemoteCommands::do_garments(Client& c) {
  const GarmentCatalog g = c.list_garments();
  for (const auto& t : g.garments) std::printf("%s\n", t.c_str());
  for (const auto& m : g.meshes)
    std::printf("%s  %s  (uploaded: %d vertices, %d triangles)\n", m.id.c_str(), m.name.c_str(), m.vertices,
                m.triangles);
  return kExitOk;
}

int RemoteCommands::do_materials(Client& c) {
  std::printf("%-24s %14s %12s\n", "material", "density kg/m2", "thickness mm");
  for (const auto& m : c.list_materials())
    std::printf("%-24s %14.4f %12.3f\n", m.name.c_str(), m.density, 1e3 * m.thickness);
  return kExitOk;
}

int RemoteCommands::do_create(Client& c) {
  if (spec_.garment.empty() == spec_.mesh_id.empty())
    throw sim::InputError("create: give exactly one of --garment TYPE or --mesh ID");
  if (create_->count("--dt") > 0) spec_.settings.dt = dt_;
  if (no_self_contact_) spec_.settings.self_contact = false;
  if (!urdf_.empty()) {
    std::ifstream f(urdf_, std::ios::binary);
    if (!f) throw sim::InputError("--urdf: cannot read '" + urdf_ + "'");
    spec_.robot.urdf.assign(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
  }
  for (const std::string& kv : garment_params_) spec_.garment_params.insert(parse_name_value(kv, "--garment-param"));
  for (const std::string& kv : material_params_)
    spec_.material_params.insert(parse_name_value(kv, "--material-param"));
  const CreatedScenes s = c.create_scenes(spec_);
  std::fprintf(stderr, "created %zu scene(s): %d vertices, %zu triangles, dt %g s, backend %s\n", s.ids.size(),
               s.info.vertex_count, s.info.triangles.size() / 3, s.info.dt, s.info.backend.c_str());
  for (const auto& id : s.ids) std::printf("%s\n", id.c_str());
  return kExitOk;
}

int RemoteCommands::do_step(Client& c) {
  if (substeps_ < 1) throw sim::InputError("step: --substeps must be at least 1");
  StepOptions opt;
  opt.substeps = substeps_;
  // Positions are only needed for --out; the batch comes back lighter without them.
  opt.omit_positions = step_out_.empty();
  const auto states = c.step(ids_, {}, opt);
  bool any_failed = false;
  for (const auto& s : states) {
    std::printf("%s  t %.4f s  steps %lld  %.1f ms  newton %d  pcg %d  contacts %d%s%s\n", s.id.c_str(), s.time,
                static_cast<long long>(s.steps), s.stats.wall_ms, s.stats.newton_iterations,
                s.stats.pcg_iterations, s.stats.active_contacts, s.failed ? "  FAILED: " : "",
                s.failed ? s.failure.c_str() : "");
    any_failed = any_failed || s.failed;
  }
  if (!step_out_.empty() && !states.empty()) {
    write_positions(step_out_, states.front().positions);
    std::fprintf(stderr, "wrote %s (%zu vertices of %s)\n", step_out_.c_str(), states.front().positions.size() / 3,
                 states.front().id.c_str());
  }
  return any_failed ? kExitFailed : kExitOk;
}

int RemoteCommands::do_report(Client& c) {
  if (report_open_ && report_out_.empty()) report_out_ = "report-" + job_id_;
  const Report r = c.get_report(job_id_, /*include_files=*/!report_out_.empty());
  print_job(r.job);
  if (!r.file_names.empty()) std::printf("files: %s\n", join(r.file_names, ", ").c_str());
  if (!r.summary_json.empty()) std::printf("%s\n", r.summary_json.c_str());
  if (!report_out_.empty()) {
    const int n = write_report_files(r, report_out_);
    std::fprintf(stderr, "wrote %d file(s) to %s\n", n, report_out_.c_str());
  }
  if (report_open_) {
    namespace fs = std::filesystem;
    const fs::path dir(report_out_);
    if (fs::exists(dir / "animation.npy") && !fs::exists(dir / "animation.gif"))
      experiment::run_plot_script("plot_animation.py", report_out_);
    if (!experiment::run_plot_script("report_html.py", report_out_))
      throw sim::InputError("report --open: could not write report.html (needs Python; set GD_PYTHON)");
    const std::string page = fs::absolute(dir / "report.html").string();
    std::printf("report: %s\n", page.c_str());
    const char* display = std::getenv("DISPLAY");
    if (display && *display && std::system("command -v xdg-open >/dev/null 2>&1") == 0)
      (void)std::system(("xdg-open '" + page + "' >/dev/null 2>&1 &").c_str());
  }
  return r.job.status == JobStatus::kSucceeded ? kExitOk : kExitFailed;
}

int RemoteCommands::do_cancel(Client& c) {
  const JobInfo j = c.cancel_job(job_id_);
  print_job(j);
  if (j.status != JobStatus::kCancelled)
    std::fprintf(stderr, "job %s stops at its next step\n", j.id.c_str());
  return kExitOk;
}

int RemoteCommands::do_reports(Client& c) {
  const ReportList list = c.list_reports(limit_, offset_);
  for (const auto& j : list.jobs) print_job(j);
  std::printf("(%zu of %d reports)\n", list.jobs.size(), list.total);
  return kExitOk;
}

int RemoteCommands::do_destroy(Client& c) {
  std::printf("destroyed %d scene(s)\n", c.destroy(ids_));
  return kExitOk;
}

int RemoteCommands::do_upload(Client& c) {
  const std::string name = upload_name_.empty() ? std::filesystem::path(upload_file_).stem().string() : upload_name_;
  const UploadedMesh m = c.upload_mesh(name, read_file(upload_file_));
  std::fprintf(stderr, "uploaded %s: %d vertices, %d triangles\n", upload_file_.c_str(), m.vertices, m.triangles);
  std::printf("%s\n", m.id.c_str());
  return kExitOk;
}

}  // namespace gd::cli
