#pragma once
// A per-test output directory under the system temp dir, removed when the test ends unless
// GD_KEEP_TEST_OUTPUT is set (to look at a failing run's files).
#include <cstdlib>
#include <filesystem>
#include <string>
#include <system_error>

namespace gd::experiment::testing {

class TempDir {
 public:
  explicit TempDir(const std::string& name)
      : path_(std::filesystem::temp_directory_path() / ("gd_experiment_test_" + name)) {
    std::filesystem::remove_all(path_);
  }
  ~TempDir() {
    std::error_code ec;
    if (!std::getenv("GD_KEEP_TEST_OUTPUT")) std::filesystem::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  std::string str() const { return path_.string(); }
  std::string operator/(const std::string& sub) const { return (path_ / sub).string(); }

 private:
  std::filesystem::path path_;
};

}  // namespace gd::experiment::testing
