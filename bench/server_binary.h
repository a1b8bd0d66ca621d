#pragma once
/// \file
/// The gd-server that gd-bench's service and load cases start by default.

#include <filesystem>
#include <string>

namespace gd::bench {

/// The gd-server beside this executable (its build directory's bin/), else "gd-server" on PATH.
inline std::string default_server_binary() {
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  return ec ? std::string("gd-server") : (self.parent_path() / "gd-server").string();
}

}  // namespace gd::bench
