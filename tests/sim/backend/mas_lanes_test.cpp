// The CPU backend's MAS domain factorisations and solves, four domains side by side
// (backend/cpu/mas_solve_cpu.h; AVX2 where the processor has it) give, lane by lane, the bits of
// one domain factored and solved by a team of one (sim/solver/mas_dense.h), the arithmetic the
// GPU's warps share; a missing domain packs the identity; and the solve solves the system.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <vector>

#include "sim/backend/cpu/mas_solve_cpu.h"
#include "sim/solver/preconditioner.h"  // with mas_preconditioner.h, mas_dense.h (their include order)
#include "sim/team.h"

namespace gd::sim {
namespace {

constexpr int W = kMasCpuLanes;

/// A symmetric positive definite m x m row-major matrix M Mᵀ + m I, entries of mixed magnitude;
/// `singular` makes its last rows zero (the pivot replacement's case).
std::vector<double> random_spd(int m, bool singular, std::mt19937& rng) {
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  std::vector<double> M(static_cast<size_t>(m) * m), A(M.size());
  for (double& v : M) v = value(rng) * std::pow(10.0, static_cast<int>(rng() % 3) - 1);
  for (int i = 0; i < m; ++i)
    for (int j = 0; j < m; ++j) {
      double s = i == j ? m : 0.0;
      for (int k = 0; k < m; ++k) s += M[i * m + k] * M[j * m + k];
      A[i * m + j] = s;
    }
  if (singular)
    for (int i = m - 2; i < m; ++i)
      for (int j = 0; j < m; ++j) A[i * m + j] = A[j * m + i] = 0.0;
  return A;
}

TEST(MasLanes, EachLaneIsATeamOfOnesFactorAndSolveBitForBit) {
#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
  EXPECT_EQ(mas_lanes_use_avx2(), __builtin_cpu_supports("avx2") != 0);  // the AVX2 paths compared where they run
#endif
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> value(-1.0, 1.0);
  for (const int m : {3, 6, 7, 48, 96, 192}) {
    for (const int present : {W, W - 1, 1}) {  // a level's last group may hold fewer domains
      const size_t tri = static_cast<size_t>(m) * (m + 1) / 2;
      std::vector<std::vector<double>> blocks(W), spd(W);
      std::vector<double> b(static_cast<size_t>(W) * m);
      for (int w = 0; w < W; ++w) {
        spd[w] = blocks[w] = random_spd(m, w == 1 && m > 3, rng);
        for (int i = 0; i < m; ++i) b[W * i + w] = w < present ? value(rng) : 0.0;
      }
      std::vector<double*> ptrs(W, nullptr);
      for (int w = 0; w < present; ++w) ptrs[w] = blocks[w].data();
      std::vector<float> lanes(W * tri);
      mas_factor_lanes_cpu(ptrs.data(), m, lanes.data());
      std::vector<double> x = b;
      mas_solve_lanes_cpu(lanes.data(), m, x.data());
      std::vector<double> portable_x = b;
      mas_detail::cholesky_solve_packed_lanes<W>(lanes.data(), m, portable_x.data());
      ASSERT_EQ(0, std::memcmp(x.data(), portable_x.data(), x.size() * sizeof(double))) << "m " << m;
      for (int w = 0; w < W; ++w) {
        std::vector<float> one(tri);
        std::vector<double> xw(m);
        for (int i = 0; i < m; ++i) xw[i] = b[W * i + w];
        if (w < present) {
          std::vector<double> a = spd[w];
          mas_detail::cholesky_in_place(SerialTeam{}, a.data(), m);
          mas_detail::pack_lower(SerialTeam{}, a.data(), m, one.data());
        } else {
          for (int i = 0; i < m; ++i)
            for (int k = 0; k <= i; ++k) one[i * (i + 1) / 2 + k] = k == i ? 1.0f : 0.0f;
        }
        for (size_t q = 0; q < tri; ++q)
          ASSERT_EQ(0, std::memcmp(&one[q], &lanes[W * q + w], sizeof(float))) << "m " << m << " lane " << w << " entry " << q;
        mas_detail::cholesky_solve_packed(SerialTeam{}, one.data(), m, xw.data());
        for (int i = 0; i < m; ++i)
          ASSERT_EQ(0, std::memcmp(&xw[i], &x[W * i + w], sizeof(double))) << "m " << m << " lane " << w << " row " << i;
        if (w >= present || (w == 1 && m > 3)) continue;  // the identity; the replaced pivots
        // A x = b to the single-precision factor's accuracy.
        double err = 0, scale = 0;
        for (int i = 0; i < m; ++i) {
          double r = -b[W * i + w];
          for (int k = 0; k < m; ++k) r += spd[w][i * m + k] * x[W * k + w];
          err = std::max(err, std::fabs(r));
          scale = std::max(scale, std::fabs(b[W * i + w]));
        }
        EXPECT_LT(err, 1e-4 * scale) << "m " << m << " lane " << w;
      }
    }
  }
}

}  // namespace
}  // namespace gd::sim
