// CpuExec::sum2_effects_to, the two sums of PCG's fused update pass: each term summed exactly
// as CpuExec::sum sums it (the same blocks in the same order, so the same bits), every
// iteration's effect applied once, and the same bits at any thread count.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "sim/backend/cpu/exec_cpu.h"
#include "sim/backend/cpu/omp_threads.h"

namespace gd::sim {
namespace {

double term_a(int i) { return std::sin(0.37 * i) * 1e3 + 1.0 / (i + 1); }
double term_b(int i) { return std::cos(0.11 * i) * std::exp(-1e-4 * i); }

struct Result {
  double a = 0, b = 0;
  std::vector<int> visits;
};

template <class Exec>
Result sum2(int n, int parallel_min) {
  Result r;
  r.visits.assign(n, 0);
  int* visits = r.visits.data();
  Exec::sum2_effects_to(n, [=](int i) {
    ++visits[i];  // an effect: each i exactly once
    return Sum2{term_a(i), term_b(i)};
  }, &r.a, &r.b, parallel_min);
  return r;
}

TEST(ExecSums, Sum2AddsEachTermAsSumDoes) {
  for (const int n : {0, 1, 100, 4095, 4096, 20000, 300000}) {
    for (const int parallel_min : {CpuExec::kParallelMin, CpuExec::kParallelMinHeavy, CpuExec::kParallelMinVector / 3}) {
      const Result r = sum2<CpuExec>(n, parallel_min);
      EXPECT_EQ(r.a, CpuExec::sum(n, term_a, parallel_min)) << "n " << n << ", parallel_min " << parallel_min;
      EXPECT_EQ(r.b, CpuExec::sum(n, term_b, parallel_min)) << "n " << n << ", parallel_min " << parallel_min;
      for (int i = 0; i < n; ++i) ASSERT_EQ(r.visits[i], 1) << "iteration " << i << " of " << n;
    }
  }
}

TEST(ExecSums, Sum2HasTheSameBitsAtOneAndTwoThreads) {
  const int before = omp_threads();
  set_omp_threads(1);
  const Result one = sum2<CpuExec>(300000, CpuExec::kParallelMinHeavy);
  set_omp_threads(2);
  const Result two = sum2<CpuExec>(300000, CpuExec::kParallelMinHeavy);
  set_omp_threads(before);
  EXPECT_EQ(one.a, two.a);
  EXPECT_EQ(one.b, two.b);
}

TEST(ExecSums, GpuPathsPolicySumsAsTheCpuDoes) {
  const Result cpu = sum2<CpuExec>(20000, CpuExec::kParallelMinVector / 3);
  const Result gpu_paths = sum2<CpuGpuPathsExec>(20000, CpuExec::kParallelMinVector / 3);
  EXPECT_EQ(cpu.a, gpu_paths.a);
  EXPECT_EQ(cpu.b, gpu_paths.b);
}

}  // namespace
}  // namespace gd::sim
