#pragma once
/// \file
/// One real gd-server process per test suite (gd::ServerProcess: a free loopback port, a fresh
/// data directory with its SQLite store), and small helpers shared by the client tests.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "gd/client.h"
#include "gd/server_process.h"

namespace gd::client_test {

/// Vertices of the test towels: small, so that a step takes milliseconds.
inline constexpr int kTowelVertices = 200;  // the generators' smallest

class ServerTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    ServerProcessOptions o;
    o.binary = GD_SERVER_BINARY;
    o.args = {"--threads", "2", "--log-level", "warn"};
    log_file_ = (std::filesystem::temp_directory_path() /
                 ("gd_client_tests_server_" + std::to_string(::getpid()) + ".log"))
                    .string();
    o.log_file = log_file_;
    server_ = std::make_unique<ServerProcess>(o);
  }
  /// Stops the server; its log is kept only when a test of the suite failed.
  static void TearDownTestSuite() {
    server_.reset();
    const auto* suite = ::testing::UnitTest::GetInstance()->current_test_suite();
    std::error_code ec;
    if (suite == nullptr || !suite->Failed()) std::filesystem::remove(log_file_, ec);
  }

  static const std::string& address() { return server_->address(); }
  static ServerProcess& server() { return *server_; }

  Client client_{address()};

  /// `count` towels of ~kTowelVertices vertices, self-contact off (fast), cotton.
  CreatedScenes make_towels(int count, uint64_t seed = 0) {
    SceneSpec spec;
    spec.garment = "towel";
    spec.vertices = kTowelVertices;
    spec.count = count;
    spec.seed = seed;
    spec.settings.self_contact = false;
    return client_.create_scenes(spec);
  }

 private:
  static inline std::unique_ptr<ServerProcess> server_;
  static inline std::string log_file_;
};

inline bool all_finite(const std::vector<float>& v) {
  for (float x : v)
    if (!std::isfinite(x)) return false;
  return true;
}

/// The largest |a_i - b_i| (infinity when the sizes differ).
inline double max_abs_diff(const std::vector<float>& a, const std::vector<float>& b) {
  if (a.size() != b.size()) return INFINITY;
  double m = 0;
  for (size_t i = 0; i < a.size(); ++i) m = std::max(m, static_cast<double>(std::abs(a[i] - b[i])));
  return m;
}

/// A fresh empty directory under the system's temporary directory.
inline std::filesystem::path fresh_dir(const std::string& name) {
  const auto d = std::filesystem::temp_directory_path() / ("gd_client_tests_" + std::to_string(::getpid())) / name;
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

}  // namespace gd::client_test
