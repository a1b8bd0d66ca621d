#pragma once
/// \file
/// The CPU backend's block-row product (sim/block_row.h's block_row_product): with AVX2 where the
/// processor has it (checked once at run time), else the portable loop. Both do the same
/// multiplications and additions in the same order (no fused multiply-add), so the results are
/// bit-identical; the AVX2 path takes a block in three vector multiplies and adds instead of nine
/// scalar ones (the block product is a quarter of a self-contact step's time).

#include "sim/block_row.h"

namespace gd::sim {

/// Row i of (A + C) x into y[0..2], as block_row_product.
void block_row_product_cpu(int i, const BlockRows& A, const BlockRows& C, const double* x, double* y);

/// Whether block_row_product_cpu runs the AVX2 path on this processor.
bool block_row_uses_avx2();

}  // namespace gd::sim
