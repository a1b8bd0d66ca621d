#pragma once
/// \file
/// The project's one spdlog logger ("gd"). Library code logs through gd::log(); nothing prints
/// to std::cout.

#include <spdlog/spdlog.h>

namespace gd {

/// The shared logger; created on first use, writes to stderr.
spdlog::logger& log();

}  // namespace gd
