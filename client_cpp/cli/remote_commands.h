#pragma once
/// \file
/// The `gd --server HOST:PORT <command>` subcommands: thin wrappers over gd::Client that print
/// results and map errors to exit codes (0 ok, 1 a job or scene failed, 2 bad input, 3 server
/// unreachable or another RPC error; see client_cpp/README.md).

#include <CLI/CLI.hpp>
#include <array>
#include <string>
#include <utility>
#include <vector>

#include "gd/client.h"

namespace gd::cli {

/// "NAME=VALUE" of --garment-param or --task-param (`flag`) as (name, value). Throws
/// sim::InputError when it is not a name, '=' and a number; the name is checked by its user.
std::pair<std::string, double> parse_name_value(const std::string& name_value, const std::string& flag);
/// "T:V" (two numbers, e.g. a time and a force) as {T, V}; throws InputError naming `flag` and the text.
std::array<double, 2> parse_knot(const std::string& text, const std::string& flag);

/// Exit codes of the command line.
enum ExitCode : int { kExitOk = 0, kExitFailed = 1, kExitBadInput = 2, kExitRpcError = 3 };

/// Prints `error` on stderr and returns its exit code: the server's INVALID_ARGUMENT and
/// NOT_FOUND are bad input (2), anything else (UNAVAILABLE, DEADLINE_EXCEEDED, ...) is 3.
int report_client_error(const ClientError& error);

/// What `gd --server S run ...` sends: the job, and the local files that go with it.
struct RemoteRun {
  JobSpec job;
  std::string garment_obj;      ///< a local .obj given as --garment: uploaded first
  std::string trajectory_file;  ///< a local trajectory file: its text goes in the job
  std::string out_dir;          ///< where the report's files are written
  bool quiet = false;
};

/// Submits the run as a job, draws a progress bar from WatchJob, then fetches the report and
/// writes its files (summary.json, OBJs, CSVs, plots) into out_dir. Returns the exit code.
int run_remote(const std::string& server, const ClientOptions& options, const RemoteRun& run);

/// How to reach a server securely, from gd's flags (files named on the command line).
struct ConnectionFlags {
  std::string token_file;     ///< --token-file (else $GD_TOKEN_FILE when set)
  std::string tls_ca;         ///< --tls-ca: PEM roots to trust (implies TLS)
  bool tls = false;           ///< --tls: TLS with the system's roots
  std::string tls_cert, tls_key;  ///< --tls-cert/--tls-key: a client certificate (mutual TLS)
};
/// ClientOptions with the token and PEM files read. Throws sim::InputError naming the flag of a
/// missing or empty file.
ClientOptions client_options(const ConnectionFlags& flags);

/// The remote-only subcommands (info, garments, materials, create, step, report, reports,
/// destroy, upload, view), added to `app` on construction; their options live here.
class RemoteCommands {
 public:
  explicit RemoteCommands(CLI::App& app);
  /// True when the parsed command line chose one of them.
  bool selected() const;
  /// Runs the chosen subcommand against `server`; returns the exit code. `flags` are passed on
  /// to the Python viewer (view).
  int execute(const std::string& server, const ClientOptions& options, const ConnectionFlags& flags = {});

 private:
  CLI::App* info_ = nullptr;
  CLI::App* garments_ = nullptr;
  CLI::App* materials_ = nullptr;
  CLI::App* create_ = nullptr;
  CLI::App* step_ = nullptr;
  CLI::App* report_ = nullptr;
  CLI::App* cancel_ = nullptr;
  CLI::App* reports_ = nullptr;
  CLI::App* destroy_ = nullptr;
  CLI::App* upload_ = nullptr;
  CLI::App* view_ = nullptr;

  SceneSpec spec_;
  std::vector<std::string> garment_params_;  ///< --garment-param NAME=VALUE
  std::vector<std::string> material_params_;  ///< --material-param NAME=VALUE
  bool no_self_contact_ = false;
  double dt_ = 0;
  std::string urdf_;
  std::vector<std::string> ids_;
  int substeps_ = 1;
  std::string step_out_;
  std::string job_id_;
  std::string view_job_;  ///< gd view --job
  std::string report_out_;
  bool report_open_ = false;
  int limit_ = 100;
  int offset_ = 0;
  std::string upload_file_;
  std::string upload_name_;
  int view_port_ = 8080;
  int view_every_ = 1;
  std::string view_host_ = "127.0.0.1";
  std::string view_screenshot_;
  double view_wait_ = 8.0;

  int do_info(Client& c);
  int do_garments(Client& c);
  int do_materials(Client& c);
  int do_create(Client& c);
  int do_step(Client& c);
  int do_report(Client& c);
  int do_cancel(Client& c);
  int do_reports(Client& c);
  int do_destroy(Client& c);
  int do_upload(Client& c);
  /// Runs the Python viewer (python -m garmentdynamics.viewer; $GD_PYTHON or python3) on the
  /// scenes, after checking they exist.
  int do_view(Client& c, const std::string& server, const ConnectionFlags& flags);
};

}  // namespace gd::cli
