#include "stream_case.h"

#include <algorithm>
#include <chrono>
#include <stdexcept>

#include "sim/backend/cpu/omp_threads.h"
#include "sim/log.h"

namespace gd::bench {
namespace {

/// One pass over a[0, n) on `threads` threads, each a contiguous share; returns seconds.
double timed_pass(const std::vector<double>& a, int threads, double* sink) {
  const long n = static_cast<long>(a.size());
  const double* p = a.data();
  double total = 0;
  const auto t0 = std::chrono::steady_clock::now();
#pragma omp parallel num_threads(threads) reduction(+ : total)
  {
    const int t = omp_thread(), team = omp_team_size();
    const long lo = n * t / team, hi = n * (t + 1) / team;
    // One double of each 64-byte cache line, four independent sums: the whole line still comes
    // from memory, and the adds (a portable build has no wide vectors) stay far from the limit.
    double s[4] = {0, 0, 0, 0};
    long i = lo;
    for (; i + 32 <= hi; i += 32) s[0] += p[i], s[1] += p[i + 8], s[2] += p[i + 16], s[3] += p[i + 24];
    for (; i < hi; i += 8) s[0] += p[i];
    total += s[0] + s[1] + s[2] + s[3];
  }
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  *sink += total;
  return seconds;
}

}  // namespace

std::vector<StreamRow> run_stream_case(const StreamCaseOptions& opt) {
  const int threads = opt.threads > 0 ? opt.threads : omp_threads();
  std::vector<StreamRow> rows;
  double sink = 0;
  for (const double mb : opt.megabytes) {
    if (!(mb > 0)) throw std::invalid_argument("gd-bench stream: array sizes must be positive megabytes");
    std::vector<double> a(static_cast<size_t>(mb * 1e6 / sizeof(double)), 1.0);
    double best_one = 1e30, best_many = 1e30;
    for (int r = 0; r < std::max(1, opt.repeats); ++r) {
      best_one = std::min(best_one, timed_pass(a, 1, &sink));
      best_many = std::min(best_many, timed_pass(a, threads, &sink));
    }
    StreamRow row;
    row.megabytes = mb;
    row.threads = threads;
    const double bytes = static_cast<double>(a.size() * sizeof(double));
    row.one_thread_gb_s = bytes / best_one / 1e9;
    row.threads_gb_s = bytes / best_many / 1e9;
    row.scaling = row.threads_gb_s / row.one_thread_gb_s;
    gd::log().info("stream {:.1f} MB: 1 thread {:.1f} GB/s, {} threads {:.1f} GB/s ({:.2f}x)", mb, row.one_thread_gb_s,
                   threads, row.threads_gb_s, row.scaling);
    rows.push_back(row);
  }
  if (sink < 0) gd::log().debug("stream: {}", sink);  // keeps the sums
  return rows;
}

nlohmann::json to_json(const StreamRow& r) {
  return {{"case", "stream"},          {"megabytes", r.megabytes},        {"threads", r.threads},
          {"one_thread_gb_s", r.one_thread_gb_s}, {"threads_gb_s", r.threads_gb_s}, {"scaling", r.scaling}};
}

}  // namespace gd::bench
