#pragma once
/// \file
/// The CPU execution policies of the shared solver: plain host vectors and OpenMP loops.
/// CpuExec (the CPU backend): element loops that scatter into shared rows run colour by colour
/// over chunks of consecutive elements (no two chunks of one colour share a vertex; SceneData's
/// Coloring), so adds need no atomics and results are deterministic. CpuGpuPathsExec runs the
/// CUDA backend's code paths on the CPU, so that CPU tests execute them.

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <limits>
#include <numeric>
#include <vector>

#include "sim/backend/cpu/block_row_cpu.h"
#include "sim/backend/cpu/huge_page_allocator.h"
#include "sim/backend/cpu/mas_solve_cpu.h"
#include "sim/backend/cpu/omp_threads.h"
#include "sim/backend/round_trips.h"
#include "sim/demand.h"
#include "sim/hd.h"
#include "sim/team.h"

namespace gd::sim {

struct CpuExec {
  static constexpr const char* kName = "cpu";
  /// Element loops use a chunk colouring instead of atomic adds.
  static constexpr bool kColoring = true;
  /// Vector<T> is host memory: host-side stages (the contact couplings' merge, the sparse direct
  /// solver) read it in place.
  static constexpr bool kHostMemory = true;
  /// The contact couplings are merged by the host's OpenMP code, reading the pairs in place
  /// (pair_blocks.cpp); policies without it merge on the backend (coupling_merge.h).
  static constexpr bool kHostMerge = true;
  /// The LBVH broad phase's pairs are sorted per query and unpacked on the host
  /// (lbvh_broad_phase.h); policies without it sort and unpack them on the backend and copy the
  /// result back in one piece.
  static constexpr bool kHostPairs = true;
  /// The LBVH's queries traverse once, each chunk of queries growing its own list
  /// (Lbvh::query_single_pass); policies without it count, then write (two traversals).
  static constexpr bool kSinglePassQueries = true;

  template <class T>
  using Vector = std::vector<T>;
  /// An array of megabytes allocated once per scene and streamed through every iteration (the
  /// Hessian's blocks, MAS's dense blocks and factors): on transparent huge pages
  /// (huge_page_allocator.h), so that a pass over it does not miss the TLB every 4 KiB.
  template <class T>
  using LargeVector = std::vector<T, HugePageAllocator<T>>;

  template <class T, class A>
  static T* ptr(std::vector<T, A>& v) { return v.data(); }
  template <class T, class A>
  static const T* ptr(const std::vector<T, A>& v) { return v.data(); }
  template <class T>
  static void upload(Vector<T>& dst, const std::vector<T>& src) { dst = src; }
  template <class T>
  static void download(std::vector<T>& dst, const Vector<T>& src) { dst = src; }
  /// src's src.size() values copied to dst (host memory the caller sized).
  template <class T>
  static void download_to(T* dst, const Vector<T>& src) { std::copy(src.begin(), src.end(), dst); }
  template <class T, class A>
  static void resize(std::vector<T, A>& v, size_t n) { v.assign(n, T{}); }
  /// n elements whose values the caller overwrites before reading: keeps what is there and
  /// reallocates only to grow (per-pair buffers change size every Newton iteration; zeroing
  /// ~10 MB of them per step was ~2% of a 2-thread T-shirt step, on one thread).
  template <class T>
  static void resize_for_overwrite(Vector<T>& v, size_t n) { v.resize(n); }
  template <class T>
  static void fill(Vector<T>& v, T value) { std::fill(v.begin(), v.end(), value); }

  /// Loops shorter than this run on the calling thread: a parallel region costs more than a
  /// few thousand cheap iterations, and far more when the cores are busy with other work.
  static constexpr int kParallelMin = 16384;
  /// The same for loops whose iterations are heavy (element energies and Hessians).
  static constexpr int kParallelMinHeavy = 1024;
  /// The same for PCG's vector operations over 3n coordinates, run ~10 times per iteration on
  /// a warm team (RGBench's 4867-vertex T-shirt: its dot products and updates were serial).
  static constexpr int kParallelMinVector = 4096;

  /// Runs f(i) for i in [0, n) on the OpenMP threads.
  template <class F>
  static void for_each(int n, const F& f, int parallel_min = kParallelMin) {
#pragma omp parallel for schedule(static) if (n >= parallel_min)
    for (int i = 0; i < n; ++i) f(i);
  }

  /// for_each with the iterations handed to the threads one at a time as they come free: for a
  /// few dozen iterations of widely different cost (the LBVH's query chunks: one region of the
  /// cloth in contact, another not) where each iteration writes only its own output, so who runs
  /// which changes nothing. Not for loops that write rows another pass reads: a static schedule
  /// keeps those in the cache of the core that wrote them.
  template <class F>
  static void for_each_dynamic(int n, const F& f, int parallel_min = kParallelMin) {
#pragma omp parallel for schedule(dynamic, 1) if (n >= parallel_min)
    for (int i = 0; i < n; ++i) f(i);
  }

  /// The team of for_each_team's work items (sim/team.h): the calling thread.
  using Team = SerialTeam;

  /// Runs f(team, t) for t in [0, n), one team per work item (sim/team.h); on the CPU a team is
  /// the thread that runs the item.
  template <class F>
  static void for_each_team(int n, const F& f, int parallel_min = kParallelMin) {
    for_each(n, [&](int t) { f(Team{}, t); }, parallel_min);
  }

  /// Sum of f(i) over [0, n). Loops of parallel_min or more are summed in blocks of a size set
  /// by n and parallel_min alone, the block sums then added in order: the same bits at any
  /// thread count (an OpenMP reduction adds in an order that depends on it, and a run's steps
  /// then differ in the last bits between 1 and 2 threads).
  template <class F>
  static double sum(int n, const F& f, int parallel_min = kParallelMin) {
    return block_sum<double>(n, f, parallel_min);
  }

  /// The work of items [0, i) counted as i: block_sum's default split, by item count.
  struct CountWork {
    int64_t operator()(int i) const { return i; }
  };

  /// sum() for any T with += (double, Sum2): T{} plus f(i) in sum()'s blocks and order. The
  /// blocks are dealt to the threads by work_before(i), the work of items [0, i) (non-decreasing
  /// in i): by item count unless the items differ in cost. Only who computes a block changes, not
  /// its sum.
  template <class T, class F, class W = CountWork>
  static T block_sum(int n, const F& f, int parallel_min, const W& work_before = W{}) {
    T s{};
    if (n < parallel_min || n <= 0) {
      for (int i = 0; i < n; ++i) s += f(i);
      return s;
    }
    const int block = std::max(64, parallel_min / 8);
    const int blocks = (n + block - 1) / block;
    constexpr int kOnStack = 256;
    T stack[kOnStack];
    std::vector<T> heap(blocks > kOnStack ? blocks : 0);
    T* part = blocks > kOnStack ? heap.data() : stack;
#pragma omp parallel
    {
      const int threads = omp_team_size(), t = omp_thread();
      const int first = first_block_of(t, threads, n, block, blocks, work_before);
      const int last = first_block_of(t + 1, threads, n, block, blocks, work_before);
      for (int b = first; b < last; ++b) {
        T p{};
        const int end = std::min(n, (b + 1) * block);
        for (int i = b * block; i < end; ++i) p += f(i);
        part[b] = p;
      }
    }
    for (int b = 0; b < blocks; ++b) s += part[b];
    return s;
  }

  /// The first of thread t's blocks in block_sum: each thread takes a run of whole blocks whose
  /// items come within half a block of an even split of the n items. (OpenMP's static schedule of
  /// the blocks gave the first thread one whole block more than the second: at 2 threads 20 of
  /// the 4867-vertex T-shirt's 39 product blocks, 2560 rows against 2307, and 15 of a PCG
  /// vector's 29, 11% more items.)
  static int first_block_of(int t, int threads, int n, int block, int blocks) {
    return first_block_of(t, threads, n, block, blocks, CountWork{});
  }

  /// first_block_of by work: thread t starts at the block boundary whose work_before is nearest
  /// t / threads of the whole (a tie: the later boundary).
  template <class W>
  static int first_block_of(int t, int threads, int n, int block, int blocks, const W& work_before) {
    if (t <= 0) return 0;
    if (t >= threads) return blocks;
    auto at = [&](int b) {
      return static_cast<double>(work_before(static_cast<int>(std::min<int64_t>(n, static_cast<int64_t>(b) * block))));
    };
    const double share = at(blocks) * t / threads;
    int lo = 0, hi = blocks;  // the first boundary at or past the share
    while (lo < hi) {
      const int mid = lo + (hi - lo) / 2;
      if (at(mid) < share) lo = mid + 1;
      else hi = mid;
    }
    if (lo > 0 && share - at(lo - 1) < at(lo) - share) --lo;
    return lo;
  }

  /// Sum of f(i) over [0, n) where f also writes memory (each i evaluated exactly once).
  template <class F>
  static double sum_effects(int n, const F& f, int parallel_min = kParallelMin) {
    return sum(n, f, parallel_min);
  }

  /// Sum of f(i) over [0, n) into *out, the backend's memory: no value returns to the host.
  template <class F>
  static void sum_to(int n, const F& f, double* out, int parallel_min = kParallelMin) {
    *out = CpuExec::sum(n, f, parallel_min);
  }
  /// sum_effects into *out, the backend's memory.
  template <class F>
  static void sum_effects_to(int n, const F& f, double* out, int parallel_min = kParallelMin) {
    *out = CpuExec::sum_effects(n, f, parallel_min);
  }
  /// sum_effects_to for items of unequal cost: work_before(i) is the work of items [0, i)
  /// (non-decreasing), and the threads take block_sum's blocks by work instead of by count. The
  /// same blocks added in the same order: the bits of sum_effects_to.
  template <class F, class W>
  static void sum_effects_balanced_to(int n, const F& f, const W& work_before, double* out,
                                      int parallel_min = kParallelMin) {
    *out = block_sum<double>(n, f, parallel_min, work_before);
  }
  /// Two sums of one loop into *out_a and *out_b (the backend's memory): f(i) returns both terms
  /// of i as a Sum2 and may write memory (each i evaluated exactly once); each term is added in
  /// sum()'s blocks and order, so the bits do not depend on the thread count.
  template <class F>
  static void sum2_effects_to(int n, const F& f, double* out_a, double* out_b, int parallel_min = kParallelMin) {
    const Sum2 s = block_sum<Sum2>(n, f, parallel_min);
    *out_a = s.a;
    *out_b = s.b;
  }
  /// PCG reads its stop flag every this many iterations (Solver::solve_pcg): every iteration on
  /// the CPU, where a read costs nothing.
  static constexpr int kPcgCheckEvery = 1;

  /// Maximum of f(i) over [0, n) (0 for n == 0).
  template <class F>
  static double max(int n, const F& f, int parallel_min = kParallelMin) {
    double m = 0.0;
#pragma omp parallel for schedule(static) reduction(max : m) if (n >= parallel_min)
    for (int i = 0; i < n; ++i) m = std::max(m, f(i));
    return m;
  }
  /// max() into *out, the backend's memory: no value returns to the host.
  template <class F>
  static void max_to(int n, const F& f, double* out, int parallel_min = kParallelMin) {
    *out = CpuExec::max(n, f, parallel_min);
  }
  /// Minimum of f(i) over [0, n) into *out (+infinity for n == 0); a NaN term is skipped
  /// (std::min keeps the running minimum).
  template <class F>
  static void min_to(int n, const F& f, double* out, int parallel_min = kParallelMin) {
    double m = std::numeric_limits<double>::infinity();
#pragma omp parallel for schedule(static) reduction(min : m) if (n >= parallel_min)
    for (int i = 0; i < n; ++i) m = std::min(m, f(i));
    *out = m;
  }

  /// Add into memory owned by the current element's colour (exclusive by construction).
  static inline void add(double* p, double v) { *p += v; }

  /// Adds 1 to *p, which other iterations of the same loop may increment at the same time, and
  /// returns the value before (acquire-release: what the incrementing iterations wrote before is
  /// visible after it).
  static inline int atomic_increment(int* p) { return std::atomic_ref<int>(*p).fetch_add(1, std::memory_order_acq_rel); }

  /// Sorts 64-bit keys ascending. From kParallelMinVector keys on, contiguous runs (one per
  /// thread) are sorted in parallel and then merged pairwise, each round's merges in parallel:
  /// the LBVH's Morton keys were a serial sort on the main thread of every 2-thread broad phase.
  /// Keys are plain integers, so every correct sort gives the same array: the same bits at any
  /// thread count.
  static void sort(Vector<uint64_t>& v) {
    const int n = static_cast<int>(v.size());
    const int runs = n >= kParallelMinVector ? std::min(omp_threads(), 16) : 1;
    if (runs <= 1) {
      std::sort(v.begin(), v.end());
      return;
    }
    auto bound = [&](int r) { return v.begin() + static_cast<long>(static_cast<int64_t>(n) * r / runs); };
#pragma omp parallel for schedule(static, 1)
    for (int r = 0; r < runs; ++r) std::sort(bound(r), bound(r + 1));
    for (int width = 1; width < runs; width *= 2) {
      const int merges = (runs + 2 * width - 1) / (2 * width);
#pragma omp parallel for schedule(static, 1) if (merges > 1)
      for (int m = 0; m < merges; ++m) {
        const int lo = 2 * width * m, mid = std::min(lo + width, runs), hi = std::min(lo + 2 * width, runs);
        if (mid < hi) std::inplace_merge(bound(lo), bound(mid), bound(hi));
      }
    }
  }
  /// In-place exclusive prefix sum of v[0, count).
  template <class T>
  static void exclusive_scan(Vector<T>& v, int count) {
    std::exclusive_scan(v.begin(), v.begin() + count, v.begin(), T{0});
  }
  /// One element, read back to the host.
  template <class T>
  static T read(const Vector<T>& v, size_t i) { return v[i]; }
  /// A host vector handed to the backend (the CPU takes it as it is; its old contents come back).
  template <class T>
  static void take(Vector<T>& dst, std::vector<T>& src) { dst.swap(src); }
  /// Waits for queued work (stage timers); nothing is queued on the CPU.
  static void sync() {}

  /// A row of the block product (sim/block_row.h): AVX2 where the processor has it, the same bits.
  static void block_row(int i, const BlockRows& A, const BlockRows& C, const double* x, double* y) {
    block_row_product_cpu(i, A, C, x, y);
  }

  /// MAS domains factored and solved together (backend/cpu/mas_solve_cpu.h): their factors are
  /// packed interleaved by this many, with AVX2 where the processor has it, the same bits.
  static constexpr int kMasLanes = kMasCpuLanes;
  static void mas_factor_lanes(double* const* A, int m, float* P) { mas_factor_lanes_cpu(A, m, P); }
  static void mas_solve_lanes(const float* P, int m, double* b) { mas_solve_lanes_cpu(P, m, b); }
};

/// The CUDA backend's code paths on the CPU (BackendKind::kCpuGpuPaths): element loops without
/// colouring, every add into shared rows atomic (std::atomic_ref), the contact pairs' adds in
/// parallel. Like the GPU's, its results vary in the last bits with thread timing. For tests
/// (ctest label gpu-paths) and for measuring what the atomics cost.
struct CpuGpuPathsExec : CpuExec {
  static constexpr const char* kName = "cpu-gpu-paths";
  static constexpr bool kColoring = false;
  static constexpr bool kHostMerge = false;  ///< as CudaExec
  static constexpr bool kHostPairs = false;  ///< as CudaExec
  static constexpr int kMasLanes = 1;        ///< as CudaExec: a warp per domain
  static constexpr bool kSinglePassQueries = false;  ///< as CudaExec
  static constexpr int kPcgCheckEvery = 8;  ///< as CudaExec
  /// Add into memory other threads may add into at the same time.
  static inline void add(double* p, double v) { std::atomic_ref<double>(*p).fetch_add(v, std::memory_order_relaxed); }
  /// The block product's row as the GPU computes it: the portable loop (CPU tests compare the two).
  static void block_row(int i, const BlockRows& A, const BlockRows& C, const double* x, double* y) {
    block_row_product(i, A, C, x, y);
  }

  /// Test seam: loops still allowed to "launch" on this thread before one fails with BackendError,
  /// as a GPU kernel launch can (< 0: never). CPU tests use it to check that a failed launch fails
  /// that scene's step and nothing else (tests/sim/backend/backend_error_test.cpp).
  static inline thread_local int launches_before_failure = -1;
  template <class F>
  static void for_each(int n, const F& f, int parallel_min = kParallelMin) {
    if (launches_before_failure == 0) {
      launches_before_failure = -1;
      throw BackendError("cpu-gpu-paths backend: kernel launch failed (simulated)");
    }
    if (launches_before_failure > 0) --launches_before_failure;
    CpuExec::for_each(n, f, parallel_min);
  }

  /// The GPU's teams (a warp's lanes and order of additions) replayed on the CPU.
  using Team = WarpOrderTeam;
  template <class F>
  static void for_each_team(int n, const F& f, int parallel_min = kParallelMin) {
    for_each(n, [&](int t) { f(Team{}, t); }, parallel_min);
  }

  // What returns a value or a copy to the host counts as a round trip (host_round_trips()), as
  // it would on the GPU.
  template <class F>
  static double sum(int n, const F& f, int parallel_min = kParallelMin) {
    ++host_round_trips().reductions;
    return CpuExec::sum(n, f, parallel_min);
  }
  template <class F>
  static double sum_effects(int n, const F& f, int parallel_min = kParallelMin) {
    ++host_round_trips().reductions;
    return CpuExec::sum_effects(n, f, parallel_min);
  }
  template <class F>
  static double max(int n, const F& f, int parallel_min = kParallelMin) {
    ++host_round_trips().reductions;
    return CpuExec::max(n, f, parallel_min);
  }
  template <class T>
  static void download(std::vector<T>& dst, const Vector<T>& src) {
    ++host_round_trips().downloads;
    CpuExec::download(dst, src);
  }
  template <class T>
  static void download_to(T* dst, const Vector<T>& src) {
    ++host_round_trips().downloads;
    CpuExec::download_to(dst, src);
  }
  template <class T>
  static T read(const Vector<T>& v, size_t i) {
    ++host_round_trips().downloads;
    return v[i];
  }
};

}  // namespace gd::sim
