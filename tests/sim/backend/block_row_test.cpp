// The block product's row (sim/block_row.h): the CPU backend's (AVX2 where the processor has it)
// gives the same bits as the portable loop the GPU runs, on rows of every length (empty, one
// block, odd and even counts), with and without a second matrix, reading x up to its last
// vertex; and both are the product y = (A + C) x to rounding.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "sim/backend/cpu/block_row_cpu.h"

namespace gd::sim {
namespace {

struct RandomBlockCsr {
  std::vector<int> row_ptr{0}, cols;
  std::vector<double> vals;
  BlockRows rows() const { return {row_ptr.data(), cols.data(), vals.data()}; }
};

/// n rows of 0..max_blocks blocks each, columns anywhere in [0, n) (the last vertex often).
RandomBlockCsr random_csr(int n, int max_blocks, std::mt19937& rng) {
  RandomBlockCsr m;
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  for (int i = 0; i < n; ++i) {
    const int blocks = static_cast<int>(rng() % (max_blocks + 1));
    for (int b = 0; b < blocks; ++b) {
      m.cols.push_back(b % 3 == 0 ? n - 1 : static_cast<int>(rng() % n));
      for (int v = 0; v < 9; ++v) m.vals.push_back(value(rng) * std::pow(10.0, static_cast<int>(rng() % 7) - 3));
    }
    m.row_ptr.push_back(static_cast<int>(m.cols.size()));
  }
  return m;
}

TEST(BlockRow, TheCpuPathGivesThePortableLoopsBitsAndTheProduct) {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  // The AVX2 path is the one compared wherever the processor has it.
  EXPECT_EQ(block_row_uses_avx2(), __builtin_cpu_supports("avx2") != 0);
#endif
  std::mt19937 rng(7);
  const int n = 300;
  const RandomBlockCsr a = random_csr(n, 25, rng), c = random_csr(n, 11, rng);
  // x exactly 3n long, so a read past the last vertex would leave the allocation (ASan, valgrind).
  std::vector<double> x(3 * n);
  std::uniform_real_distribution<double> value(-2.0, 2.0);
  for (double& v : x) v = value(rng);
  for (const bool couplings : {false, true}) {
    const BlockRows A = a.rows();
    const BlockRows C = couplings ? c.rows() : BlockRows{};
    for (int i = 0; i < n; ++i) {
      double cpu[3], portable[3];
      block_row_product_cpu(i, A, C, x.data(), cpu);
      block_row_product(i, A, C, x.data(), portable);
      ASSERT_EQ(0, std::memcmp(cpu, portable, sizeof cpu)) << "row " << i << ", couplings " << couplings;
      // The product itself, summed row by row in long double.
      for (int r = 0; r < 3; ++r) {
        long double want = 0, scale = 0;
        for (const RandomBlockCsr* m : {&a, couplings ? &c : nullptr}) {
          if (!m) continue;
          for (int k = m->row_ptr[i]; k < m->row_ptr[i + 1]; ++k)
            for (int col = 0; col < 3; ++col) {
              const long double term = static_cast<long double>(m->vals[9 * k + 3 * r + col]) * x[3 * m->cols[k] + col];
              want += term;
              scale += std::fabs(static_cast<double>(term));
            }
        }
        EXPECT_NEAR(static_cast<double>(want), cpu[r], 1e-14 * static_cast<double>(scale) + 1e-300) << "row " << i;
      }
    }
  }
}

TEST(BlockRow, AnEmptyRowIsZero) {
  const std::vector<int> row_ptr{0, 0};
  const std::vector<double> x{1.0, 2.0, 3.0};
  const BlockRows A{row_ptr.data(), nullptr, nullptr};
  double y[3] = {7, 7, 7};
  block_row_product_cpu(0, A, BlockRows{}, x.data(), y);
  EXPECT_EQ(y[0], 0.0);
  EXPECT_EQ(y[1], 0.0);
  EXPECT_EQ(y[2], 0.0);
}

}  // namespace
}  // namespace gd::sim
