#pragma once
// Test helpers of the service's integration tests: a temporary directory, and a real gd-server
// process (GD_SERVER_BIN) started on a free loopback port (--port 0 --port-file), killed in the
// destructor.

#include <fcntl.h>
#include <gtest/gtest.h>
#include <grpcpp/grpcpp.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "garmentdynamics/v1/garmentdynamics.grpc.pb.h"

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

/// A gd-server process on a free loopback port, with its data in `data_dir`.
class ServerProcess {
 public:
  explicit ServerProcess(const std::string& data_dir, std::vector<std::string> extra = {}) : data_dir_(data_dir) {
    fs::create_directories(data_dir);
    port_file_ = data_dir + "/port";
    log_file_ = data_dir + "/../" + fs::path(data_dir).filename().string() + "-server.log";
    fs::remove(port_file_);
    std::vector<std::string> args = {server_binary(), "--port",    "0",        "--port-file", port_file_,
                                     "--data-dir",    data_dir,    "--threads", "2",           "--log-level",
                                     "debug"};
    args.insert(args.end(), extra.begin(), extra.end());
    pid_ = fork();
    if (pid_ == 0) {
      const int fd = ::open(log_file_.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
      if (fd >= 0) {
        dup2(fd, 1);
        dup2(fd, 2);
      }
      std::vector<char*> argv;
      for (auto& a : args) argv.push_back(a.data());
      argv.push_back(nullptr);
      execv(argv[0], argv.data());
      _exit(127);
    }
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (std::chrono::steady_clock::now() < deadline) {
      int status = 0;
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        throw std::runtime_error("gd-server (" + server_binary() + ") exited at startup with status " +
                                 std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -WTERMSIG(status)) +
                                 "; its log:\n" + log());
      }
      std::ifstream f(port_file_);
      if (f >> port_ && port_ > 0) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    if (port_ <= 0) throw std::runtime_error("gd-server did not write its port within 30 s; its log:\n" + log());
    channel_ = grpc::CreateChannel(address(), grpc::InsecureChannelCredentials());
    if (!channel_->WaitForConnected(std::chrono::system_clock::now() + std::chrono::seconds(10)))
      throw std::runtime_error("cannot connect to gd-server at " + address());
  }
  ~ServerProcess() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
  }
  ServerProcess(const ServerProcess&) = delete;
  ServerProcess& operator=(const ServerProcess&) = delete;

  int port() const { return port_; }
  pid_t pid() const { return pid_; }
  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  std::shared_ptr<grpc::Channel> channel() const { return channel_; }
  std::unique_ptr<pb::GarmentDynamics::Stub> stub() const { return pb::GarmentDynamics::NewStub(channel_); }
  std::string log() const {
    std::ifstream f(log_file_);
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
  }

  /// kill -9, waits for the process.
  void kill9() {
    ::kill(pid_, SIGKILL);
    waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }
  /// Sends a signal and waits up to timeout_s for the exit. Returns the exit code (-1: killed by
  /// a signal or did not exit in time).
  int signal_and_wait(int sig, double timeout_s) {
    ::kill(pid_, sig);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::duration<double>(timeout_s);
    int status = 0;
    while (std::chrono::steady_clock::now() < deadline) {
      if (waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return -1;
  }

 private:
  std::string data_dir_, port_file_, log_file_;
  pid_t pid_ = -1;
  int port_ = 0;
  std::shared_ptr<grpc::Channel> channel_;
};

/// A client context with a deadline (tests never hang on a stuck server).
inline std::unique_ptr<grpc::ClientContext> ctx(double seconds = 60) {
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
