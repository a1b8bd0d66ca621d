#pragma once
// Helpers shared by the gd_metrics tests.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "metrics/cloud_io.h"
#include "sim/demand.h"

namespace gd::metrics::testing {

/// Removes the directories made by temp_dir when the test binary exits.
struct TempDirs {
  std::vector<std::filesystem::path> dirs;
  ~TempDirs() {
    std::error_code ec;
    for (const auto& d : dirs) std::filesystem::remove_all(d, ec);
  }
};

/// A fresh per-process, per-test directory under the system temp dir (removed at exit).
inline std::string temp_dir(const std::string& name) {
  static TempDirs made;
  const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
  const auto d = std::filesystem::temp_directory_path() /
                 ("gd_metrics_" + std::to_string(::getpid()) + "_" + info->name() + "_" + name);
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  made.dirs.push_back(d);
  return d.string();
}

inline Cloud random_cloud(size_t n, unsigned seed, float scale = 1.0f) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-scale, scale);
  Cloud c(n);
  for (auto& p : c) p = Eigen::Vector3f(u(rng), u(rng), u(rng));
  return c;
}

/// The RGBench data folder: $GD_SHARED_DIR/data/rgbench, else <repo>/../shared/data/rgbench
/// (found from gd_sim's GD_DEFAULT_DATA_DIR = <repo>/data); "" when neither exists.
inline std::string rgbench_data_dir() {
  std::filesystem::path shared;
  if (const char* s = std::getenv("GD_SHARED_DIR"); s && *s) {
    shared = s;
  } else {
#ifdef GD_DEFAULT_DATA_DIR
    shared = std::filesystem::path(GD_DEFAULT_DATA_DIR).parent_path().parent_path() / "shared";
#endif
  }
  const auto d = shared / "data" / "rgbench";
  return !shared.empty() && std::filesystem::is_directory(d) ? d.string() : "";
}

/// Expects `f` to throw an InputError whose message contains `needle`.
template <class F>
void expect_input_error(F&& f, const std::string& needle) {
  try {
    f();
    ADD_FAILURE() << "no InputError thrown";
  } catch (const sim::InputError& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

}  // namespace gd::metrics::testing
