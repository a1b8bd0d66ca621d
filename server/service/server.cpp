#include "service/server.h"

#include <grpcpp/ext/proto_server_reflection_plugin.h>
#include <grpcpp/grpcpp.h>
#include <grpcpp/health_check_service_interface.h>
#include <spdlog/fmt/fmt.h>

#include <algorithm>
#include <chrono>
#include <condition_variable>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <sstream>
#include <thread>

#include "service/auth.h"
#include "service/job_queue.h"
#include "service/mesh_library.h"
#include "service/reflection_v1.h"
#include "service/report_store.h"
#include "service/scene_pool.h"
#include "service/service.h"
#include "sim/demand.h"
#include "sim/log.h"

#ifndef GD_VERSION
#define GD_VERSION "0.0.0"
#endif

namespace gd::service {
namespace fs = std::filesystem;

namespace {
constexpr const char* kServiceName = "garmentdynamics.v1.GarmentDynamics";
constexpr int kShutdownSeconds = 5;  ///< Server::Shutdown's deadline for in-flight calls

/// A PEM file's text; throws sim::InputError naming the flag.
std::string read_pem(const std::string& path, const char* flag) {
  std::ifstream f(path, std::ios::binary);
  std::ostringstream ss;
  if (f) ss << f.rdbuf();
  if (!f || ss.str().find("-----BEGIN") == std::string::npos)
    throw sim::InputError(fmt::format("cannot read a PEM file from '{}' ({})", path, flag));
  return ss.str();
}

/// Insecure, or TLS (and mTLS) from the options' PEM files. Throws sim::InputError.
std::shared_ptr<grpc::ServerCredentials> server_credentials(const ServerOptions& o) {
  if (o.tls_cert.empty() != o.tls_key.empty())
    throw sim::InputError("give both --tls-cert and --tls-key (or neither)");
  if (o.tls_cert.empty()) {
    if (!o.tls_client_ca.empty()) throw sim::InputError("--tls-client-ca needs --tls-cert and --tls-key");
    return grpc::InsecureServerCredentials();
  }
  grpc::SslServerCredentialsOptions ssl(o.tls_client_ca.empty()
                                            ? GRPC_SSL_DONT_REQUEST_CLIENT_CERTIFICATE
                                            : GRPC_SSL_REQUEST_AND_REQUIRE_CLIENT_CERTIFICATE_AND_VERIFY);
  ssl.pem_key_cert_pairs.push_back({read_pem(o.tls_key, "--tls-key"), read_pem(o.tls_cert, "--tls-cert")});
  if (!o.tls_client_ca.empty()) ssl.pem_root_certs = read_pem(o.tls_client_ca, "--tls-client-ca");
  return grpc::SslServerCredentials(ssl);
}
}  // namespace

bool is_loopback_host(const std::string& host) {
  return host == "localhost" || host == "::1" || host == "[::1]" || host.rfind("127.", 0) == 0;
}

struct Server::Impl {
  ServerOptions options;
  std::unique_ptr<ReportStore> store;
  std::unique_ptr<MeshLibrary> meshes;
  std::unique_ptr<ScenePool> scenes;
  std::unique_ptr<JobQueue> jobs;
  std::unique_ptr<GarmentDynamicsService> service;
  std::unique_ptr<ReflectionV1> reflection_v1;
  std::unique_ptr<grpc::Server> server;
  int port = 0;
  std::once_flag drained;
  // The lease sweeper: expires idle scenes and meshes every quarter of the shorter lease (at
  // most every 30 s).
  std::thread sweeper;
  std::mutex sweep_mu;
  std::condition_variable sweep_cv;
  bool sweep_stop = false;

  void start_sweeper() {
    const double s = options.scene_lease_seconds, m = options.mesh_lease_seconds;
    if (!(s > 0) && !(m > 0)) return;
    const double shortest = !(s > 0) ? m : !(m > 0) ? s : std::min(s, m);
    const auto period = std::chrono::duration<double>(std::clamp(shortest / 4, 0.05, 30.0));
    sweeper = std::thread([this, period, m] {
      std::unique_lock<std::mutex> lock(sweep_mu);
      while (!sweep_cv.wait_for(lock, period, [this] { return sweep_stop; })) {
        scenes->expire_idle();
        meshes->expire_idle(m, [this](const std::string& path) { return jobs->uses_file(path); });
      }
    });
  }
  void stop_sweeper() {
    {
      std::lock_guard<std::mutex> lock(sweep_mu);
      sweep_stop = true;
    }
    sweep_cv.notify_all();
    if (sweeper.joinable()) sweeper.join();
  }
};

Server::Server() : impl_(std::make_unique<Impl>()) {}

Server::~Server() {
  drain();
  if (impl_->server) impl_->server->Wait();
  impl_->stop_sweeper();
}

std::unique_ptr<Server> Server::start(const ServerOptions& o, Status* status) {
  auto fail = [&](Status st) {
    *status = std::move(st);
    return std::unique_ptr<Server>();
  };
  if (o.data_dir.empty()) return fail(Status::InvalidArgument("no data directory given (--data-dir DIR)"));
  if (o.port < 0 || o.port > 65535) return fail(Status::InvalidArgument(fmt::format("bad port {}", o.port)));
  if (o.max_message_mb < 1 || o.max_message_mb > 2000)
    return fail(Status::InvalidArgument("--max-message-mb must be in [1, 2000]"));
  if (o.job_workers < 1) return fail(Status::InvalidArgument("--job-workers must be >= 1"));
  if (!(o.scene_lease_seconds >= 0)) return fail(Status::InvalidArgument("--scene-lease-s must be >= 0 (0: never)"));
  if (!(o.mesh_lease_seconds >= 0)) return fail(Status::InvalidArgument("--mesh-lease-s must be >= 0 (0: never)"));
  if (o.auth_token_file.empty() && !o.allow_unauthenticated && !is_loopback_host(o.host))
    return fail(Status::InvalidArgument(fmt::format(
        "--host {} is reachable from other machines: give --auth-token-file FILE (and --tls-cert/--tls-key), or "
        "--allow-unauthenticated on a network you trust", o.host)));
  TokenSet tokens;
  std::shared_ptr<grpc::ServerCredentials> credentials;
  try {
    if (!o.auth_token_file.empty()) tokens = TokenSet::load(o.auth_token_file);
    credentials = server_credentials(o);
  } catch (const std::exception& e) {
    return fail(Status::InvalidArgument(e.what()));
  }
  if (tokens.enabled() && o.tls_cert.empty() && !is_loopback_host(o.host))
    gd::log().warn("bearer tokens over plaintext on {}: anyone on the path can read them; add --tls-cert/--tls-key",
                   o.host);
  std::unique_ptr<Server> s(new Server());
  Impl& im = *s->impl_;
  im.options = o;
  const size_t max_bytes = size_t(o.max_message_mb) << 20;
  try {
    fs::create_directories(o.data_dir);
    im.store = std::make_unique<ReportStore>((fs::path(o.data_dir) / "gd.sqlite").string());
    im.meshes = std::make_unique<MeshLibrary>((fs::path(o.data_dir) / "meshes").string(), *im.store, o.max_vertices,
                                              max_bytes);
    PoolOptions po;
    po.threads = o.threads;
    po.max_scenes = o.max_scenes;
    po.max_vertices = o.max_vertices;
    po.max_substeps = o.max_substeps;
    po.max_queued_frame_bytes = static_cast<size_t>(o.max_queued_frames_mb) << 20;
    po.max_reply_bytes = max_bytes;
    po.scene_lease_seconds = o.scene_lease_seconds;
    po.backend = o.backend;
    po.deterministic = o.deterministic;
    po.robot_urdf = o.robot_urdf;
    po.robot_package_paths = o.robot_package_paths;
    im.scenes = std::make_unique<ScenePool>(po);
    JobQueueOptions jo;
    jo.data_dir = o.data_dir;
    jo.max_queued_frame_bytes = po.max_queued_frame_bytes;
    jo.capture_root = o.capture_root.empty() ? (fs::path(o.data_dir) / "captures").string() : o.capture_root;
    fs::create_directories(jo.capture_root);
    jo.workers = o.job_workers;
    jo.threads_per_job = std::max(1, im.scenes->threads() / o.job_workers);  // the jobs' share of --threads
    jo.max_job_steps = o.max_job_steps;
    jo.max_vertices = o.max_vertices;
    jo.plots = o.plots;
    jo.backend = o.backend;
    jo.deterministic = o.deterministic;
    jo.robot_urdf = o.robot_urdf;
    jo.robot_package_paths = o.robot_package_paths;
    im.jobs = std::make_unique<JobQueue>(jo, *im.store, *im.meshes);
  } catch (const std::exception& e) {
    return fail(Status::InvalidArgument(e.what()));
  }
  HandlerOptions ho;
  ho.version = GD_VERSION;
  ho.tokens = tokens;
  ho.max_streams = o.max_streams;
  ho.max_reply_bytes = max_bytes;
  ho.max_report_file_bytes = std::min<size_t>(32u << 20, max_bytes - std::min<size_t>(max_bytes / 2, 1u << 20));
  im.service = std::make_unique<GarmentDynamicsService>(*im.scenes, *im.jobs, *im.meshes, ho);

  grpc::EnableDefaultHealthCheckService(true);
  grpc::reflection::InitProtoReflectionServerBuilderPlugin();
  grpc::ServerBuilder b;
  const std::string addr = fmt::format("{}:{}", o.host, o.port);
  // No SO_REUSEPORT: with it gRPC bound one socket per poller, each on its own free port when
  // --port is 0 (a server on two ports, one of them in --port-file), and a second server could
  // bind a port this one holds without an error (grpc/grpc#11920, #24730).
  b.AddChannelArgument(GRPC_ARG_ALLOW_REUSEPORT, 0);
  b.AddListeningPort(addr, credentials, &im.port);
  b.RegisterService(im.service.get());
  im.reflection_v1 = std::make_unique<ReflectionV1>(std::vector<std::string>{
      kServiceName, "grpc.health.v1.Health", "grpc.reflection.v1.ServerReflection",
      "grpc.reflection.v1alpha.ServerReflection"});
  b.RegisterService(im.reflection_v1.get());
  b.SetMaxReceiveMessageSize(static_cast<int>(max_bytes));
  b.SetMaxSendMessageSize(static_cast<int>(max_bytes));
  b.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIME_MS, 60 * 1000);
  b.AddChannelArgument(GRPC_ARG_KEEPALIVE_TIMEOUT_MS, 20 * 1000);
  b.AddChannelArgument(GRPC_ARG_KEEPALIVE_PERMIT_WITHOUT_CALLS, 1);
  b.AddChannelArgument(GRPC_ARG_HTTP2_MIN_RECV_PING_INTERVAL_WITHOUT_DATA_MS, 10 * 1000);
  b.AddChannelArgument(GRPC_ARG_HTTP2_MAX_PING_STRIKES, 0);
  im.server = b.BuildAndStart();
  if (!im.server || im.port == 0) return fail(Status::Unavailable(fmt::format("cannot listen on {} (in use?)", addr)));
  if (auto* h = im.server->GetHealthCheckService()) {
    h->SetServingStatus(true);
    h->SetServingStatus(kServiceName, true);
  }
  im.start_sweeper();
  gd::log().info("gd-server {} on {}:{} ({} scene threads, backend {}, data in {}; {}, {})", GD_VERSION, o.host,
                 im.port, im.scenes->threads(),
                 o.backend == sim::BackendKind::kCpu ? "cpu" : o.backend == sim::BackendKind::kCuda ? "cuda" : "auto",
                 o.data_dir, o.tls_cert.empty() ? "plaintext" : o.tls_client_ca.empty() ? "TLS" : "mutual TLS",
                 tokens.enabled() ? fmt::format("{} bearer token(s)", tokens.size()) : std::string("no tokens"));
  return s;
}

int Server::port() const { return impl_->port; }

std::string Server::address() const { return fmt::format("{}:{}", impl_->options.host, impl_->port); }

void Server::wait() { impl_->server->Wait(); }

void Server::drain() {
  std::call_once(impl_->drained, [this] {
    Impl& im = *impl_;
    if (!im.server) return;
    gd::log().info("draining: health NOT_SERVING, no new jobs, {} s grace for running jobs", im.options.grace_seconds);
    if (auto* h = im.server->GetHealthCheckService()) {
      h->SetServingStatus(false);
      h->SetServingStatus(kServiceName, false);
    }
    im.service->stop_accepting();
    im.jobs->drain(im.options.grace_seconds);
    im.service->begin_drain();
    im.server->Shutdown(std::chrono::system_clock::now() + std::chrono::seconds(kShutdownSeconds));
    gd::log().info("drained; shut down");
  });
}

void Server::drain_on_signal(const sigset_t& signals) {
  int sig = 0;
  sigwait(&signals, &sig);
  gd::log().info("signal {}: draining", sig);
  const double budget = impl_->options.grace_seconds + kShutdownSeconds + kDrainOverrunSeconds;
  std::thread([signals, budget] {
    timespec wait{};
    wait.tv_sec = static_cast<time_t>(std::ceil(budget));
    const int again = sigtimedwait(&signals, nullptr, &wait);
    if (again > 0)
      gd::log().error("signal {} during the drain: exiting now, without waiting for it", again);
    else
      gd::log().error("the drain is still running after {:.0f} s (a call does not finish): exiting now", budget);
    gd::log().flush();
    std::_Exit(1);
  }).detach();
  drain();
}

}  // namespace gd::service
