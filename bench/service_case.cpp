#include "service_case.h"

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <functional>
#include <thread>

#include "gd/client.h"
#include "gd/server_process.h"
#include "server_binary.h"
#include "service/scene_pool.h"

namespace gd::bench {

namespace {

using Clock = std::chrono::steady_clock;

double ms_since(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

double mean(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x;
  return v.empty() ? 0 : s / static_cast<double>(v.size());
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

void check(const service::Status& s, const char* what) {
  if (!s.ok()) throw std::runtime_error(std::string(what) + ": " + service::code_name(s.code()) + ": " + s.message());
}

/// (a): one batched StepScenes over gRPC, positions returned. Returns wall ms.
double grpc_step(Client& client, const std::vector<std::string>& ids, int substeps) {
  StepOptions o;
  o.substeps = substeps;
  const auto t0 = Clock::now();
  const auto states = client.step(ids, {}, o);
  const double ms = ms_since(t0);
  for (const auto& s : states)
    if (s.failed) throw std::runtime_error("scene " + s.id + " failed over gRPC: " + s.failure);
  return ms;
}

/// (b): the same batched step on the in-process ScenePool. Returns wall ms.
double inproc_step(service::ScenePool& pool, const std::vector<std::string>& ids, int substeps) {
  service::StepRequest req;
  req.scene_ids = ids;
  req.substeps = substeps;
  req.include_positions = true;
  std::vector<service::SceneSnapshot> states;
  const auto t0 = Clock::now();
  check(pool.step(req, &states), "in-process step");
  const double ms = ms_since(t0);
  for (const auto& s : states)
    if (s.failed) throw std::runtime_error("scene " + s.scene_id + " failed in-process: " + s.failure);
  return ms;
}

}  // namespace

ServiceCaseResult run_service_case(const ServiceCaseOptions& opt) {
  ServiceCaseResult r;
  r.options = opt;
  r.threads = opt.threads > 0 ? opt.threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  const std::string name = "service/" + std::to_string(opt.scenes) + "x" + std::to_string(opt.vertices);
  ServerProcessOptions so;
  try {
    // (a) the server, a child process with the same worker count and the CPU backend.
    so.binary = opt.server_binary.empty() ? default_server_binary() : opt.server_binary;
    so.args = {"--threads", std::to_string(r.threads), "--backend", "cpu", "--max-scenes",
               std::to_string(std::max(opt.scenes, 16)), "--max-vertices",
               std::to_string(std::max(2 * opt.vertices, 50000))};
    so.log_file = (std::filesystem::temp_directory_path() / ("gd-bench-server-" + std::to_string(::getpid()) + ".log")).string();
    const auto t_setup = Clock::now();
    ServerProcess server(so);
    ClientOptions co;
    co.deadline = std::chrono::minutes(10);
    Client client(server.address(), co);
    SceneSpec spec;
    spec.garment = opt.garment;
    spec.material = opt.material;
    spec.vertices = opt.vertices;
    spec.count = opt.scenes;
    spec.settings.self_contact = opt.self_contact;
    const CreatedScenes remote = client.create_scenes(spec);
    r.vertices = remote.info.vertex_count;
    r.response_mb = 12.0 * r.vertices * opt.scenes / (1024.0 * 1024.0);

    // (b) the same scenes in this process.
    service::PoolOptions po;
    po.threads = r.threads;
    po.backend = sim::BackendKind::kCpu;
    po.max_scenes = std::max(opt.scenes, 16);
    po.max_vertices = std::max(2 * opt.vertices, 50000);
    service::ScenePool pool(po);
    service::SceneSpec local_spec;
    local_spec.garment = opt.garment;
    local_spec.material = opt.material;
    local_spec.vertices = opt.vertices;
    local_spec.count = opt.scenes;
    local_spec.self_contact = opt.self_contact;
    service::CreatedScenes local;
    check(pool.create(local_spec, &local), "in-process create");
    std::fprintf(stderr,
                 "[gd-bench] %s: %d scenes x %d vertices (%s, %s, self-contact %s), %d threads, server %s "
                 "(setup %.1f s)\n",
                 name.c_str(), opt.scenes, r.vertices, opt.garment.c_str(), opt.material.c_str(),
                 opt.self_contact ? "on" : "off", r.threads, server.address().c_str(), ms_since(t_setup) / 1e3);

    const double w_grpc = grpc_step(client, remote.ids, opt.substeps);
    const double w_local = inproc_step(pool, local.ids, opt.substeps);
    std::fprintf(stderr, "[gd-bench] %s: warm-up step: gRPC %.1f ms, in-process %.1f ms\n", name.c_str(), w_grpc,
                 w_local);
    for (int round = 0; round < opt.rounds; ++round) {
      const auto run_grpc = [&] {
        for (int i = 0; i < opt.steps; ++i) r.grpc_ms.push_back(grpc_step(client, remote.ids, opt.substeps));
      };
      const auto run_local = [&] {
        for (int i = 0; i < opt.steps; ++i) r.inproc_ms.push_back(inproc_step(pool, local.ids, opt.substeps));
      };
      if (round % 2 == 0) {
        run_grpc();
        run_local();
      } else {
        run_local();
        run_grpc();
      }
      std::fprintf(stderr, "[gd-bench] %s: round %d/%d: gRPC %.1f ms/step, in-process %.1f ms/step so far\n",
                   name.c_str(), round + 1, opt.rounds, mean(r.grpc_ms), mean(r.inproc_ms));
    }
    // The transport alone: the batch's state (positions) fetched without stepping.
    constexpr int kStateCalls = 10;
    std::vector<double> sg, si;
    for (int i = 0; i < kStateCalls; ++i) {
      auto t0 = Clock::now();
      const auto remote_states = client.get_state(remote.ids);
      sg.push_back(ms_since(t0));
      std::vector<service::SceneSnapshot> local_states;
      t0 = Clock::now();
      check(pool.state(local.ids, false, &local_states), "in-process state");
      si.push_back(ms_since(t0));
    }
    r.state_grpc_ms = median(sg);
    r.state_inproc_ms = median(si);
    std::fprintf(stderr, "[gd-bench] %s: GetState of the batch: gRPC %.2f ms, in-process %.2f ms (medians of %d)\n",
                 name.c_str(), r.state_grpc_ms, r.state_inproc_ms, kStateCalls);
    client.destroy(remote.ids);
    int destroyed = 0;
    check(pool.destroy(local.ids, &destroyed), "in-process destroy");
    std::error_code ec;
    std::filesystem::remove(so.log_file, ec);  // kept only when something went wrong
  } catch (const std::exception& e) {
    r.error = e.what();
    std::fprintf(stderr, "[gd-bench] %s: FAILED: %s\n", name.c_str(), e.what());
  }
  r.grpc_mean = mean(r.grpc_ms);
  r.inproc_mean = mean(r.inproc_ms);
  r.grpc_median = median(r.grpc_ms);
  r.inproc_median = median(r.inproc_ms);
  if (r.inproc_mean > 0 && r.grpc_mean > 0) {
    r.ratio = r.grpc_mean / r.inproc_mean;
    r.overhead_pct = 100.0 * (r.ratio - 1.0);
    r.transport_overhead_pct = 100.0 * (r.state_grpc_ms - r.state_inproc_ms) / r.inproc_mean;
    std::fprintf(stderr,
                 "[gd-bench] %s: gRPC %.1f ms, in-process %.1f ms per batched step: ratio %.3f (%+.1f%%); transport "
                 "alone %+.2f%%\n",
                 name.c_str(), r.grpc_mean, r.inproc_mean, r.ratio, r.overhead_pct, r.transport_overhead_pct);
  }
  return r;
}

nlohmann::json to_json(const ServiceCaseResult& r) {
  const bool ok = r.ratio > 0;
  nlohmann::json j = {{"case", "service/" + std::to_string(r.options.scenes) + "x" + std::to_string(r.options.vertices)},
                      {"scenes", r.options.scenes},
                      {"vertices", r.vertices},
                      {"garment", r.options.garment},
                      {"material", r.options.material},
                      {"self_contact", r.options.self_contact},
                      {"threads", r.threads},
                      {"backend", "cpu"},
                      {"substeps", r.options.substeps},
                      {"rounds", r.options.rounds},
                      {"steps_per_round", r.options.steps},
                      {"response_mb", r.response_mb},
                      {"grpc_ms", r.grpc_ms},
                      {"inproc_ms", r.inproc_ms},
                      {"grpc_ms_per_step", ok ? nlohmann::json(r.grpc_mean) : nlohmann::json(nullptr)},
                      {"inproc_ms_per_step", ok ? nlohmann::json(r.inproc_mean) : nlohmann::json(nullptr)},
                      {"grpc_ms_median", ok ? nlohmann::json(r.grpc_median) : nlohmann::json(nullptr)},
                      {"inproc_ms_median", ok ? nlohmann::json(r.inproc_median) : nlohmann::json(nullptr)},
                      {"ratio", ok ? nlohmann::json(r.ratio) : nlohmann::json(nullptr)},
                      {"overhead_pct", ok ? nlohmann::json(r.overhead_pct) : nlohmann::json(nullptr)},
                      {"state_grpc_ms", r.state_grpc_ms},
                      {"state_inproc_ms", r.state_inproc_ms},
                      {"transport_overhead_pct", ok ? nlohmann::json(r.transport_overhead_pct) : nlohmann::json(nullptr)}};
  if (!r.error.empty()) j["error"] = r.error;
  return j;
}

void print_table(const ServiceCaseResult& r) {
  std::printf("%-18s %7s %9s %8s %8s %14s %14s %12s %12s %8s %9s\n", "case", "scenes", "vertices", "threads",
              "steps", "gRPC ms/step", "inproc ms/step", "gRPC median", "inproc med.", "ratio", "overhead");
  const std::string name = "service/" + std::to_string(r.options.scenes) + "x" + std::to_string(r.options.vertices);
  std::printf("%-18s %7d %9d %8d %8zu %14.1f %14.1f %12.1f %12.1f %8.3f %8.1f%%%s\n", name.c_str(), r.options.scenes,
              r.vertices, r.threads, r.grpc_ms.size(), r.grpc_mean, r.inproc_mean, r.grpc_median, r.inproc_median,
              r.ratio, r.overhead_pct, r.error.empty() ? "" : ("  FAILED: " + r.error).c_str());
  std::printf("transport alone (GetState of the batch, medians): gRPC %.2f ms, in-process %.2f ms: %+.2f%% of the "
              "in-process step\n",
              r.state_grpc_ms, r.state_inproc_ms, r.transport_overhead_pct);
  std::printf("(one batched step = %d substeps of every scene, %.2f MB of positions returned; ratio = gRPC mean / "
              "in-process mean; goal: overhead under 5%%)\n",
              r.options.substeps, r.response_mb);
}

}  // namespace gd::bench
