#pragma once
/// \file
/// Contact couplings as a block matrix: the off-diagonal 3x3 blocks of the contact pairs' 12x12
/// Hessians summed per coupled (row, column) vertex pair into a block CSR. Host code, the CPU
/// backend's path (the GPU's policies build the CSR on the backend: solver/coupling_merge.h, and
/// come here only for scenes too large for its keys), run in parallel over the OpenMP threads with
/// a result that does not depend on their number.

#include <vector>

namespace gd::sim {

/// Values stored per pair: the six 3x3 blocks (a, b), a < b, of its symmetric 12x12 Hessian above
/// the diagonal, each row-major, in the order (0,1), (0,2), (0,3), (1,2), (1,3), (2,3); block (b, a)
/// is the transpose of (a, b). (The diagonal blocks go straight into the matrix's diagonal.)
constexpr int kPairBlockValues = 54;

/// Offset of block (a, b), a < b, within a pair's kPairBlockValues.
constexpr int pair_block_offset(int a, int b) { return 9 * (a == 0 ? b - 1 : a == 1 ? b + 1 : 5); }

/// One list of pairs: `count` pairs of 4 vertex ids (v, 4 per pair) with their off-diagonal
/// Hessian blocks (H, kPairBlockValues per pair).
struct PairHessians {
  int count = 0;
  const int* v = nullptr;
  const double* H = nullptr;
};

/// Block CSR of the couplings: row i's blocks are cols/vals[row_ptr[i], row_ptr[i+1]) (vals: 9
/// per block, row-major). Never empty: a matrix without couplings holds one zero block after the
/// last row, so pointers into it stay valid.
struct CouplingMatrix {
  std::vector<int> row_ptr, cols;
  std::vector<double> vals;
  /// merge_pair_blocks' working arrays (per-thread counts, each vertex's pair corners, the rows
  /// laid out at their bound before the zero blocks are left out), kept from call to call rather
  /// than allocated and page-faulted every Newton iteration.
  struct Scratch {
    std::vector<int> counts, start, incidences, bound, cols;
    std::vector<double> vals;
  } scratch;
};

/// Sums the off-diagonal blocks (a != b) of every pair in `lists` between free vertices (fixed[v]
/// == 0) into `out` (overwritten; its storage is reused). n: vertex count. A row's columns come in
/// the order they first appear (lists in order, pairs in order, a then b), and the blocks of one
/// column are summed in that order: the same bits on any number of threads. A column whose sum
/// is zero gets no slot (it adds nothing to a product).
void merge_pair_blocks(int n, const int* fixed, const std::vector<PairHessians>& lists, CouplingMatrix* out);

}  // namespace gd::sim
