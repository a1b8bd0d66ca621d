#include "sim/solver/pair_blocks.h"

#include <algorithm>
#include <limits>

#include "sim/backend/cpu/omp_threads.h"
#include "sim/demand.h"

namespace gd::sim {
namespace {

/// The lists' pairs numbered one after another: pair p's list and index within it.
struct PairIndex {
  const std::vector<PairHessians>* lists;
  const PairHessians& list(long p, long* local) const {
    for (const PairHessians& l : *lists) {
      if (p < l.count) {
        *local = p;
        return l;
      }
      p -= l.count;
    }
    GD_DEMAND(false, "pair index past the lists");
    return lists->front();
  }
};

}  // namespace

void merge_pair_blocks(int n, const int* fixed, const std::vector<PairHessians>& lists, CouplingMatrix* out) {
  long pairs = 0;
  for (const PairHessians& l : lists) pairs += l.count;
  GD_DEMAND(4 * pairs < std::numeric_limits<int>::max(), "too many contact pairs to merge");
  const PairIndex index{&lists};
  const int threads = pairs >= 2048 ? std::max(1, omp_threads()) : 1;
  // 1. Each free vertex's incidences (pair, corner), in pair order: each thread counts those of
  //    its contiguous range of pairs per vertex, a vertex's are laid out thread by thread, then
  //    filled (4 ints per pair: at 20k vertices ~4 MB, where a reference per block was ~50 MB).
  std::vector<int>& counts = out->scratch.counts;
  counts.assign(static_cast<size_t>(threads) * (n + 1), 0);
  auto range = [&](int t, long* b, long* e) {
    *b = pairs * t / threads;
    *e = pairs * (t + 1) / threads;
  };
  auto each_corner = [&](long b, long e, auto&& f) {  // f(vertex, 4 p + a) over free corners
    for (long p = b; p < e;) {
      long local;
      const PairHessians& l = index.list(p, &local);
      const long stop = std::min(e, p - local + l.count);
      for (; p < stop; ++p, ++local)
        for (int a = 0; a < 4; ++a) {
          const int v = l.v[4 * local + a];
          if (!fixed[v]) f(v, static_cast<int>(4 * p + a));
        }
    }
  };
#pragma omp parallel num_threads(threads)
  {
    const int t = omp_thread();
    long b, e;
    range(t, &b, &e);
    int* c = counts.data() + static_cast<size_t>(t) * (n + 1);
    each_corner(b, e, [&](int v, int) { ++c[v]; });
  }
  std::vector<int>& start = out->scratch.start;  // incidences of vertex i: [start[i], start[i+1])
  start.assign(n + 1, 0);
  for (int i = 0; i < n; ++i) {
    int s = start[i];
    for (int t = 0; t < threads; ++t) {
      int& c = counts[static_cast<size_t>(t) * (n + 1) + i];
      const int k = c;
      c = s;  // now the thread's cursor into vertex i's incidences
      s += k;
    }
    start[i + 1] = s;
  }
  std::vector<int>& inc = out->scratch.incidences;
  inc.resize(start[n]);  // every entry written below
#pragma omp parallel num_threads(threads)
  {
    const int t = omp_thread();
    long b, e;
    range(t, &b, &e);
    int* cursor = counts.data() + static_cast<size_t>(t) * (n + 1);
    each_corner(b, e, [&](int v, int pa) { inc[cursor[v]++] = pa; });
  }
  // Row i's blocks, in order: its incidences (pair order), each pair's other free corners b in
  // order; block (a, b) is stored above the diagonal (a < b) or is the transpose of (b, a).
  auto each_block = [&](int i, auto&& f) {  // f(col, block, transposed)
    for (int k = start[i]; k < start[i + 1]; ++k) {
      const long p = inc[k] >> 2;
      const int a = inc[k] & 3;
      long local;
      const PairHessians& l = index.list(p, &local);
      const int* vs = l.v + 4 * local;
      const double* H = l.H + kPairBlockValues * local;
      for (int b = 0; b < 4; ++b)
        if (b != a && !fixed[vs[b]]) f(vs[b], H + (a < b ? pair_block_offset(a, b) : pair_block_offset(b, a)), a > b);
    }
  };
  // 2. Per row, one slot per distinct column in order of first appearance, holding the sum of
  //    the column's blocks, and none for a column whose sum is zero (a quarter of fold/5000's: a
  //    barrier's Hessian couples only the corners of its closest feature). A zero slot adds
  //    nothing to a product, so leaving it out changes no sum, and it would cost every PCG
  //    iteration its 72 bytes and nine products. Count the columns (a bound: which sums are zero
  //    is known once they are summed), lay the rows out at the bound, sum the blocks and move
  //    each row's nonzero slots up, then copy the rows into place.
  //    mark/pos: per-thread column stamps of the current row.
  std::vector<int>& bound = out->scratch.bound;  // row i's slots at most: [bound[i], bound[i+1])
  bound.assign(n + 1, 0);
  const int row_threads = start[n] >= 1024 ? std::max(1, omp_threads()) : 1;
#pragma omp parallel num_threads(row_threads)
  {
    std::vector<int> mark(n, -1);
#pragma omp for schedule(static)
    for (int i = 0; i < n; ++i) {
      int k = 0;
      each_block(i, [&](int col, const double*, bool) {
        if (mark[col] != i) mark[col] = i, ++k;
      });
      bound[i + 1] = k;
    }
  }
  for (int i = 0; i < n; ++i) bound[i + 1] += bound[i];
  std::vector<int>& bound_cols = out->scratch.cols;
  std::vector<double>& bound_vals = out->scratch.vals;
  bound_cols.resize(bound[n]);
  bound_vals.assign(9 * static_cast<size_t>(bound[n]), 0.0);
  std::vector<int>& row_ptr = out->row_ptr;
  row_ptr.assign(n + 1, 0);
#pragma omp parallel num_threads(row_threads)
  {
    std::vector<int> mark(n, -1), pos(n);
#pragma omp for schedule(static)
    for (int i = 0; i < n; ++i) {
      int k = bound[i];
      each_block(i, [&](int col, const double* block, bool transposed) {
        if (mark[col] != i) {
          mark[col] = i;
          pos[col] = k;
          bound_cols[k++] = col;
        }
        double* dst = bound_vals.data() + 9 * static_cast<size_t>(pos[col]);
        if (transposed) {
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) dst[3 * r + c] += block[3 * c + r];
        } else {
          for (int q = 0; q < 9; ++q) dst[q] += block[q];
        }
      });
      // The row's zero slots left out, the others moved up in order (in this core's cache).
      int kept = bound[i];
      for (int slot = bound[i]; slot < k; ++slot) {
        const double* v = bound_vals.data() + 9 * static_cast<size_t>(slot);
        bool zero = true;
        for (int q = 0; q < 9; ++q) zero &= v[q] == 0.0;
        if (zero) continue;
        if (kept != slot) {
          bound_cols[kept] = bound_cols[slot];
          std::copy_n(v, 9, bound_vals.data() + 9 * static_cast<size_t>(kept));
        }
        ++kept;
      }
      row_ptr[i + 1] = kept - bound[i];
    }
  }
  for (int i = 0; i < n; ++i) row_ptr[i + 1] += row_ptr[i];
  const int blocks = row_ptr[n];
  out->cols.resize(std::max(blocks, 1));
  out->vals.resize(9 * static_cast<size_t>(std::max(blocks, 1)));
  if (blocks == 0) {  // keep the pointers valid
    out->cols[0] = 0;
    std::fill(out->vals.begin(), out->vals.end(), 0.0);
  }
  int* cols = out->cols.data();
  double* vals = out->vals.data();
#pragma omp parallel for num_threads(row_threads) schedule(static)
  for (int i = 0; i < n; ++i) {
    const int from = bound[i], count = row_ptr[i + 1] - row_ptr[i];
    std::copy_n(bound_cols.data() + from, count, cols + row_ptr[i]);
    std::copy_n(bound_vals.data() + 9 * static_cast<size_t>(from), 9 * static_cast<size_t>(count),
                vals + 9 * static_cast<size_t>(row_ptr[i]));
  }
}

}  // namespace gd::sim
