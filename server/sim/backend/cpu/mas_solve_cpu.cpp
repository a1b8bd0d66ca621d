#include "sim/backend/cpu/mas_solve_cpu.h"

#include <cmath>
#include <cstddef>
#include <vector>

#include "sim/solver/preconditioner.h"  // with mas_preconditioner.h, mas_dense.h (their include order)
#include "sim/team.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define GD_MAS_SOLVE_AVX2 1
#endif

namespace gd::sim {
namespace {

constexpr int W = kMasCpuLanes;

/// The packed identity factor in lane w of P.
void pack_identity(int m, float* P, int w) {
  for (int i = 0; i < m; ++i)
    for (int k = 0; k <= i; ++k) P[static_cast<size_t>(W) * (i * (i + 1) / 2 + k) + w] = k == i ? 1.0f : 0.0f;
}

void portable_factor(double* const* A, int m, float* P) {
  for (int w = 0; w < W; ++w) {
    if (!A[w]) {
      pack_identity(m, P, w);
      continue;
    }
    mas_detail::cholesky_in_place(SerialTeam{}, A[w], m);
    mas_detail::pack_lower(SerialTeam{}, A[w], m, P + w, W);
  }
}

void portable_solve(const float* P, int m, double* b) { mas_detail::cholesky_solve_packed_lanes<W>(P, m, b); }

#ifdef GD_MAS_SOLVE_AVX2
/// Four single-precision factor entries (one per domain) widened to double.
__attribute__((target("avx2"), always_inline)) inline __m256d load4(const float* p) {
  return _mm256_cvtps_pd(_mm_loadu_ps(p));
}

/// Four double entries (one per domain).
__attribute__((target("avx2"), always_inline)) inline __m256d load4(const double* p) { return _mm256_loadu_pd(p); }

/// dot4(a, b, n) of four interleaved pairs of rows (lane w: a[W k + w], b[W k + w]; a in single or
/// double precision): its four partial sums in four vectors, added as dot4 adds them.
template <class A>
__attribute__((target("avx2"), always_inline)) inline __m256d dot4_lanes(const A* a, const double* b, int n) {
  __m256d t0 = _mm256_setzero_pd(), t1 = t0, t2 = t0, t3 = t0;
  int k = 0;
  for (; k + 4 <= n; k += 4) {
    t0 = _mm256_add_pd(t0, _mm256_mul_pd(load4(a + W * k), _mm256_loadu_pd(b + W * k)));
    t1 = _mm256_add_pd(t1, _mm256_mul_pd(load4(a + W * (k + 1)), _mm256_loadu_pd(b + W * (k + 1))));
    t2 = _mm256_add_pd(t2, _mm256_mul_pd(load4(a + W * (k + 2)), _mm256_loadu_pd(b + W * (k + 2))));
    t3 = _mm256_add_pd(t3, _mm256_mul_pd(load4(a + W * (k + 3)), _mm256_loadu_pd(b + W * (k + 3))));
  }
  for (; k < n; ++k) t0 = _mm256_add_pd(t0, _mm256_mul_pd(load4(a + W * k), _mm256_loadu_pd(b + W * k)));
  return _mm256_add_pd(_mm256_add_pd(t0, t1), _mm256_add_pd(t2, t3));
}

/// cholesky_in_place's arithmetic on four blocks copied side by side (lane w: block w), then
/// pack_lower's: the pivot test and its replacement by lane, sqrt and the division correctly
/// rounded as the scalar ones.
__attribute__((target("avx2"))) void avx2_factor(double* const* A, int m, float* P) {
  thread_local std::vector<double> scratch;
  scratch.resize(static_cast<size_t>(W) * m * m);
  double* F = scratch.data();  // F[W (i m + k) + w] = A[w][i m + k], lower triangle
  for (int i = 0; i < m; ++i)
    for (int k = 0; k <= i; ++k)
      for (int w = 0; w < W; ++w) F[W * (static_cast<size_t>(i) * m + k) + w] = A[w] ? A[w][static_cast<size_t>(i) * m + k] : 0.0;
  const __m256d sign = _mm256_set1_pd(-0.0), tiny = _mm256_set1_pd(1e-12), one = _mm256_set1_pd(1.0);
  const __m256d zero = _mm256_setzero_pd();
  for (int j = 0; j < m; ++j) {
    double* rj = F + W * static_cast<size_t>(j) * m;
    const __m256d ajj = _mm256_loadu_pd(rj + W * j);
    const __m256d abs_ajj = _mm256_andnot_pd(sign, ajj);
    __m256d s = _mm256_sub_pd(ajj, dot4_lanes(rj, rj, j));
    const __m256d pivot_ok = _mm256_cmp_pd(s, _mm256_mul_pd(tiny, abs_ajj), _CMP_GT_OQ);
    const __m256d fallback = _mm256_blendv_pd(one, abs_ajj, _mm256_cmp_pd(abs_ajj, zero, _CMP_GT_OQ));
    s = _mm256_blendv_pd(fallback, s, pivot_ok);
    const __m256d d = _mm256_sqrt_pd(s);
    const __m256d inv = _mm256_div_pd(one, d);
    for (int i = j + 1; i < m; ++i) {
      double* ri = F + W * static_cast<size_t>(i) * m;
      _mm256_storeu_pd(ri + W * j, _mm256_mul_pd(_mm256_sub_pd(_mm256_loadu_pd(ri + W * j), dot4_lanes(ri, rj, j)), inv));
    }
    _mm256_storeu_pd(rj + W * j, d);
  }
  for (int i = 0; i < m; ++i) {  // pack_lower: single precision, the diagonal's reciprocal
    const double* ri = F + W * static_cast<size_t>(i) * m;
    float* row = P + static_cast<size_t>(W) * (i * (i + 1) / 2);
    for (int k = 0; k < i; ++k) _mm_storeu_ps(row + W * k, _mm256_cvtpd_ps(_mm256_loadu_pd(ri + W * k)));
    _mm_storeu_ps(row + W * i, _mm256_cvtpd_ps(_mm256_div_pd(one, _mm256_loadu_pd(ri + W * i))));
  }
  for (int w = 0; w < W; ++w)
    if (!A[w]) pack_identity(m, P, w);
}

/// The portable loop's arithmetic with lane w of each vector holding domain w: the forward
/// pass's four partial sums t0..t3 (dot4's), then the backward pass's updates. No fused
/// multiply-add (the target is avx2 alone), so each lane rounds as the portable loop's does.
__attribute__((target("avx2"))) void avx2_solve(const float* P, int m, double* b) {
  for (int i = 0; i < m; ++i) {  // L u = b
    const float* ri = P + static_cast<size_t>(W) * (i * (i + 1) / 2);
    const __m256d t = dot4_lanes(ri, b, i);
    _mm256_storeu_pd(b + W * i, _mm256_mul_pd(_mm256_sub_pd(_mm256_loadu_pd(b + W * i), t), load4(ri + W * i)));
  }
  // Lᵀ y = u, four rows at a time: each entry below them is read and written once for the four
  // (b[k] -= r_i[k] y_i for i, i-1, i-2, i-3 in turn, the single-row loop's order).
  int i = m - 1;
  for (; i >= 3; i -= 4) {
    const float* r0 = P + static_cast<size_t>(W) * (i * (i + 1) / 2);
    const float* r1 = P + static_cast<size_t>(W) * ((i - 1) * i / 2);
    const float* r2 = P + static_cast<size_t>(W) * ((i - 2) * (i - 1) / 2);
    const float* r3 = P + static_cast<size_t>(W) * ((i - 3) * (i - 2) / 2);
    const __m256d y0 = _mm256_mul_pd(_mm256_loadu_pd(b + W * i), load4(r0 + W * i));
    __m256d b1 = _mm256_sub_pd(_mm256_loadu_pd(b + W * (i - 1)), _mm256_mul_pd(load4(r0 + W * (i - 1)), y0));
    const __m256d y1 = _mm256_mul_pd(b1, load4(r1 + W * (i - 1)));
    __m256d b2 = _mm256_sub_pd(_mm256_loadu_pd(b + W * (i - 2)), _mm256_mul_pd(load4(r0 + W * (i - 2)), y0));
    b2 = _mm256_sub_pd(b2, _mm256_mul_pd(load4(r1 + W * (i - 2)), y1));
    const __m256d y2 = _mm256_mul_pd(b2, load4(r2 + W * (i - 2)));
    __m256d b3 = _mm256_sub_pd(_mm256_loadu_pd(b + W * (i - 3)), _mm256_mul_pd(load4(r0 + W * (i - 3)), y0));
    b3 = _mm256_sub_pd(b3, _mm256_mul_pd(load4(r1 + W * (i - 3)), y1));
    b3 = _mm256_sub_pd(b3, _mm256_mul_pd(load4(r2 + W * (i - 3)), y2));
    const __m256d y3 = _mm256_mul_pd(b3, load4(r3 + W * (i - 3)));
    for (int k = 0; k < i - 3; ++k) {
      __m256d v = _mm256_sub_pd(_mm256_loadu_pd(b + W * k), _mm256_mul_pd(load4(r0 + W * k), y0));
      v = _mm256_sub_pd(v, _mm256_mul_pd(load4(r1 + W * k), y1));
      v = _mm256_sub_pd(v, _mm256_mul_pd(load4(r2 + W * k), y2));
      _mm256_storeu_pd(b + W * k, _mm256_sub_pd(v, _mm256_mul_pd(load4(r3 + W * k), y3)));
    }
    _mm256_storeu_pd(b + W * i, y0);
    _mm256_storeu_pd(b + W * (i - 1), y1);
    _mm256_storeu_pd(b + W * (i - 2), y2);
    _mm256_storeu_pd(b + W * (i - 3), y3);
  }
  for (; i >= 0; --i) {  // the first rows, one at a time
    const float* ri = P + static_cast<size_t>(W) * (i * (i + 1) / 2);
    const __m256d y = _mm256_mul_pd(_mm256_loadu_pd(b + W * i), load4(ri + W * i));
    for (int k = 0; k < i; ++k)
      _mm256_storeu_pd(b + W * k, _mm256_sub_pd(_mm256_loadu_pd(b + W * k), _mm256_mul_pd(load4(ri + W * k), y)));
    _mm256_storeu_pd(b + W * i, y);
  }
}
#endif

struct Paths {
  void (*factor)(double* const*, int, float*);
  void (*solve)(const float*, int, double*);
};

/// The paths for this processor, chosen at the first call.
const Paths& paths() {
  static const Paths chosen = [] {
#ifdef GD_MAS_SOLVE_AVX2
    if (__builtin_cpu_supports("avx2")) return Paths{avx2_factor, avx2_solve};
#endif
    return Paths{portable_factor, portable_solve};
  }();
  return chosen;
}

}  // namespace

void mas_factor_lanes_cpu(double* const* A, int m, float* P) { paths().factor(A, m, P); }

void mas_solve_lanes_cpu(const float* P, int m, double* b) { paths().solve(P, m, b); }

bool mas_lanes_use_avx2() { return paths().solve != portable_solve; }

}  // namespace gd::sim
