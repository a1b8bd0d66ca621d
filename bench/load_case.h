#pragma once
/// \file
/// gd-bench load: many clients stepping their own scenes on one gd-server at once, as an RL
/// cluster's rollout workers do.
///
/// Each of `clients` threads opens its own gd::Client (its own channel), creates one scene
/// (`garment` at `vertices`, cotton, the service's defaults) and then steps it, `substeps` per
/// StepScenes call with positions returned, as fast as the server answers, for `seconds`. The
/// server is a gd-server child process on a free loopback port (or `server`, an address, when
/// given). Reported: calls and scene-steps per second over the timed window, per-call latency
/// (p50, p99, max), errors by status code, and the server's resident memory (VmRSS) before the
/// scenes, after the run and after they are destroyed (child server only).

#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace gd::bench {

struct LoadCaseOptions {
  int clients = 16;
  double seconds = 10;
  std::string garment = "towel";
  int vertices = 400;           ///< per scene
  int substeps = 1;             ///< per StepScenes call
  int threads = 0;              ///< the child server's scene workers (0: all cores)
  std::string server;           ///< host:port of a running gd-server (empty: start one)
  std::string server_binary;    ///< gd-server to start (empty: the one beside gd-bench)
};

struct LoadCaseResult {
  LoadCaseOptions options;
  int vertices = 0;             ///< per scene, as built
  double wall_s = 0;            ///< the timed window
  long calls = 0;               ///< StepScenes calls that succeeded
  double calls_per_s = 0, scene_steps_per_s = 0;
  double p50_ms = 0, p99_ms = 0, max_ms = 0;
  std::map<std::string, long> errors;  ///< failed calls by status code name
  double rss_start_mb = -1, rss_loaded_mb = -1, rss_end_mb = -1;  ///< -1: not measured
  std::string error;            ///< non-empty when the case could not run
};

/// Runs the case (progress on stderr every 2 s). Setup errors are returned in `error`; errors of
/// single calls during the run are counted, not thrown.
LoadCaseResult run_load_case(const LoadCaseOptions& options);

nlohmann::json to_json(const LoadCaseResult& r);
/// The table gd-bench load prints without --json.
void print_table(const LoadCaseResult& r);

}  // namespace gd::bench
