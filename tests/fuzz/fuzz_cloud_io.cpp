// libFuzzer target: a point-cloud file (metrics::load_cloud, PCL's PCD and PLY readers behind
// it), as jobs with a capture read its frames and `gd metrics --real FILE` reads one. The input
// is written as a .ply file when it starts with "ply" (every PLY file does), as a .pcd file
// otherwise. Expected: a cloud of finite points, or sim::InputError.

#include <pcl/console/print.h>

#include <cstring>

#include "fuzz_common.h"
#include "metrics/cloud_io.h"

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  gd::fuzz::quiet_logs();
  // load_cloud lowers PCL's console to errors on its first call; PCL's error lines for broken
  // files would still flood the log: load one cloud, then silence PCL for good.
  const char kOne[] = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\nWIDTH 1\nHEIGHT 1\n"
                      "POINTS 1\nDATA ascii\n0 0 0\n";
  gd::metrics::load_cloud(gd::fuzz::write_input("init.pcd", reinterpret_cast<const uint8_t*>(kOne), sizeof kOne - 1));
  if (!std::getenv("GD_LOG_LEVEL")) pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const bool ply = size >= 3 && std::memcmp(data, "ply", 3) == 0;
  const std::string path = gd::fuzz::write_input(ply ? "frame.ply" : "frame.pcd", data, size);
  gd::metrics::Cloud c;
  if (!gd::fuzz::input_errors_only([&] { c = gd::metrics::load_cloud(path); })) return 0;
  for (size_t i = 0; i < c.size(); ++i) GD_FUZZ_CHECK(c[i].allFinite(), "point " + std::to_string(i));
  return 0;
}
