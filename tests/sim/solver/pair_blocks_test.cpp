// The contact couplings' block CSR: the sums of a plain map, columns in order of first
// appearance, Dirichlet vertices and zero sums left out, the same bits on one thread and on
// several.
#include "sim/solver/pair_blocks.h"

#include <gtest/gtest.h>

#include <map>
#include <random>
#include <utility>
#include <vector>

#include "sim/backend/cpu/omp_threads.h"

namespace gd::sim {
namespace {

struct RandomPairs {
  std::vector<int> v;
  std::vector<double> H;
  PairHessians view() const { return {static_cast<int>(v.size() / 4), v.data(), H.data()}; }
};

/// `count` pairs of 4 distinct vertices among the first `span` of n (so pairs share couplings).
RandomPairs random_pairs(int count, int span, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> vertex(0, span - 1);
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  RandomPairs p;
  for (int c = 0; c < count; ++c) {
    int vs[4];
    for (int a = 0; a < 4; ++a) {
      bool repeat = true;
      while (repeat) {
        vs[a] = vertex(rng);
        repeat = false;
        for (int b = 0; b < a; ++b) repeat = repeat || vs[b] == vs[a];
      }
      p.v.push_back(vs[a]);
    }
    for (int k = 0; k < kPairBlockValues; ++k) p.H.push_back(value(rng));
  }
  return p;
}

/// The reference: a map from (row, col) to the summed block, same summation order.
std::map<std::pair<int, int>, std::vector<double>> reference(const std::vector<PairHessians>& lists,
                                                             const std::vector<int>& fixed) {
  std::map<std::pair<int, int>, std::vector<double>> m;
  for (const PairHessians& l : lists)
    for (int c = 0; c < l.count; ++c)
      for (int a = 0; a < 4; ++a)
        for (int b = 0; b < 4; ++b) {
          const int r = l.v[4 * c + a], col = l.v[4 * c + b];
          if (a == b || fixed[r] || fixed[col]) continue;
          auto& blk = m[{r, col}];
          blk.resize(9, 0.0);
          for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j)  // block (a, b) is stored for a < b, (b, a) as its transpose
              blk[3 * i + j] += a < b ? l.H[kPairBlockValues * c + pair_block_offset(a, b) + 3 * i + j]
                                      : l.H[kPairBlockValues * c + pair_block_offset(b, a) + 3 * j + i];
        }
  return m;
}

TEST(PairBlocks, SumsEveryOffDiagonalBlockOfFreeVertices) {
  const int n = 3000;
  const RandomPairs act = random_pairs(6000, 900, 1), fr = random_pairs(2500, 900, 2);
  std::vector<int> fixed(n, 0);
  for (int i = 0; i < n; i += 7) fixed[i] = 1;
  const std::vector<PairHessians> lists{act.view(), fr.view()};
  CouplingMatrix out;
  merge_pair_blocks(n, fixed.data(), lists, &out);
  const auto ref = reference(lists, fixed);
  ASSERT_EQ(out.row_ptr.size(), size_t(n) + 1);
  ASSERT_EQ(out.row_ptr[n], static_cast<int>(ref.size()));
  for (int i = 0; i < n; ++i) {
    for (int k = out.row_ptr[i]; k < out.row_ptr[i + 1]; ++k) {
      const auto it = ref.find({i, out.cols[k]});
      ASSERT_NE(it, ref.end()) << "row " << i << " col " << out.cols[k];
      for (int e = 0; e < 9; ++e) EXPECT_EQ(out.vals[9 * k + e], it->second[e]);
      for (int q = out.row_ptr[i]; q < k; ++q) EXPECT_NE(out.cols[q], out.cols[k]) << "a column twice in row " << i;
    }
  }
}

TEST(PairBlocks, ColumnsComeInTheOrderTheyFirstAppear) {
  // Pair 0 couples 0-1, 0-2, 0-3; pair 1 couples 0 with 5, 4, 1 (1 already there).
  const std::vector<int> v{0, 1, 2, 3, 0, 5, 4, 1};
  std::vector<double> H(2 * kPairBlockValues, 1.0);
  const std::vector<int> fixed(6, 0);
  CouplingMatrix out;
  merge_pair_blocks(6, fixed.data(), {PairHessians{2, v.data(), H.data()}}, &out);
  const std::vector<int> row0(out.cols.begin() + out.row_ptr[0], out.cols.begin() + out.row_ptr[1]);
  EXPECT_EQ(row0, (std::vector<int>{1, 2, 3, 5, 4}));
  EXPECT_EQ(out.vals[9 * (out.row_ptr[0] + 0)], 2.0);  // 0-1 in both pairs
  EXPECT_EQ(out.vals[9 * (out.row_ptr[0] + 3)], 1.0);
}

TEST(PairBlocks, ColumnsThatSumToZeroGetNoSlot) {
  // Pair 0 couples 0-1, 0-2, 0-3, pair 1 couples 0 with 5, 4, 1. Pair 0's block (0, 2) is zero
  // (a barrier coupling only its closest feature's corners), and pair 1's (0, 1) cancels pair 0's.
  const std::vector<int> v{0, 1, 2, 3, 0, 5, 4, 1};
  std::vector<double> H(2 * kPairBlockValues, 1.0);
  for (int q = 0; q < 9; ++q) H[pair_block_offset(0, 2) + q] = 0.0;
  for (int q = 0; q < 9; ++q) H[kPairBlockValues + pair_block_offset(0, 3) + q] = -1.0;
  const std::vector<int> fixed(6, 0);
  CouplingMatrix out;
  merge_pair_blocks(6, fixed.data(), {PairHessians{2, v.data(), H.data()}}, &out);
  const std::vector<int> row0(out.cols.begin() + out.row_ptr[0], out.cols.begin() + out.row_ptr[1]);
  EXPECT_EQ(row0, (std::vector<int>{3, 5, 4}));  // 1 cancelled, 2 zero; the others in order
  const std::vector<int> row2(out.cols.begin() + out.row_ptr[2], out.cols.begin() + out.row_ptr[3]);
  EXPECT_EQ(row2, (std::vector<int>{1, 3}));  // (2, 0) is the zero block's transpose
  for (int k = 0; k < out.row_ptr[6]; ++k) {
    bool zero = true;
    for (int q = 0; q < 9; ++q) zero = zero && out.vals[9 * k + q] == 0.0;
    EXPECT_FALSE(zero) << "slot " << k << " is zero";
  }
}

TEST(PairBlocks, NoPairsLeaveOneZeroBlock) {
  const std::vector<int> fixed(4, 0);
  CouplingMatrix out;
  merge_pair_blocks(4, fixed.data(), {PairHessians{}}, &out);
  EXPECT_EQ(out.row_ptr, std::vector<int>(5, 0));
  ASSERT_EQ(out.cols.size(), 1u);
  EXPECT_EQ(out.vals, std::vector<double>(9, 0.0));
}

TEST(PairBlocks, SameBitsOnOneThreadAndOnSeveral) {
  const int n = 20000;
  const RandomPairs act = random_pairs(30000, n, 3), fr = random_pairs(9000, n / 2, 4);
  std::vector<int> fixed(n, 0);
  for (int i = 0; i < n; i += 11) fixed[i] = 1;
  const std::vector<PairHessians> lists{act.view(), fr.view()};
  const int saved = omp_threads();
  CouplingMatrix one, many;
  set_omp_threads(1);
  merge_pair_blocks(n, fixed.data(), lists, &one);
  set_omp_threads(4);  // more threads than cores is fine: the split, not the speed, is tested
  merge_pair_blocks(n, fixed.data(), lists, &many);
  set_omp_threads(saved);
  EXPECT_EQ(one.row_ptr, many.row_ptr);
  EXPECT_EQ(one.cols, many.cols);
  EXPECT_EQ(one.vals, many.vals);
}

}  // namespace
}  // namespace gd::sim
