#pragma once
/// \file
/// The short summary `gd run` prints after a run, local or remote (from its summary.json).

#include <nlohmann/json.hpp>
#include <string>

namespace gd::cli {

/// Prints the run line (garment, material, task, mode, size, timing, contact health), the
/// metrics line when the run had a capture, and "wrote OUT/summary.json". Keys missing from
/// `summary` print as "?" / 0 rather than throwing.
void print_run_summary(const nlohmann::json& summary, const std::string& out_dir);

}  // namespace gd::cli
