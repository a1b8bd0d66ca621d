#pragma once
/// \file
/// The gd-server process minus flag parsing: opens the data directory (SQLite store, meshes,
/// jobs), builds the cores and the gRPC server (message size limits, keepalive, grpc.health.v1,
/// server reflection), and drains on request: health NOT_SERVING, no new jobs, running jobs
/// get a grace period and are then interrupted, streams end, in-flight calls finish, then the
/// server shuts down. No gRPC types in this header.

#include <csignal>
#include <memory>
#include <string>

#include "service/status.h"
#include "sim/solver/options.h"

namespace gd::service {

struct ServerOptions {
  std::string host = "127.0.0.1";
  int port = 50051;                  ///< 0: pick a free port (see Server::port())
  std::string data_dir;              ///< required: gd.sqlite, jobs/, meshes/, captures/
  std::string capture_root;          ///< empty: data_dir/captures
  sim::BackendKind backend = sim::BackendKind::kCpu;
  bool deterministic = false;  ///< SceneOptions::deterministic for every scene (--deterministic)
  /// Cores the server computes on (0: hardware concurrency): its scene workers, and each of the
  /// job_workers jobs' solver gets threads / job_workers OpenMP threads (at least one).
  int threads = 0;
  int max_scenes = 256;
  int max_vertices = 50000;
  int max_substeps = 1000;
  int max_message_mb = 64;           ///< receive and send limit per message
  int max_queued_frames_mb = 16;     ///< frames one StreamFrames subscription queues for a slow reader
  int max_streams = 64;              ///< StreamFrames and WatchJob calls open at once (0: no limit)
  int job_workers = 1;
  long max_job_steps = 2'000'000;    ///< simulation steps per job (0: no limit)
  bool plots = false;
  /// URDF of robot mode's arms for requests that send none (empty: they must send one).
  std::string robot_urdf;
  /// Directories where the URDF's `package://NAME/...` meshes are looked for (repeatable flag).
  std::vector<std::string> robot_package_paths;
  double grace_seconds = 10;         ///< drain: how long running jobs may still take
  double scene_lease_seconds = 3600; ///< scenes no call names for this long are destroyed (0: never)
  double mesh_lease_seconds = 7 * 86400;  ///< uploads unused for this long are deleted (0: never)
  /// Security (docs/service.md, "Tokens and TLS").
  std::string auth_token_file;       ///< bearer tokens, one per line (empty: no authentication)
  std::string tls_cert, tls_key;     ///< PEM certificate chain and private key: serve TLS (both or neither)
  std::string tls_client_ca;         ///< PEM CA: require client certificates signed by it (mTLS; needs TLS)
  /// Listen on a non-loopback host without tokens (refused otherwise: anyone who can reach the
  /// port could run, read and destroy everything).
  bool allow_unauthenticated = false;
};

/// Whether `host` names only this machine (127.0.0.0/8, ::1, localhost).
bool is_loopback_host(const std::string& host);

/// Seconds a drain may overrun its budget before drain_on_signal ends the process.
inline constexpr int kDrainOverrunSeconds = 10;

class Server {
 public:
  /// Builds and starts the server. Returns null and sets *status on failure (bad data dir, port
  /// in use, ...).
  static std::unique_ptr<Server> start(const ServerOptions& options, Status* status);
  ~Server();

  /// The bound port (the chosen one when options.port was 0).
  int port() const;
  /// "host:port" as bound.
  std::string address() const;
  /// Blocks until the server has shut down (after drain()).
  void wait();
  /// Drains and shuts down (see the file comment); returns when done. Thread-safe, idempotent.
  void drain();
  /// Waits for one of `signals` (blocked in every thread), then drains. A second signal during
  /// the drain, or a drain still running kDrainOverrunSeconds past its budget (the grace period
  /// plus the 5 s shutdown deadline), ends the process at once with exit code 1 after an error
  /// line: a call stuck in work that never looks at its context cannot keep the server alive
  /// (jobs it left running are INTERRUPTED at the next start, as after kill -9).
  void drain_on_signal(const sigset_t& signals);

 private:
  Server();
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gd::service
