#include "sim/log.h"

#include <spdlog/sinks/stdout_color_sinks.h>

#include <cstdlib>

#include "sim/demand.h"

namespace gd {

spdlog::logger& log() {
  static std::shared_ptr<spdlog::logger> logger = [] {
    auto l = spdlog::get("gd");
    if (!l) l = spdlog::stderr_color_mt("gd");
    if (const char* lvl = std::getenv("GD_LOG_LEVEL")) l->set_level(spdlog::level::from_str(lvl));
    return l;
  }();
  return *logger;
}

}  // namespace gd

namespace gd::sim {

void demand_failed(const char* cond, const char* file, int line, const std::string& msg) {
  gd::log().critical("invariant failed: {} ({}:{}) {}", cond, file, line, msg);
  gd::log().flush();
  std::abort();
}

}  // namespace gd::sim
