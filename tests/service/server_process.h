#pragma once
// Test helpers of the service's integration tests: a temporary directory, and a real gd-server
// process (GD_SERVER_BIN) started on a free loopback port by the client library's
// gd::ServerProcess, stopped in the destructor.

#include <gtest/gtest.h>
#include <grpcpp/grpcpp.h>
#include <signal.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "garmentdynamics/v1/garmentdynamics.grpc.pb.h"
#include "gd/server_process.h"

namespace gd::service::testing {

namespace fs = std::filesystem;
namespace pb = ::garmentdynamics::v1;

/// A fresh directory under the system temp dir, removed with everything in it at the end.
class TempDir {
 public:
  TempDir() {
    std::string tmpl = (fs::temp_directory_path() / "gd-service-test-XXXXXX").string();
    if (!mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
    path_ = tmpl;
  }
  ~TempDir() {
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  const fs::path& path() const { return path_; }
  std::string str() const { return path_.string(); }

 private:
  fs::path path_;
};

/// The gd-server binary the tests run.
inline std::string server_binary() {
  const char* e = std::getenv("GD_SERVER_BIN");
#ifdef GD_SERVER_BIN_DEFAULT
  return e && *e ? e : GD_SERVER_BIN_DEFAULT;
#else
  return e && *e ? e : "build/bin/gd-server";
#endif
}

/// A gd-server process (the client library's gd::ServerProcess) on a free loopback port, with its
/// data in `data_dir`, a debug log beside it, and a raw gRPC channel for the service's own stubs.
class ServerProcess {
 public:
  explicit ServerProcess(const std::string& data_dir, std::vector<std::string> extra = {})
      : log_file_(next_log_file(data_dir)),
        process_(options(data_dir, log_file_, std::move(extra))),
        channel_(grpc::CreateChannel(process_.address(), grpc::InsecureChannelCredentials())) {}

  int port() const { return process_.port(); }
  int pid() const { return process_.pid(); }
  std::string address() const { return process_.address(); }
  std::shared_ptr<grpc::Channel> channel() const { return channel_; }
  std::unique_ptr<pb::GarmentDynamics::Stub> stub() const { return pb::GarmentDynamics::NewStub(channel_); }
  std::string log() const {
    std::ifstream f(log_file_);
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
  }

  /// kill -9 (a crash), waits for the process.
  void kill9() {
    process_.signal(SIGKILL);
    process_.wait(std::chrono::seconds(30));
  }
  /// Sends `sig` (0: none) and waits up to timeout_s for the exit. Returns the exit code (-1: did
  /// not exit in time; 128 + signal: killed by one).
  int signal_and_wait(int sig, double timeout_s) {
    if (sig != 0) process_.signal(sig);
    return process_.wait(std::chrono::milliseconds(static_cast<int64_t>(timeout_s * 1000)));
  }

 private:
  /// DIR/../<name>-server-<n>.log: one per start, so a restart on the same data directory does not
  /// overwrite the log of the server before it (gd::ServerProcess truncates its log file).
  static std::string next_log_file(const std::string& data_dir) {
    static int starts = 0;
    return data_dir + "/../" + fs::path(data_dir).filename().string() + "-server-" + std::to_string(++starts) + ".log";
  }
  static gd::ServerProcessOptions options(const std::string& data_dir, const std::string& log_file,
                                          std::vector<std::string> extra) {
    fs::create_directories(data_dir);
    gd::ServerProcessOptions o;
    o.binary = server_binary();
    o.data_dir = data_dir;
    o.log_file = log_file;
    o.args = {"--threads", "2", "--log-level", "debug"};
    o.args.insert(o.args.end(), extra.begin(), extra.end());
    return o;
  }

  std::string log_file_;
  gd::ServerProcess process_;
  std::shared_ptr<grpc::Channel> channel_;
};

/// A client context with a deadline (tests never hang on a stuck server), stretched by
/// GD_TEST_DEADLINE_SCALE where set (scripts/sanitize: instrumented servers run 5-20x slower).
inline std::unique_ptr<grpc::ClientContext> ctx(double seconds = 60) {
  if (const char* s = std::getenv("GD_TEST_DEADLINE_SCALE"); s && std::atof(s) > 0) seconds *= std::atof(s);
  auto c = std::make_unique<grpc::ClientContext>();
  c->set_deadline(std::chrono::system_clock::now() + std::chrono::milliseconds(static_cast<int64_t>(seconds * 1000)));
  return c;
}

/// float32 (N, 3) array -> xyz triples.
inline std::vector<float> floats(const pb::Array& a) {
  std::vector<float> v(a.data().size() / 4);
  std::memcpy(v.data(), a.data().data(), v.size() * 4);
  return v;
}

inline pb::Array int_array(const std::vector<int32_t>& v) {
  pb::Array a;
  a.set_dtype("int32");
  a.add_shape(static_cast<int64_t>(v.size()));
  a.set_data(std::string(reinterpret_cast<const char*>(v.data()), v.size() * 4));
  return a;
}

inline pb::Array vec3_array(const std::vector<float>& xyz) {
  pb::Array a;
  a.set_dtype("float32");
  a.add_shape(static_cast<int64_t>(xyz.size() / 3));
  a.add_shape(3);
  a.set_data(std::string(reinterpret_cast<const char*>(xyz.data()), xyz.size() * 4));
  return a;
}

}  // namespace gd::service::testing
