// gd-server: parses flags, builds the server (server.h), waits for SIGTERM/SIGINT, drains, exits 0
// (1 when a second signal or a call that never finishes cuts the drain short).
#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>
#include <fstream>
#include <pthread.h>
#include <spdlog/pattern_formatter.h>
#include <thread>

#include "service/server.h"
#include "sim/log.h"

namespace {

/// %* in a pattern: the message as a JSON string body (quotes, backslashes, control characters escaped).
class JsonMessageFlag : public spdlog::custom_flag_formatter {
 public:
  void format(const spdlog::details::log_msg& msg, const std::tm&, spdlog::memory_buf_t& dest) override {
    for (char c : msg.payload) {
      switch (c) {
        case '"': dest.append(std::string_view("\\\"")); break;
        case '\\': dest.append(std::string_view("\\\\")); break;
        case '\n': dest.append(std::string_view("\\n")); break;
        case '\r': dest.append(std::string_view("\\r")); break;
        case '\t': dest.append(std::string_view("\\t")); break;
        default:
          if (static_cast<unsigned char>(c) < 0x20) {
            char buf[8];
            std::snprintf(buf, sizeof buf, "\\u%04x", c);
            dest.append(std::string_view(buf));
          } else {
            dest.push_back(c);
          }
      }
    }
  }
  std::unique_ptr<custom_flag_formatter> clone() const override { return std::make_unique<JsonMessageFlag>(); }
};

void use_json_log() {
  auto f = std::make_unique<spdlog::pattern_formatter>(spdlog::pattern_time_type::utc, std::string("\n"));
  f->add_flag<JsonMessageFlag>('*').set_pattern(
      R"({"time":"%Y-%m-%dT%H:%M:%S.%eZ","level":"%l","logger":"%n","thread":%t,"msg":"%*"})");
  gd::log().set_formatter(std::move(f));
}

}  // namespace

int main(int argc, char** argv) {
  gd::service::ServerOptions o;
  std::string backend = "cpu", log_format = "text", log_level = "info", port_file;
  CLI::App app{"gd-server: the GarmentDynamics gRPC service (docs/service.md)"};
  app.add_option("--host", o.host, "address to listen on")->capture_default_str();
  app.add_option("--port", o.port, "TCP port (0: pick a free one, printed and written to --port-file)")
      ->required()->check(CLI::Range(0, 65535));
  app.add_option("--port-file", port_file, "write the bound port to this file once listening");
  app.add_option("--data-dir", o.data_dir, "directory of the SQLite store, jobs and meshes")->required();
  app.add_option("--capture-root", o.capture_root, "jobs' captures are resolved under it (default DATA_DIR/captures)");
  app.add_option("--backend", backend, "cpu | cuda | auto")->check(CLI::IsMember({"cpu", "cuda", "auto"}))->capture_default_str();
  app.add_flag("--deterministic", o.deterministic,
               "CUDA: assembly in a fixed order instead of atomic adds, so a scene reset by seed takes the same "
               "steps bit for bit (slower; the CPU backend is deterministic either way)");
  app.add_option("--threads", o.threads, "cores to compute on: the scene worker threads, and each running job's solver threads (--threads / "
                 "--job-workers, at least 1); 0: hardware concurrency")->check(CLI::NonNegativeNumber);
  app.add_option("--max-scenes", o.max_scenes, "scenes alive at once")->check(CLI::NonNegativeNumber)->capture_default_str();
  app.add_option("--max-vertices", o.max_vertices, "vertices per scene")->check(CLI::NonNegativeNumber)->capture_default_str();
  app.add_option("--max-substeps", o.max_substeps, "substeps per StepScenes call")->check(CLI::NonNegativeNumber)->capture_default_str();
  app.add_option("--max-message-mb", o.max_message_mb, "largest message received or sent, MiB")->check(CLI::Range(1, 2000))->capture_default_str();
  app.add_option("--max-queued-frames-mb", o.max_queued_frames_mb,
                 "frames one StreamFrames subscription queues for a client that reads slower than its scenes step, MiB "
                 "(past it the oldest are dropped and counted in dropped_frames)")
      ->check(CLI::Range(1, 4096))
      ->capture_default_str();
  app.add_option("--max-streams", o.max_streams,
                 "StreamFrames and WatchJob calls open at once (a waiting one holds no thread); more are refused "
                 "(0: no limit)")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--job-workers", o.job_workers, "jobs run at once")->check(CLI::PositiveNumber)->capture_default_str();
  app.add_option("--max-job-steps", o.max_job_steps,
                 "simulation steps per job (its simulated time over dt; 0: no limit): a longer job is refused or "
                 "fails before its scene is built")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--robot-urdf", o.robot_urdf,
                 "URDF of robot mode's arms for scenes and jobs whose request sends none (e.g. RGBench's "
                 "piper_with_gripper.urdf; docs/robot.md); without it such requests are refused")
      ->check(CLI::ExistingFile);
  app.add_option("--robot-urdf-package-path", o.robot_package_paths,
                 "directory where --robot-urdf's package://NAME/... link meshes are looked for, as DIR/NAME/... or, "
                 "for a DIR named NAME, DIR/... (repeatable); meshes found nowhere leave their links without a "
                 "collider (the server's log lists them)")
      ->check(CLI::ExistingDirectory);
  app.add_flag("--plots", o.plots, "draw the PNG plots of capture jobs (needs Python with matplotlib)");
  app.add_option("--scene-lease-s", o.scene_lease_seconds,
                 "scenes that no call names for this long are destroyed (a client that died or never called "
                 "DestroyScenes); later calls get NOT_FOUND saying so; 0: never")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--mesh-lease-s", o.mesh_lease_seconds,
                 "uploaded meshes that no call uses for this long (UploadMesh, CreateScenes, SubmitJob) are "
                 "deleted; later calls naming one get NOT_FOUND saying so; 0: never")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();
  app.add_option("--grace-seconds", o.grace_seconds, "on SIGTERM: how long running jobs may still take")->check(CLI::NonNegativeNumber)->capture_default_str();
  app.add_option("--auth-token-file", o.auth_token_file,
                 "bearer tokens, one per line ('#' comments): every call but the health check must send one "
                 "(metadata 'authorization: Bearer TOKEN'); each token sees only the scenes and jobs it made")
      ->check(CLI::ExistingFile);
  app.add_option("--tls-cert", o.tls_cert, "PEM certificate chain: serve TLS (with --tls-key)")->check(CLI::ExistingFile);
  app.add_option("--tls-key", o.tls_key, "PEM private key of --tls-cert")->check(CLI::ExistingFile);
  app.add_option("--tls-client-ca", o.tls_client_ca, "PEM CA: require client certificates signed by it (mutual TLS)")
      ->check(CLI::ExistingFile);
  app.add_flag("--allow-unauthenticated", o.allow_unauthenticated,
               "listen on a non-loopback --host without --auth-token-file (a network you trust)");
  app.add_option("--log-format", log_format, "text | json (one JSON object per line)")->check(CLI::IsMember({"text", "json"}))->capture_default_str();
  app.add_option("--log-level", log_level, "trace | debug | info | warn | error")->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  o.backend = backend == "cuda" ? gd::sim::BackendKind::kCuda : backend == "auto" ? gd::sim::BackendKind::kAuto
                                                                                  : gd::sim::BackendKind::kCpu;
  if (log_format == "json") use_json_log();
  gd::log().set_level(spdlog::level::from_str(log_level));
  gd::log().flush_on(spdlog::level::info);

  // SIGTERM/SIGINT are taken by a watcher thread (sigwait), never by an asynchronous handler:
  // blocked here, before any thread starts, so every thread inherits the mask.
  sigset_t sigs;
  sigemptyset(&sigs);
  sigaddset(&sigs, SIGTERM);
  sigaddset(&sigs, SIGINT);
  pthread_sigmask(SIG_BLOCK, &sigs, nullptr);
  std::signal(SIGPIPE, SIG_IGN);

  gd::service::Status st;
  auto server = gd::service::Server::start(o, &st);
  if (!server) {
    gd::log().error("gd-server: {}", st.message());
    return 2;
  }
  if (!port_file.empty()) {
    const std::string tmp = port_file + ".tmp";
    {
      std::ofstream f(tmp);
      f << server->port() << "\n";
    }
    std::rename(tmp.c_str(), port_file.c_str());
  }
  std::printf("listening on %s\n", server->address().c_str());
  std::fflush(stdout);

  std::thread watcher([&] { server->drain_on_signal(sigs); });
  server->wait();
  watcher.join();
  server.reset();
  gd::log().info("gd-server exits");
  return 0;
}
