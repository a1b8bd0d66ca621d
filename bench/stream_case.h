#pragma once
/// \file
/// gd-bench stream: how this machine's memory reads scale with threads, the ceiling of a
/// memory-bound stage's thread scaling (PCG's block product streams the Hessian's blocks every
/// iteration: about 4.6 MB on RGBench's 4867-vertex T-shirt).
///
/// For each array size, the array of doubles is read `repeats` times by one thread and by
/// `threads` threads, each thread a contiguous share as the solver's static schedules split rows
/// (one value of each cache line summed, so that the arithmetic never limits); the best pass of
/// each gives a read rate in GB/s, and their ratio is the most a loop that only streams that much
/// memory can gain from the threads. The two sides alternate pass
/// by pass, so that a machine whose speed drifts affects both alike.

#include <nlohmann/json.hpp>
#include <vector>

namespace gd::bench {

struct StreamCaseOptions {
  std::vector<double> megabytes{1.0, 4.6, 16.0, 64.0};  ///< array sizes, MB (1e6 bytes)
  int threads = 0;                                      ///< the many-thread side (0: all cores)
  int repeats = 30;                                     ///< passes per side and size
};

struct StreamRow {
  double megabytes = 0;
  int threads = 0;
  double one_thread_gb_s = 0, threads_gb_s = 0;
  double scaling = 0;  ///< threads_gb_s / one_thread_gb_s
};

/// Runs the probe (progress on the log); throws std::invalid_argument on a size <= 0.
std::vector<StreamRow> run_stream_case(const StreamCaseOptions& opt);
nlohmann::json to_json(const StreamRow& r);

}  // namespace gd::bench
