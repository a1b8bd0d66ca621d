#pragma once
/// \file
/// One row of the block matrix-vector product y = A x, for 3x3-block CSR matrices whose blocks are
/// stored row-major (9 values each). The row is summed in nine lanes, a[m] += b[m] x_c[m % 3] for
/// each block b of the row and its column c, and the lanes are summed per row at the end: the
/// products of one block are independent adds, so no add waits for the one before it within a
/// block, and SIMD units take the nine lanes as vectors. Every backend sums in this order: the
/// CPU's AVX2 path (backend/cpu/block_row_cpu.h) gives the portable loop's bits, and CUDA's differs
/// only where nvcc fuses a multiply and an add.

#include "sim/hd.h"

namespace gd::sim {

/// A block CSR's arrays (row_ptr null: a matrix with no entries).
struct BlockRows {
  const int* row_ptr = nullptr;
  const int* cols = nullptr;
  const double* vals = nullptr;
};

/// Adds blocks [begin, end) of a block row times x into the lanes a[0..8].
GD_HD_ALWAYS_INLINE void add_block_row_lanes(const int* cols, const double* vals, int begin, int end,
                                             const double* x, double* a) {
  for (int k = begin; k < end; ++k) {
    const double* b = vals + 9 * k;
    const double* xc = x + 3 * cols[k];
    for (int m = 0; m < 9; ++m) a[m] += b[m] * xc[m % 3];
  }
}

/// Row i of (A + C) x into y[0..2]: A's blocks, then C's, in lanes; y[r] = a[3r] + a[3r + 1] + a[3r + 2].
GD_HD_ALWAYS_INLINE void block_row_product(int i, const BlockRows& A, const BlockRows& C, const double* x, double* y) {
  double a[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
  add_block_row_lanes(A.cols, A.vals, A.row_ptr[i], A.row_ptr[i + 1], x, a);
  if (C.row_ptr) add_block_row_lanes(C.cols, C.vals, C.row_ptr[i], C.row_ptr[i + 1], x, a);
  y[0] = a[0] + a[1] + a[2];
  y[1] = a[3] + a[4] + a[5];
  y[2] = a[6] + a[7] + a[8];
}

}  // namespace gd::sim
