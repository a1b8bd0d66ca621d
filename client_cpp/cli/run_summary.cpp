#include "run_summary.h"

#include <cstdio>

namespace gd::cli {

namespace {

std::string str(const nlohmann::json& s, const char* key) {
  return s.contains(key) && s[key].is_string() ? s[key].get<std::string>() : std::string("?");
}

double num(const nlohmann::json& s, const char* key) {
  return s.contains(key) && s[key].is_number() ? s[key].get<double>() : 0.0;
}

}  // namespace

void print_run_summary(const nlohmann::json& s, const std::string& out_dir) {
  std::printf("%s / %s / %s (%s): %d vertices, %d steps, %.1f s wall (%.0f ms/step), max intersecting pairs %d, "
              "untangling %d\n",
              str(s, "garment").c_str(), str(s, "material").c_str(), str(s, "task").c_str(), str(s, "mode").c_str(),
              static_cast<int>(num(s, "vertices")), static_cast<int>(num(s, "steps")), num(s, "wall_seconds"),
              num(s, "ms_per_step"), static_cast<int>(num(s, "intersecting_pairs_max")),
              static_cast<int>(num(s, "untangle_runs")));
  if (s.contains("cd_l1_r2s"))
    std::printf("metrics (mean over %d frames): cd_l1_r2s %.4f  cd_l1_s2r %.4f  cd_l2_s2r %.4f  hd_s2r %.4f  "
                "hd_r2s %.4f  z_err %.4f  sim_stab %.4f\n",
                static_cast<int>(num(s, "frames_in_window")), num(s, "cd_l1_r2s"), num(s, "cd_l1_s2r"),
                num(s, "cd_l2_s2r"), num(s, "hd_s2r"), num(s, "hd_r2s"), num(s, "z_err"), num(s, "sim_stab"));
  std::printf("wrote %s/summary.json\n", out_dir.c_str());
}

}  // namespace gd::cli
