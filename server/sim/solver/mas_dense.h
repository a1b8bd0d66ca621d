#pragma once
/// \file
/// The per-domain dense algebra and level views of the multilevel additive Schwarz preconditioner
/// (mas_preconditioner.h), as GD_HD functions over teams (sim/team.h): Morton codes, the
/// Cholesky factorisation, its single-precision packing and solves, a level's view and the
/// cross entries a level reads.

#include <cmath>
#include <cstdint>

#include "sim/hd.h"
#include "sim/solver/preconditioner.h"
#include "sim/team.h"

namespace gd::sim {

namespace mas_detail {

/// Spreads the low 10 bits of v so that bit k lands at bit 3k (Morton interleave).
GD_HD uint64_t spread_bits(uint64_t v) {
  v &= 0x3ff;
  v = (v | (v << 16)) & 0x30000ff;
  v = (v | (v << 8)) & 0x300f00f;
  v = (v | (v << 4)) & 0x30c30c3;
  v = (v | (v << 2)) & 0x9249249;
  return v;
}

/// 30-bit Morton code of a point inside the cube [lo, lo + size]^3.
GD_HD uint64_t morton_code(const double* p, const double* lo, double inv_size) {
  uint64_t c[3];
  for (int k = 0; k < 3; ++k) {
    double u = (p[k] - lo[k]) * inv_size * 1023.0;
    u = u < 0 ? 0 : (u > 1023.0 ? 1023.0 : u);
    c[k] = static_cast<uint64_t>(u);
  }
  return spread_bits(c[0]) | (spread_bits(c[1]) << 1) | (spread_bits(c[2]) << 2);
}

/// In-place Cholesky factorisation of the symmetric m x m row-major matrix A (lower triangle
/// read and overwritten with L, A = L Lᵀ) by a team (sim/team.h): column by column, the rows
/// below the diagonal split over its lanes. A pivot that is not positive (rounding in a nearly
/// singular aggregate) is replaced by its row's diagonal entry or 1, so the factor stays usable as
/// a preconditioner. Returns the number of pivots so replaced.
template <class Team>
GD_HD int cholesky_in_place(const Team& team, double* A, int m) {
  int fixed = 0;
  for (int j = 0; j < m; ++j) {
    double* rj = A + static_cast<size_t>(j) * m;
    double s = rj[j] - team.dot(rj, rj, j);
    if (!(s > 1e-12 * fabs(rj[j]))) {
      s = fabs(rj[j]) > 0 ? fabs(rj[j]) : 1.0;
      ++fixed;
    }
    const double d = sqrt(s);
    const double inv = 1.0 / d;
    team.range(j + 1, m, [&](int i) {
      double* ri = A + static_cast<size_t>(i) * m;
      ri[j] = (ri[j] - dot4(ri, rj, j)) * inv;
    });
    team.single([&] { rj[j] = d; });  // after the range: its lanes read rj[j] above
  }
  return fixed;
}

/// Packs the lower triangle of a row-major m x m factor into single precision, row by row (row i
/// at i (i + 1) / 2), with the reciprocals of the diagonal in place of the diagonal (the solves
/// then multiply instead of dividing). L Lᵀ of the rounded factor is still symmetric positive
/// definite, and the apply reads a quarter of the bytes of the double factor. Entry q of the
/// packed triangle goes to P[stride * q]: a stride W interleaves W domains' factors (the CPU's
/// layout, read by cholesky_solve_packed_lanes; P then points at the domain's lane).
template <class Team>
GD_HD void pack_lower(const Team& team, const double* L, int m, float* P, int stride = 1) {
  team.range(0, m, [&](int i) {
    float* row = P + static_cast<size_t>(stride) * (i * (i + 1) / 2);
    for (int k = 0; k < i; ++k) row[stride * k] = static_cast<float>(L[static_cast<size_t>(i) * m + k]);
    row[stride * i] = static_cast<float>(1.0 / L[static_cast<size_t>(i) * m + i]);
  });
}

/// Solves L Lᵀ y = b in place (b overwritten by y) with a factor packed by pack_lower, by a team:
/// the forward pass takes one team dot product per row; the backward pass scatters row i of L
/// once y_i is known (independent updates, split over the lanes). (Single precision here too was
/// tried: PCG no faster at 20k vertices, and P⁻¹ no longer exactly symmetric.)
template <class Team>
GD_HD void cholesky_solve_packed(const Team& team, const float* __restrict__ P, int m, double* __restrict__ b) {
  for (int i = 0; i < m; ++i) {  // L u = b
    const float* __restrict__ ri = P + i * (i + 1) / 2;
    const double t = team.dot(ri, b, i);
    team.single([&] { b[i] = (b[i] - t) * ri[i]; });
  }
  for (int i = m - 1; i >= 0; --i) {  // Lᵀ y = u
    const float* __restrict__ ri = P + i * (i + 1) / 2;
    const double yi = b[i] * ri[i];
    team.range(0, i, [&](int k) { b[k] -= ri[k] * yi; });
    team.single([&] { b[i] = yi; });  // after the range: its lanes read b[i] above
  }
}

/// cholesky_solve_packed for W domains at once, their factors interleaved by pack_lower with
/// stride W and their right-hand sides too (b[W i + w]: entry i of domain w), in place. Each
/// domain gets a team of one's arithmetic, dot4's order of additions included, so the results
/// are those of W separate solves bit for bit; the W domains' independent sums are what a SIMD
/// unit takes side by side (the CPU backend: backend/cpu/mas_solve_cpu.h). A domain past the
/// level's last takes an identity factor and a zero right-hand side.
template <int W>
GD_HD void cholesky_solve_packed_lanes(const float* __restrict__ P, int m, double* __restrict__ b) {
  for (int i = 0; i < m; ++i) {  // L u = b
    const float* __restrict__ ri = P + static_cast<size_t>(W) * (i * (i + 1) / 2);
    double t[4][W];
    for (int j = 0; j < 4; ++j)
      for (int w = 0; w < W; ++w) t[j][w] = 0;
    int k = 0;
    for (; k + 4 <= i; k += 4)
      for (int j = 0; j < 4; ++j)
        for (int w = 0; w < W; ++w) t[j][w] += ri[W * (k + j) + w] * b[W * (k + j) + w];
    for (; k < i; ++k)
      for (int w = 0; w < W; ++w) t[0][w] += ri[W * k + w] * b[W * k + w];
    for (int w = 0; w < W; ++w) b[W * i + w] = (b[W * i + w] - ((t[0][w] + t[1][w]) + (t[2][w] + t[3][w]))) * ri[W * i + w];
  }
  for (int i = m - 1; i >= 0; --i) {  // Lᵀ y = u
    const float* __restrict__ ri = P + static_cast<size_t>(W) * (i * (i + 1) / 2);
    double y[W];
    for (int w = 0; w < W; ++w) y[w] = b[W * i + w] * ri[W * i + w];
    for (int k = 0; k < i; ++k)
      for (int w = 0; w < W; ++w) b[W * k + w] -= ri[W * k + w] * y[w];
    for (int w = 0; w < W; ++w) b[W * i + w] = y[w];
  }
}

/// One level of the hierarchy, as raw pointers for kernels.
struct LevelView {
  int nodes = 0, domains = 0;
  const int* node_of;  ///< per vertex: its node at this level (-1 for Dirichlet vertices)
  const int* offsets;  ///< nodes + 1: node k's vertices are members[offsets[k] .. offsets[k+1])
  const int* members;  ///< the free vertices, node by node
};

/// Node a's three entries of domain d's right-hand side at b[stride * (3a + c)]: level 0's
/// residual r at the node's vertex, a coarse level's restricted residual, zero past the level's
/// last node.
GD_HD void gather_rhs(const LevelView& L, int B, const double* restricted, const double* r, int d, int a, double* b,
                      int stride) {
  const int first = d * B;
  const int count = L.nodes - first < B ? L.nodes - first : B;
  const double* y = a >= count ? nullptr : restricted ? restricted + 3 * (first + a) : r + 3 * L.members[first + a];
  for (int c = 0; c < 3; ++c) b[stride * (3 * a + c)] = y ? y[c] : 0.0;
}

/// The range [*lo, *hi) of members gathered by part j of the `parts` parts of domain d.
GD_HD void part_range(const LevelView& L, int B, int d, int j, int parts, int* lo, int* hi) {
  const int first = d * B;
  const int count = L.nodes - first < B ? L.nodes - first : B;
  const int a = L.offsets[first];
  const long long verts = L.offsets[first + count] - a;
  *lo = a + static_cast<int>(verts * j / parts);
  *hi = a + static_cast<int>(verts * (j + 1) / parts);
}

/// Where vertex v's cross entries start (see the file comment): v's slots are as many as its
/// row's entries, the mesh pattern's and the couplings'.
GD_HD int cross_offset(const BlockMatrixView& M, int v) { return M.row_ptr[v] + (M.cpl_row_ptr ? M.cpl_row_ptr[v] : 0); }

/// Calls f(column, block) for the entries of vertex v's row that level l reads: the whole row
/// (mesh pattern and couplings) at level 0, above it the cross entries left by level l-1 (k >= 0:
/// the mesh pattern's block k; k < 0: coupling -k-1).
template <class F>
GD_HD void for_entries(const BlockMatrixView& M, const int* xref, const int* xcount, int l, int v, F&& f) {
  if (l == 0) {
    for (int k = M.row_ptr[v]; k < M.row_ptr[v + 1]; ++k) f(M.cols[k], M.vals + 9 * k);
    if (M.cpl_row_ptr)
      for (int k = M.cpl_row_ptr[v]; k < M.cpl_row_ptr[v + 1]; ++k) f(M.cpl_cols[k], M.cpl_vals + 9 * k);
    return;
  }
  const int* e = xref + cross_offset(M, v);
  for (int i = 0; i < xcount[v]; ++i) {
    const int k = e[i];
    if (k >= 0)
      f(M.cols[k], M.vals + 9 * k);
    else
      f(M.cpl_cols[-k - 1], M.cpl_vals + 9 * (-k - 1));
  }
}

inline constexpr int kMaxLevels = 8;
inline constexpr int kMaxDomainNodes = 64;  ///< most nodes a domain may hold (B)

/// Most fine vertices gathered by one part of a domain (see the file comment): a level-0 or
/// level-1 domain (B nodes of one vertex, or of about B) is one part, a coarse domain many.
inline constexpr int kPartVertices = 256;

/// Every level's view and solution, passed by value into the prolongation kernel.
struct LevelPack {
  LevelView L[kMaxLevels];
  const double* sol[kMaxLevels];
};

}  // namespace mas_detail

}  // namespace gd::sim
