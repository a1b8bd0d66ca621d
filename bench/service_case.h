#pragma once
/// \file
/// gd-bench service: the cost of the gRPC service over calling its core directly.
///
/// The same batch (by default 16 towels of ~5000 vertices, cotton, CPU backend, the same worker
/// threads) is built twice: (a) on a gd-server child process on a free loopback port, driven by
/// gd::Client; (b) in this process, in a gd::service::ScenePool (the plain-C++ core the server
/// runs). After one untimed warm-up step of each, `rounds` rounds alternate (a) and (b) (the
/// order flips every round, so drift from the machine's load or the cloth settling hits both
/// sides alike), each timing `steps` batched steps of `substeps` substeps with positions
/// returned. Reported: mean and median ms per batched step of each side, their ratio
/// (gRPC / in-process) and the overhead in percent (the goal is under 5%); then 10 GetState
/// calls of the whole batch on each side time the transport alone (its cost per call, relative
/// to the in-process step).

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace gd::bench {

struct ServiceCaseOptions {
  int scenes = 16;
  int vertices = 5000;
  std::string garment = "towel";
  std::string material = "cotton";
  bool self_contact = true;     ///< the service's default
  int threads = 0;              ///< server and pool workers (0: hardware concurrency)
  int rounds = 3;
  int steps = 3;                ///< timed batched steps per side and round
  int substeps = 1;
  std::string server_binary;    ///< gd-server (empty: the one beside gd-bench)
};

struct ServiceCaseResult {
  ServiceCaseOptions options;
  int vertices = 0;             ///< per scene, as built
  int threads = 0;
  std::vector<double> grpc_ms;      ///< every timed batched step, in order
  std::vector<double> inproc_ms;
  double grpc_mean = 0, inproc_mean = 0, grpc_median = 0, inproc_median = 0;
  double ratio = 0;             ///< grpc_mean / inproc_mean
  double overhead_pct = 0;      ///< 100 (ratio - 1)
  double response_mb = 0;       ///< positions returned per batched step
  /// The transport alone: mean ms of a GetState of the whole batch (positions, no stepping) over
  /// gRPC and in-process, and their difference as a share of the in-process step. Unlike the
  /// ratio of two multi-second steps, this is not drowned by the machine's load noise.
  double state_grpc_ms = 0, state_inproc_ms = 0, transport_overhead_pct = 0;
  std::string error;            ///< non-empty when the case failed
};

/// Runs the case (progress on stderr). Errors (server that does not start, refused RPC, failed
/// scene) are caught and returned in `error`.
ServiceCaseResult run_service_case(const ServiceCaseOptions& options);

nlohmann::json to_json(const ServiceCaseResult& r);
/// The table gd-bench prints without --json.
void print_table(const ServiceCaseResult& r);

}  // namespace gd::bench
