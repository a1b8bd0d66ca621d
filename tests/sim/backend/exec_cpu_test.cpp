// CpuExec's reductions and sort.
// sum2_effects_to, the two sums of PCG's fused update pass: each term summed exactly as
// CpuExec::sum sums it (the same blocks in the same order, so the same bits), every iteration's
// effect applied once, and the same bits at any thread count.
// The blocks are shared out as whole runs within half a block of an even split of the items, or
// of their work where items differ in cost (sum_effects_balanced_to, the same bits).
// sort: from kParallelMinVector keys on, runs sorted by the threads and merged pairwise; every
// count of threads and keys gives std::sort's array, duplicates and sorted or reversed input
// included.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
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

TEST(ExecSums, Sum2HasTheSameBitsAtAnyThreadCount) {
  const int before = omp_threads();
  // 4867: RGBench's T-shirt's rows, 39 product blocks (an odd count, the last one 3 rows long).
  for (const int n : {300000, 4867}) {
    set_omp_threads(1);
    const Result one = sum2<CpuExec>(n, CpuExec::kParallelMinHeavy);
    for (const int threads : {2, 3}) {
      set_omp_threads(threads);
      const Result more = sum2<CpuExec>(n, CpuExec::kParallelMinHeavy);
      EXPECT_EQ(one.a, more.a) << n << " terms, " << threads << " threads";
      EXPECT_EQ(one.b, more.b) << n << " terms, " << threads << " threads";
      for (int i = 0; i < n; ++i) ASSERT_EQ(more.visits[i], 1) << "iteration " << i << " of " << n;
    }
  }
  set_omp_threads(before);
}

TEST(ExecSums, EachThreadTakesWholeBlocksWithinHalfABlockOfAnEvenShare) {
  for (const int n : {1, 100, 4096, 4867, 14601, 20000, 300001}) {
    for (const int block : {64, 128, 512}) {
      const int blocks = (n + block - 1) / block;
      for (int threads = 1; threads <= 5; ++threads) {
        EXPECT_EQ(CpuExec::first_block_of(0, threads, n, block, blocks), 0);
        EXPECT_EQ(CpuExec::first_block_of(threads, threads, n, block, blocks), blocks);
        for (int t = 0; t < threads; ++t) {
          const int b0 = CpuExec::first_block_of(t, threads, n, block, blocks);
          const int b1 = CpuExec::first_block_of(t + 1, threads, n, block, blocks);
          ASSERT_LE(b0, b1) << "thread " << t << " of " << threads;
          const double items = std::min(n, b1 * block) - std::min(n, b0 * block);
          EXPECT_LE(std::abs(items - static_cast<double>(n) / threads), block + 1.0)
              << "thread " << t << " of " << threads << ", " << n << " items in blocks of " << block;
        }
      }
    }
  }
  // The T-shirt's product at 2 threads: 2432 and 2435 rows (a static schedule of the blocks: 2560
  // and 2307).
  EXPECT_EQ(CpuExec::first_block_of(1, 2, 4867, 128, 39), 19);
}

// Rows of unequal work (the block product's: the rows where contact couplings add blocks cost
// more): the threads split the work, not the rows, evenly, and the sum keeps its bits.
TEST(ExecSums, BalancedSumSplitsTheWorkAndKeepsTheBits) {
  const int n = 4867, block = 128, blocks = (n + block - 1) / block;
  // Rows past 3000 carry four times the work of the others.
  auto work_before = [](int i) -> int64_t { return i + 3 * static_cast<int64_t>(std::max(0, i - 3000)); };
  const double total = static_cast<double>(work_before(n));
  for (int threads = 2; threads <= 4; ++threads) {
    EXPECT_EQ(CpuExec::first_block_of(0, threads, n, block, blocks, work_before), 0);
    EXPECT_EQ(CpuExec::first_block_of(threads, threads, n, block, blocks, work_before), blocks);
    for (int t = 0; t < threads; ++t) {
      const int b0 = CpuExec::first_block_of(t, threads, n, block, blocks, work_before);
      const int b1 = CpuExec::first_block_of(t + 1, threads, n, block, blocks, work_before);
      ASSERT_LE(b0, b1);
      const double work = static_cast<double>(work_before(std::min(n, b1 * block)) - work_before(std::min(n, b0 * block)));
      // Within one heavy block's work of an even share (half a block at each end).
      EXPECT_LE(std::abs(work - total / threads), 4.0 * block) << "thread " << t << " of " << threads;
    }
  }
  // Two threads by row count: 2432 and 2435 rows, 2432 and 8036 units of work; by work 3584
  // and 1283 rows, 5336 and 5132 units.
  EXPECT_EQ(CpuExec::first_block_of(1, 2, n, block, blocks), 19);
  EXPECT_EQ(CpuExec::first_block_of(1, 2, n, block, blocks, work_before), 28);

  const int before = omp_threads();
  set_omp_threads(1);
  double one = 0;
  CpuExec::sum_effects_to(n, term_a, &one, CpuExec::kParallelMinHeavy);
  for (const int threads : {2, 3}) {
    set_omp_threads(threads);
    std::vector<int> visits(n, 0);
    int* v = visits.data();
    double balanced = 0;
    CpuExec::sum_effects_balanced_to(n, [=](int i) {
      ++v[i];
      return term_a(i);
    }, work_before, &balanced, CpuExec::kParallelMinHeavy);
    EXPECT_EQ(balanced, one) << threads << " threads";
    for (int i = 0; i < n; ++i) ASSERT_EQ(visits[i], 1) << "row " << i;
  }
  set_omp_threads(before);
}

TEST(ExecSums, GpuPathsPolicySumsAsTheCpuDoes) {
  const Result cpu = sum2<CpuExec>(20000, CpuExec::kParallelMinVector / 3);
  const Result gpu_paths = sum2<CpuGpuPathsExec>(20000, CpuExec::kParallelMinVector / 3);
  EXPECT_EQ(cpu.a, gpu_paths.a);
  EXPECT_EQ(cpu.b, gpu_paths.b);
}

std::vector<uint64_t> random_keys(int n, uint64_t range, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<uint64_t> u(0, range);
  std::vector<uint64_t> v(n);
  for (uint64_t& k : v) k = u(rng);
  return v;
}

TEST(ExecSort, EveryThreadCountGivesStdSortsArray) {
  const int before = omp_threads();
  for (int threads : {1, 2, 3, 5}) {
    set_omp_threads(threads);
    for (int n : {0, 1, 7, CpuExec::kParallelMinVector - 1, CpuExec::kParallelMinVector, 10007, 65536}) {
      for (uint64_t range : {uint64_t{5}, ~uint64_t{0}}) {  // many duplicates, then nearly none
        std::vector<uint64_t> v = random_keys(n, range, 17u + static_cast<unsigned>(n));
        std::vector<uint64_t> expected = v;
        std::sort(expected.begin(), expected.end());
        CpuExec::sort(v);
        EXPECT_EQ(v, expected) << n << " keys, range " << range << ", " << threads << " threads";
      }
    }
    std::vector<uint64_t> sorted = random_keys(20000, ~uint64_t{0}, 3);
    std::sort(sorted.begin(), sorted.end());
    std::vector<uint64_t> v = sorted;
    CpuExec::sort(v);
    EXPECT_EQ(v, sorted) << threads << " threads, sorted input";
    std::reverse(v.begin(), v.end());
    CpuExec::sort(v);
    EXPECT_EQ(v, sorted) << threads << " threads, reversed input";
  }
  set_omp_threads(before);
}

}  // namespace
}  // namespace gd::sim
