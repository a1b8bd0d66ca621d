#include "sim/solver/pair_blocks.h"

#include <algorithm>

#include "sim/backend/cpu/omp_threads.h"

namespace gd::sim {
namespace {

/// Calls f(row, col, block, transposed) for every off-diagonal block between free vertices of the
/// pairs [begin, end) of the concatenated lists, in order; block (row, col) is the stored 3x3 at
/// `block`, or its transpose when `transposed`.
template <class F>
void each_block(const std::vector<PairHessians>& lists, const int* fixed, long begin, long end, F&& f) {
  long base = 0;
  for (const PairHessians& l : lists) {
    const long lo = std::max(begin, base), hi = std::min(end, base + l.count);
    for (long c = lo; c < hi; ++c) {
      const long p = c - base;
      const int* vs = l.v + 4 * p;
      for (int a = 0; a < 4; ++a) {
        if (fixed[vs[a]]) continue;
        for (int b = 0; b < 4; ++b)
          if (b != a && !fixed[vs[b]])
            f(vs[a], vs[b], l.H + kPairBlockValues * p + (a < b ? pair_block_offset(a, b) : pair_block_offset(b, a)),
              a > b);
      }
    }
    base += l.count;
  }
}

}  // namespace

void merge_pair_blocks(int n, const int* fixed, const std::vector<PairHessians>& lists, CouplingMatrix* out) {
  using Ref = CouplingMatrix::Ref;
  long pairs = 0;
  for (const PairHessians& l : lists) pairs += l.count;
  const int threads = pairs >= 2048 ? std::max(1, omp_threads()) : 1;
  // 1. Each thread counts the blocks per row of its contiguous range of pairs; a row's blocks
  //    are then laid out thread by thread, i.e. in pair order whatever the thread count.
  std::vector<int>& counts = out->scratch.counts;
  counts.assign(static_cast<size_t>(threads) * (n + 1), 0);
  auto range = [&](int t, long* b, long* e) {
    *b = pairs * t / threads;
    *e = pairs * (t + 1) / threads;
  };
#pragma omp parallel num_threads(threads)
  {
    const int t = omp_thread();
    long b, e;
    range(t, &b, &e);
    int* c = counts.data() + static_cast<size_t>(t) * (n + 1);
    each_block(lists, fixed, b, e, [&](int row, int, const double*, bool) { ++c[row]; });
  }
  std::vector<int>& start = out->scratch.start;  // refs of row i: [start[i], start[i+1])
  start.assign(n + 1, 0);
  for (int i = 0; i < n; ++i) {
    int s = start[i];
    for (int t = 0; t < threads; ++t) {
      int& c = counts[static_cast<size_t>(t) * (n + 1) + i];
      const int k = c;
      c = s;  // now the thread's cursor into row i
      s += k;
    }
    start[i + 1] = s;
  }
  std::vector<Ref>& refs = out->scratch.refs;
  refs.resize(start[n]);  // every entry written below
#pragma omp parallel num_threads(threads)
  {
    const int t = omp_thread();
    long b, e;
    range(t, &b, &e);
    int* cursor = counts.data() + static_cast<size_t>(t) * (n + 1);
    each_block(lists, fixed, b, e, [&](int row, int col, const double* blk, bool tr) {
      refs[cursor[row]++] = {blk, col, tr ? 1 : 0};
    });
  }
  // 2. Per row, one block per distinct column in order of first appearance: count them, lay the
  //    rows out, then sum the blocks (mark/pos: per-thread column stamps of the current row).
  std::vector<int>& row_ptr = out->row_ptr;
  row_ptr.assign(n + 1, 0);
  const int row_threads = start[n] >= 4096 ? std::max(1, omp_threads()) : 1;
#pragma omp parallel num_threads(row_threads)
  {
    std::vector<int> mark(n, -1);
#pragma omp for schedule(static)
    for (int i = 0; i < n; ++i) {
      int k = 0;
      for (int e = start[i]; e < start[i + 1]; ++e)
        if (mark[refs[e].col] != i) mark[refs[e].col] = i, ++k;
      row_ptr[i + 1] = k;
    }
  }
  for (int i = 0; i < n; ++i) row_ptr[i + 1] += row_ptr[i];
  const int blocks = row_ptr[n];
  out->cols.resize(std::max(blocks, 1));
  out->vals.assign(9 * static_cast<size_t>(std::max(blocks, 1)), 0.0);
  if (blocks == 0) out->cols[0] = 0;  // keep the pointers valid
  int* cols = out->cols.data();
  double* vals = out->vals.data();
#pragma omp parallel num_threads(row_threads)
  {
    std::vector<int> mark(n, -1), pos(n);
#pragma omp for schedule(static)
    for (int i = 0; i < n; ++i) {
      int k = row_ptr[i];
      for (int e = start[i]; e < start[i + 1]; ++e) {
        const Ref& ref = refs[e];
        if (mark[ref.col] != i) {
          mark[ref.col] = i;
          pos[ref.col] = k;
          cols[k++] = ref.col;
        }
        double* dst = vals + 9 * static_cast<size_t>(pos[ref.col]);
        if (ref.transposed) {
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) dst[3 * r + c] += ref.block[3 * c + r];
        } else {
          for (int k = 0; k < 9; ++k) dst[k] += ref.block[k];
        }
      }
    }
  }
}

}  // namespace gd::sim
