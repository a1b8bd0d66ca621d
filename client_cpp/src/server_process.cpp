#include "gd/server_process.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <thread>

extern char** environ;

namespace gd {

namespace {

[[noreturn]] void fail(const std::string& message) {
  throw ClientError(StatusCode::kUnavailable, message, "ServerProcess");
}

int decode_wait_status(int status) {
  if (WIFEXITED(status)) return WEXITSTATUS(status);
  if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
  return -1;
}

std::string read_text(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::string log_tail(const std::string& path) {
  if (path.empty()) return "";
  const std::string s = read_text(path);
  return "; its log ends:\n" + (s.size() > 2000 ? s.substr(s.size() - 2000) : s);
}

/// The port in the server's --port-file, or 0 while it is not (completely) written.
int read_port(const std::string& path) {
  const std::string s = read_text(path);
  if (s.empty() || s.back() != '\n') return 0;  // written with a trailing newline when complete
  try {
    return std::stoi(s);
  } catch (const std::exception&) {
    return 0;
  }
}

}  // namespace

ServerProcess::ServerProcess(ServerProcessOptions options) : options_(std::move(options)) {
  std::string scratch = (std::filesystem::temp_directory_path() / "gd-server-XXXXXX").string();
  if (::mkdtemp(scratch.data()) == nullptr) fail("cannot create a temporary directory: " + std::string(std::strerror(errno)));
  scratch_dir_ = scratch;
  data_dir_ = options_.data_dir.empty() ? scratch_dir_ + "/data" : options_.data_dir;
  const std::string port_file = scratch_dir_ + "/port";

  std::vector<std::string> argv_s = {options_.binary, "--host",      options_.host,  "--port", std::to_string(options_.port),
                                     "--port-file",   port_file,     "--data-dir",   data_dir_};
  argv_s.insert(argv_s.end(), options_.args.begin(), options_.args.end());
  std::vector<char*> argv;
  for (auto& a : argv_s) argv.push_back(a.data());
  argv.push_back(nullptr);

  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  if (!options_.log_file.empty()) {
    posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, options_.log_file.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_adddup2(&actions, STDOUT_FILENO, STDERR_FILENO);
  }
  pid_t pid = -1;
  const int rc = posix_spawnp(&pid, options_.binary.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    stop();
    fail("cannot start '" + options_.binary + "': " + std::strerror(rc));
  }
  pid_ = pid;

  // Wait for the port file, then for the health check to answer SERVING; give up when the
  // process exits or the time is out.
  const auto until = std::chrono::steady_clock::now() + options_.start_timeout;
  std::string last_error = "no port file yet";
  std::unique_ptr<Client> client;
  while (std::chrono::steady_clock::now() < until) {
    if (!running()) {
      const int status = exit_status_;
      const std::string tail = log_tail(options_.log_file);
      stop();
      fail(options_.binary + " exited with status " + std::to_string(status) + " before serving" + tail);
    }
    if (!client) {
      port_ = options_.port > 0 ? options_.port : read_port(port_file);
      if (port_ > 0) {
        address_ = options_.host + ":" + std::to_string(port_);
        ClientOptions co = options_.client;
        co.deadline = std::chrono::milliseconds(1000);
        client = std::make_unique<Client>(address_, co);
      }
    }
    if (client) {
      try {
        if (client->health() == HealthStatus::kServing) return;
        last_error = "health status not SERVING";
      } catch (const ClientError& e) {
        last_error = e.what();
      }
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  const std::string tail = log_tail(options_.log_file);
  stop(std::chrono::milliseconds(2000));
  fail(options_.binary + " did not serve within " + std::to_string(options_.start_timeout.count()) + " ms (" +
       last_error + ")" + tail);
}

ServerProcess::~ServerProcess() { stop(); }

bool ServerProcess::running() {
  if (pid_ <= 0) return false;
  int status = 0;
  const pid_t r = ::waitpid(pid_, &status, WNOHANG);
  if (r == 0) return true;
  if (r == pid_) exit_status_ = decode_wait_status(status);
  return false;
}

void ServerProcess::signal(int sig) {
  if (running()) ::kill(pid_, sig);
}

int ServerProcess::wait(std::chrono::milliseconds timeout) {
  const auto until = std::chrono::steady_clock::now() + timeout;
  while (running() && std::chrono::steady_clock::now() < until)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  return running() ? -1 : exit_status_;
}

int ServerProcess::stop(std::chrono::milliseconds grace) {
  if (running()) {
    signal(SIGTERM);
    if (wait(grace) < 0) {
      ::kill(pid_, SIGKILL);
      int status = 0;
      if (::waitpid(pid_, &status, 0) == pid_) exit_status_ = decode_wait_status(status);
    }
  }
  pid_ = -1;
  if (!scratch_dir_.empty()) {
    std::error_code ec;
    std::filesystem::remove_all(scratch_dir_, ec);  // the data too, unless it lives elsewhere
    scratch_dir_.clear();
  }
  return exit_status_;
}

}  // namespace gd
