#include "sim/backend/cpu/block_row_cpu.h"

#if defined(__x86_64__) && (defined(__GNUC__) || defined(__clang__))
#include <immintrin.h>
#define GD_BLOCK_ROW_AVX2 1
#endif

namespace gd::sim {
namespace {

void portable_block_row(int i, const BlockRows& A, const BlockRows& C, const double* x, double* y) {
  block_row_product(i, A, C, x, y);
}

#ifdef GD_BLOCK_ROW_AVX2
/// Adds row i of M into lanes 0-3 (lo), 4-7 (hi) and 8 (last). A block's x is read with a masked
/// load (three values: the last vertex's must not read past the vector) and spread into
/// (x0, x1, x2, x0) and (x1, x2, x0, x1), the columns of lanes 0-3 and 4-7. No fused multiply-add
/// (the target is avx2 alone), so each lane rounds as the portable loop's does.
__attribute__((target("avx2"), always_inline)) inline void avx2_add_row(int i, const BlockRows& M, const double* x,
                                                                        __m256d& lo, __m256d& hi, __m128d& last) {
  const __m256i three = _mm256_set_epi64x(0, -1, -1, -1);
  for (int k = M.row_ptr[i], end = M.row_ptr[i + 1]; k < end; ++k) {
    const double* b = M.vals + 9 * k;
    const double* xc = x + 3 * M.cols[k];
    const __m256d xv = _mm256_maskload_pd(xc, three);
    lo = _mm256_add_pd(lo, _mm256_mul_pd(_mm256_loadu_pd(b), _mm256_permute4x64_pd(xv, 0x24)));
    hi = _mm256_add_pd(hi, _mm256_mul_pd(_mm256_loadu_pd(b + 4), _mm256_permute4x64_pd(xv, 0x49)));
    last = _mm_add_sd(last, _mm_mul_sd(_mm_load_sd(b + 8), _mm_load_sd(xc + 2)));
  }
}

__attribute__((target("avx2"))) void avx2_block_row(int i, const BlockRows& A, const BlockRows& C, const double* x,
                                                    double* y) {
  __m256d lo = _mm256_setzero_pd(), hi = _mm256_setzero_pd();
  __m128d last = _mm_setzero_pd();
  avx2_add_row(i, A, x, lo, hi, last);
  if (C.row_ptr) avx2_add_row(i, C, x, lo, hi, last);
  alignas(32) double a[8];
  _mm256_store_pd(a, lo);
  _mm256_store_pd(a + 4, hi);
  y[0] = a[0] + a[1] + a[2];
  y[1] = a[3] + a[4] + a[5];
  y[2] = a[6] + a[7] + _mm_cvtsd_f64(last);
}
#endif

using BlockRowFn = void (*)(int, const BlockRows&, const BlockRows&, const double*, double*);

/// The path for this processor, chosen at the first call.
BlockRowFn block_row_path() {
  static const BlockRowFn path = [] {
#ifdef GD_BLOCK_ROW_AVX2
    if (__builtin_cpu_supports("avx2")) return static_cast<BlockRowFn>(avx2_block_row);
#endif
    return static_cast<BlockRowFn>(portable_block_row);
  }();
  return path;
}

}  // namespace

void block_row_product_cpu(int i, const BlockRows& A, const BlockRows& C, const double* x, double* y) {
  block_row_path()(i, A, C, x, y);
}

bool block_row_uses_avx2() { return block_row_path() != portable_block_row; }

}  // namespace gd::sim
