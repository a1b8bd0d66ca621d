#pragma once
/// \file
/// gd::ServerProcess: a gd-server child process on a free loopback port, for tests, benchmarks
/// and scripts that want a private server (POSIX only). The server binds port 0 and writes the
/// port it got to a file (--port-file), so there is no race for the port.
///
///     gd::ServerProcessOptions o;
///     o.binary = "build/bin/gd-server";
///     o.args = {"--threads", "2"};
///     gd::ServerProcess server(o);          // started and answering health checks
///     gd::Client client(server.address());  // "127.0.0.1:<port>"
///
/// The destructor stops the server (SIGTERM, then SIGKILL after a grace period).

#include <chrono>
#include <string>
#include <vector>

#include "gd/client.h"

namespace gd {

struct ServerProcessOptions {
  std::string binary = "gd-server";    ///< path of the gd-server executable (or a name on PATH)
  std::string host = "127.0.0.1";      ///< --host
  int port = 0;                        ///< --port; 0: the server picks a free one (read from --port-file)
  /// --data-dir (SQLite store, jobs, meshes). Empty: a fresh temporary directory, removed by stop().
  std::string data_dir;
  std::vector<std::string> args;       ///< further flags, e.g. {"--threads", "2"}
  std::chrono::milliseconds start_timeout{30'000};
  std::string log_file;                ///< the server's stdout and stderr go here ("": inherited)
  /// How the readiness check connects: TLS roots for a server with --tls-cert (the health check
  /// needs no token). Its deadline is replaced by a short one.
  ClientOptions client;
};

class ServerProcess {
 public:
  /// Starts the server and waits until its health check answers SERVING. Throws
  /// ClientError(UNAVAILABLE) with the reason (and the log's tail) when it exits or does not
  /// come up within start_timeout.
  explicit ServerProcess(ServerProcessOptions options);
  /// stop().
  ~ServerProcess();
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  /// "host:port", what gd::Client takes.
  const std::string& address() const { return address_; }
  int port() const { return port_; }
  int pid() const { return pid_; }
  /// False once the process has exited.
  bool running();
  /// Sends SIGTERM, waits up to `grace`, then SIGKILL. Returns the exit status as a shell reports
  /// it (the exit code, or 128 + signal); -1 when it was already stopped.
  int stop(std::chrono::milliseconds grace = std::chrono::milliseconds(10'000));
  /// Sends `sig` (SIGKILL to simulate a crash, SIGTERM or SIGINT to ask for a drain) and returns
  /// at once; no-op once the process has exited.
  void signal(int sig);
  /// Waits up to `timeout` for the process to exit on its own. Returns its exit status as stop()
  /// does, or -1 while it still runs. The scratch directory stays until stop() or the destructor.
  int wait(std::chrono::milliseconds timeout);

  /// The server's data directory (the temporary one when none was given).
  const std::string& data_dir() const { return data_dir_; }

 private:
  ServerProcessOptions options_;
  std::string address_;
  int port_ = 0;
  int pid_ = -1;
  int exit_status_ = -1;
  std::string scratch_dir_;  ///< port file, and the data directory when none was given
  std::string data_dir_;
};

}  // namespace gd
