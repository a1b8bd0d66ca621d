#pragma once
/// \file
/// The contact couplings' block CSR built on the backend, the GPU's path (CpuGpuPathsExec runs it
/// on the CPU; CpuExec keeps the host merge of pair_blocks.cpp, which reads the pairs' Hessians in
/// place). Without it, every Newton iteration on CUDA copied all pairs' off-diagonal blocks to
/// the host (54 values a pair: ~190 MB at fold/40000) and the CSR back.
///
/// Every off-diagonal block (a, b), a != b, of every pair between free vertices becomes one key:
/// row, column and the block's slot (pair index over both lists, then its place among the pair's
/// 12 ordered blocks). Sorted, the keys of one (row, column) are a run in slot order; each run is
/// one block of the CSR, summed in that order: the same bits on every run and thread count. Member
/// functions of Solver<Exec> (solver_impl.h).

#include <cstdint>

#include "sim/solver/solver_impl.h"

namespace gd::sim {

namespace merge_detail {

/// Key layout: row in bits 44-63, column in 24-43, slot in 0-23.
inline constexpr int kColumnShift = 24, kRowShift = 44;
inline constexpr uint64_t kSlotMask = (uint64_t(1) << kColumnShift) - 1, kVertexMask = (uint64_t(1) << 20) - 1;
inline constexpr uint64_t kNoKey = ~uint64_t(0);  ///< a block touching a Dirichlet vertex: sorts last

/// The ordered vertex pair (a, b), a != b, of block k in [0, 12) of a pair.
GD_HD void slot_vertices(int k, int* a, int* b) {
  *a = k / 3;
  const int c = k % 3;
  *b = c + (c >= *a ? 1 : 0);
}

}  // namespace merge_detail

/// Whether merge_pair_blocks_on_backend's keys hold this scene's pairs (vertex ids in 20 bits,
/// block slots in 24: a million vertices, 1.4 million pairs).
template <class Exec>
bool Solver<Exec>::backend_merge_fits() const {
  const long slots = 12L * (static_cast<long>(act_.n) + n_fr_);
  return n_ <= static_cast<int>(merge_detail::kVertexMask) + 1 && slots <= static_cast<long>(merge_detail::kSlotMask);
}

template <class Exec>
void Solver<Exec>::merge_pair_blocks_on_backend() {
  using namespace merge_detail;
  const int n0 = act_.n, n = n_;
  const int slots = 12 * (act_.n + n_fr_);
  Exec::resize_for_overwrite(mkeys_, static_cast<size_t>(slots > 0 ? slots : 1));
  const int* v0 = Exec::ptr(act_.v);
  const int* v1 = Exec::ptr(fr_v_);
  const double* H0 = Exec::ptr(act_H_);
  const double* H1 = Exec::ptr(fr_H_);
  const int* fixed = Exec::ptr(fixed_);
  uint64_t* keys = Exec::ptr(mkeys_);
  // 1. One key per block, sorted: runs of equal (row, column) in slot order.
  Exec::for_each(slots, [=] GD_HD_LAMBDA(int s) {
    const int p = s / 12;
    const int* vs = p < n0 ? v0 + 4 * p : v1 + 4 * (p - n0);
    int a, b;
    slot_vertices(s % 12, &a, &b);
    const int va = vs[a], vb = vs[b];
    keys[s] = fixed[va] || fixed[vb]
                  ? kNoKey
                  : uint64_t(va) << kRowShift | uint64_t(vb) << kColumnShift | static_cast<uint64_t>(s);
  });
  if (slots == 0) Exec::fill(mkeys_, kNoKey);
  Exec::sort(mkeys_);
  const int valid = static_cast<int>(Exec::sum(slots, [=] GD_HD_LAMBDA(int k) { return keys[k] != kNoKey ? 1.0 : 0.0; }));
  // 2. Blocks: the runs' heads counted (after the exclusive scan, key k lies in block
  //    run[k + 1] - 1, and heads are where run steps).
  Exec::resize_for_overwrite(mrun_, static_cast<size_t>(valid) + 1);
  int* run = Exec::ptr(mrun_);
  Exec::for_each(valid + 1, [=] GD_HD_LAMBDA(int k) {
    run[k] = k < valid && (k == 0 || keys[k] >> kColumnShift != keys[k - 1] >> kColumnShift) ? 1 : 0;
  });
  Exec::exclusive_scan(mrun_, valid + 1);
  const int blocks = valid > 0 ? Exec::read(mrun_, valid) : 0;
  Exec::resize_for_overwrite(cpl_cols_, static_cast<size_t>(blocks > 0 ? blocks : 1));
  Exec::resize_for_overwrite(cpl_vals_, 9 * static_cast<size_t>(blocks > 0 ? blocks : 1));
  Exec::resize_for_overwrite(cpl_row_ptr_, static_cast<size_t>(n) + 1);
  Exec::resize_for_overwrite(mblock_start_, static_cast<size_t>(blocks) + 1);
  Exec::resize_for_overwrite(mblock_row_, static_cast<size_t>(blocks > 0 ? blocks : 1));
  int* cols = Exec::ptr(cpl_cols_);
  double* vals = Exec::ptr(cpl_vals_);
  int* row_ptr = Exec::ptr(cpl_row_ptr_);
  int* start = Exec::ptr(mblock_start_);
  int* block_row = Exec::ptr(mblock_row_);
  Exec::for_each(valid, [=] GD_HD_LAMBDA(int k) {
    if (run[k + 1] == run[k]) return;  // not a head
    const int b = run[k];
    start[b] = k;
    cols[b] = static_cast<int>(keys[k] >> kColumnShift & kVertexMask);
    block_row[b] = static_cast<int>(keys[k] >> kRowShift);
  });
  Exec::for_each(1, [=] GD_HD_LAMBDA(int) {
    start[blocks] = valid;
    if (blocks == 0) cols[0] = 0;  // one zero block keeps the pointers valid (CouplingMatrix)
  });
  // 3. Row pointers: row i starts at the first block of a row >= i (binary search; rows sorted).
  Exec::for_each(n + 1, [=] GD_HD_LAMBDA(int i) {
    int lo = 0, hi = blocks;
    while (lo < hi) {
      const int mid = (lo + hi) / 2;
      if (block_row[mid] < i) lo = mid + 1;
      else hi = mid;
    }
    row_ptr[i] = lo;
  });
  // 4. Each block the sum of its run, in slot order (a stored block or its transpose).
  Exec::for_each(blocks > 0 ? blocks : 1, [=] GD_HD_LAMBDA(int b) {
    double acc[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
    if (b < blocks)
      for (int k = start[b]; k < start[b + 1]; ++k) {
        const int s = static_cast<int>(keys[k] & kSlotMask), p = s / 12;
        int a, c;
        slot_vertices(s % 12, &a, &c);
        const double* H = (p < n0 ? H0 + static_cast<size_t>(kPairBlockValues) * p
                                  : H1 + static_cast<size_t>(kPairBlockValues) * (p - n0)) +
                          (a < c ? pair_block_offset(a, c) : pair_block_offset(c, a));
        if (a < c) {
          for (int q = 0; q < 9; ++q) acc[q] += H[q];
        } else {
          for (int r = 0; r < 3; ++r)
            for (int q = 0; q < 3; ++q) acc[3 * r + q] += H[3 * q + r];
        }
      }
    for (int q = 0; q < 9; ++q) vals[9 * static_cast<size_t>(b) + q] = acc[q];
  }, Exec::kParallelMinHeavy);
}

}  // namespace gd::sim
