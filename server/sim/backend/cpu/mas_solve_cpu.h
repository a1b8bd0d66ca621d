#pragma once
/// \file
/// The CPU backend's MAS domain factorisations and solves (sim/solver/mas_dense.h's
/// cholesky_in_place, pack_lower and cholesky_solve_packed_lanes), four domains side by side, their
/// packed factors interleaved: with AVX2 where the processor has it (checked once at run time),
/// else the portable loops. Both do the same multiplications and additions in the same order (no
/// fused multiply-add), so the results are bit-identical; the AVX2 paths take the four domains'
/// sums as one vector, four independent vectors per row, where a domain alone waits on each add.

namespace gd::sim {

/// Domains a call of mas_solve_lanes_cpu solves together (the CPU's interleave of the factors).
inline constexpr int kMasCpuLanes = 4;

/// Factors the m x m row-major blocks A[0..3] (lower triangles read; scratch, may be overwritten)
/// and packs the factors interleaved into P (kMasCpuLanes * m (m + 1) / 2 floats): lane w as
/// cholesky_in_place then pack_lower(..., P + w, kMasCpuLanes) would. A null A[w] (past a level's
/// last domain) packs an identity factor.
void mas_factor_lanes_cpu(double* const* A, int m, float* P);

/// cholesky_solve_packed_lanes<kMasCpuLanes>(P, m, b).
void mas_solve_lanes_cpu(const float* P, int m, double* b);

/// Whether mas_factor_lanes_cpu and mas_solve_lanes_cpu run the AVX2 paths on this processor.
bool mas_lanes_use_avx2();

}  // namespace gd::sim
