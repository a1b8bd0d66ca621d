#pragma once
/// \file
/// A progress bar for command-line tools: redrawn in place on a terminal, one line per ~5% when
/// stderr is a file or pipe (CI logs). Library code reports progress through callbacks; only
/// the tools draw it.

#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string>

namespace gd::experiment {

class ProgressBar {
 public:
  /// `total` in whatever unit `update` is called with (steps, simulated seconds...).
  explicit ProgressBar(double total, std::string unit = "s")
      : total_(total), unit_(std::move(unit)), tty_(isatty(fileno(stderr)) != 0) {}

  /// Redraws when another ~5% is done (and at the end). `note` is appended (e.g. solver stats).
  void update(double done, const std::string& note = "") {
    const int pct = total_ > 0 ? static_cast<int>(100.0 * std::min(done, total_) / total_) : 100;
    if (pct < next_pct_ && done < total_) return;
    while (next_pct_ <= pct) next_pct_ += 5;
    constexpr int kWidth = 40;
    const int fill = kWidth * pct / 100;
    const double el = std::chrono::duration<double>(Clock::now() - start_).count();
    const double eta = done > 0 ? el * (total_ - done) / done : 0.0;
    std::fprintf(stderr, "%s[%s%s] %3d%%  %.2f/%.2f %s  elapsed %.1f s  eta %.1f s  %s%s", tty_ ? "\r" : "",
                 std::string(fill, '#').c_str(), std::string(kWidth - fill, '.').c_str(), pct, done, total_,
                 unit_.c_str(), el, eta > 0 ? eta : 0.0, note.c_str(), tty_ ? "" : "\n");
    if (tty_ && done >= total_) std::fprintf(stderr, "\n");
    std::fflush(stderr);
  }
  /// Ends a partially drawn bar (on failure or early stop).
  void finish() {
    if (tty_ && next_pct_ <= 100) std::fprintf(stderr, "\n");
  }

 private:
  using Clock = std::chrono::steady_clock;
  double total_;
  std::string unit_;
  bool tty_;
  int next_pct_ = 0;
  Clock::time_point start_ = Clock::now();
};

}  // namespace gd::experiment
