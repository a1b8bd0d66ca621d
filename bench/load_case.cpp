#include "load_case.h"

#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <optional>
#include <thread>

#include "gd/client.h"
#include "gd/server_process.h"
#include "server_binary.h"

namespace gd::bench {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

/// VmRSS of a process, MiB (-1 when unreadable).
double rss_mb(int pid) {
  std::ifstream f("/proc/" + std::to_string(pid) + "/status");
  std::string key;
  while (f >> key) {
    if (key == "VmRSS:") {
      double kb = 0;
      f >> kb;
      return kb / 1024.0;
    }
    std::string rest;
    std::getline(f, rest);
  }
  return -1;
}

double percentile(std::vector<double>& v, double q) {
  if (v.empty()) return 0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(q * static_cast<double>(v.size() - 1) + 0.5));
  std::nth_element(v.begin(), v.begin() + static_cast<long>(k), v.end());
  return v[k];
}

}  // namespace

LoadCaseResult run_load_case(const LoadCaseOptions& opt) {
  LoadCaseResult r;
  r.options = opt;
  // The scenes made so far, so a run that fails half-way leaves none on a shared server.
  std::vector<std::unique_ptr<Client>> clients;
  std::vector<std::string> ids;
  try {
    std::optional<ServerProcess> child;
    std::string address = opt.server;
    if (address.empty()) {
      ServerProcessOptions so;
      so.binary = opt.server_binary.empty() ? default_server_binary() : opt.server_binary;
      so.args = {"--backend", "cpu", "--max-scenes", std::to_string(std::max(opt.clients, 16))};
      if (opt.threads > 0) so.args.insert(so.args.end(), {"--threads", std::to_string(opt.threads)});
      so.log_file = (std::filesystem::temp_directory_path() / ("gd-bench-load-" + std::to_string(::getpid()) + ".log")).string();
      child.emplace(so);
      address = child->address();
      r.rss_start_mb = rss_mb(child->pid());
    }
    // Every client: its own channel and scene.
    ClientOptions co;
    co.deadline = std::chrono::minutes(2);
    const auto t_setup = Clock::now();
    for (int c = 0; c < opt.clients; ++c) {
      clients.push_back(std::make_unique<Client>(address, co));
      SceneSpec spec;
      spec.garment = opt.garment;
      spec.vertices = opt.vertices;
      const CreatedScenes made = clients.back()->create_scenes(spec);
      ids.push_back(made.ids.at(0));
      r.vertices = made.info.vertex_count;
    }
    std::fprintf(stderr, "[load] %d scenes of %d vertices on %s in %.1f s; stepping for %.0f s\n", opt.clients,
                 r.vertices, address.c_str(), seconds_since(t_setup), opt.seconds);

    std::mutex mu;
    std::vector<double> latencies;
    std::atomic<long> calls{0};
    std::atomic<bool> stop{false};
    std::vector<std::thread> threads;
    const auto t0 = Clock::now();
    for (int c = 0; c < opt.clients; ++c) {
      threads.emplace_back([&, c] {
        std::vector<double> mine;
        std::map<std::string, long> errs;
        StepOptions so;
        so.substeps = opt.substeps;
        while (!stop.load()) {
          const auto t = Clock::now();
          try {
            clients[c]->step({ids[c]}, {}, so);
            mine.push_back(1000.0 * seconds_since(t));
            ++calls;
          } catch (const ClientError& e) {
            ++errs[status_code_name(e.code())];
          }
        }
        std::lock_guard<std::mutex> lock(mu);
        latencies.insert(latencies.end(), mine.begin(), mine.end());
        for (const auto& [k, n] : errs) r.errors[k] += n;
      });
    }
    for (double t = 2; t < opt.seconds; t += 2) {
      std::this_thread::sleep_until(t0 + std::chrono::duration<double>(t));
      std::fprintf(stderr, "[load] %.0f s: %ld calls\n", t, calls.load());
    }
    std::this_thread::sleep_until(t0 + std::chrono::duration<double>(opt.seconds));
    stop = true;
    for (auto& t : threads) t.join();
    r.wall_s = seconds_since(t0);  // includes the calls in flight when the window closed
    r.calls = static_cast<long>(latencies.size());
    r.calls_per_s = r.calls / r.wall_s;
    r.scene_steps_per_s = r.calls_per_s * opt.substeps;
    r.p50_ms = percentile(latencies, 0.50);
    r.p99_ms = percentile(latencies, 0.99);
    r.max_ms = latencies.empty() ? 0 : *std::max_element(latencies.begin(), latencies.end());
    if (child) r.rss_loaded_mb = rss_mb(child->pid());
    for (int c = 0; c < opt.clients; ++c) clients[c]->destroy({ids[c]});
    ids.clear();
    if (child) r.rss_end_mb = rss_mb(child->pid());
  } catch (const std::exception& e) {
    r.error = e.what();
    for (size_t c = 0; c < ids.size(); ++c) {  // best effort: the server may be the failure
      try {
        clients[c]->destroy({ids[c]});
      } catch (const std::exception&) {
      }
    }
  }
  return r;
}

nlohmann::json to_json(const LoadCaseResult& r) {
  nlohmann::json j;
  j["case"] = "load/" + std::to_string(r.options.clients) + "x" + std::to_string(r.options.vertices);
  j["clients"] = r.options.clients;
  j["vertices"] = r.vertices;
  j["substeps"] = r.options.substeps;
  j["seconds"] = r.wall_s;
  j["calls"] = r.calls;
  j["calls_per_s"] = r.calls_per_s;
  j["scene_steps_per_s"] = r.scene_steps_per_s;
  j["p50_ms"] = r.p50_ms;
  j["p99_ms"] = r.p99_ms;
  j["max_ms"] = r.max_ms;
  j["errors"] = r.errors;
  j["rss_start_mb"] = r.rss_start_mb;
  j["rss_loaded_mb"] = r.rss_loaded_mb;
  j["rss_end_mb"] = r.rss_end_mb;
  if (!r.error.empty()) j["error"] = r.error;
  return j;
}

void print_table(const LoadCaseResult& r) {
  if (!r.error.empty()) {
    std::printf("load: error: %s\n", r.error.c_str());
    return;
  }
  long errors = 0;
  for (const auto& [k, n] : r.errors) errors += n;
  std::printf("%d clients, one %d-vertex %s each, %d substep(s) per call, %.1f s\n", r.options.clients, r.vertices,
              r.options.garment.c_str(), r.options.substeps, r.wall_s);
  std::printf("  %ld calls: %.1f calls/s, %.1f scene-steps/s\n", r.calls, r.calls_per_s, r.scene_steps_per_s);
  std::printf("  latency per call: p50 %.1f ms, p99 %.1f ms, max %.1f ms\n", r.p50_ms, r.p99_ms, r.max_ms);
  std::printf("  errors: %ld", errors);
  for (const auto& [k, n] : r.errors) std::printf(" %s=%ld", k.c_str(), n);
  std::printf("\n");
  if (r.rss_start_mb >= 0)
    std::printf("  server RSS: %.0f MiB at start, %.0f with the scenes after the run, %.0f after destroying them\n",
                r.rss_start_mb, r.rss_loaded_mb, r.rss_end_mb);
}

}  // namespace gd::bench
