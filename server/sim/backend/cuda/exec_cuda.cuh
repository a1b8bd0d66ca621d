#pragma once
/// \file
/// The CUDA execution policy of the shared solver: device vectors, one kernel per loop, CUB
/// reductions into per-thread device scratch (no cudaMalloc per reduction), and atomic adds for
/// element scatter (no colouring needed on the GPU); what the host reads back comes through a
/// pinned buffer per thread, copied asynchronously on the thread's stream. Compiled with `--default-stream per-thread`
/// (server/sim/CMakeLists.txt): a scene steps on one host thread, so the scenes a server steps on
/// its worker threads run on separate streams and overlap. Every launch is checked; a failure
/// throws BackendError, which fails the step of that scene (Scene::step), not the process.

#include <cub/device/device_radix_sort.cuh>
#include <cub/device/device_reduce.cuh>
#include <cub/device/device_scan.cuh>
#include <thrust/device_vector.h>
#include <thrust/execution_policy.h>
#include <thrust/fill.h>
#include <thrust/functional.h>
#include <thrust/reduce.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/iterator/transform_iterator.h>
#include <thrust/transform_reduce.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "sim/backend/round_trips.h"
#include "sim/block_row.h"
#include "sim/demand.h"
#include "sim/hd.h"
#include "sim/team.h"

namespace gd::sim {

template <class F>
__global__ void gd_for_each_kernel(int n, F f) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) f(i);
}

/// One warp per work item: warps leave together (t is the same on all 32 lanes), so every
/// __syncwarp() of a team sees its whole warp.
template <class F>
__global__ void gd_for_each_team_kernel(int n, F f) {
  const int t = static_cast<int>((blockIdx.x * blockDim.x + threadIdx.x) / kWarpLanes);
  if (t < n) f(WarpTeam{}, t);
}

struct CudaExec {
  static constexpr const char* kName = "cuda";
  static constexpr bool kColoring = false;
  static constexpr bool kHostMemory = false;  ///< device vectors: host-side stages copy them
  static constexpr bool kHostMerge = false;   ///< contact couplings merged on the device
  static constexpr bool kHostPairs = false;   ///< broad-phase pairs sorted and unpacked on the device
  static constexpr bool kSinglePassQueries = false;  ///< LBVH queries count, then write (lbvh.h)

  template <class T>
  using Vector = thrust::device_vector<T>;
  /// Exec's array of megabytes (the CPU's is on huge pages); device memory as any other here.
  template <class T>
  using LargeVector = Vector<T>;

  template <class T>
  static T* ptr(Vector<T>& v) { return thrust::raw_pointer_cast(v.data()); }
  template <class T>
  static const T* ptr(const Vector<T>& v) { return thrust::raw_pointer_cast(v.data()); }
  template <class T>
  static void upload(Vector<T>& dst, const std::vector<T>& src) { dst.assign(src.begin(), src.end()); }
  template <class T>
  static void download(std::vector<T>& dst, const Vector<T>& src) {
    dst.resize(src.size());
    download_to(dst.data(), src);
  }
  /// src's src.size() values copied to dst (host memory the caller sized): one copy, on this
  /// thread's stream. Up to kPinnedBytes (the reductions' slots, counts, single values) through
  /// this thread's pinned buffer: an asynchronous copy the host waits for, then a memcpy (a copy
  /// from device memory to pageable memory stages through a driver buffer and waits for the whole
  /// device's legacy work).
  template <class T>
  static void download_to(T* dst, const Vector<T>& src) {
    ++host_round_trips().downloads;
    copy_to_host(dst, ptr(src), sizeof(T) * src.size());
  }
  /// Largest copy to the host that goes through the pinned buffer.
  static constexpr size_t kPinnedBytes = 64 * 1024;
  /// bytes from device memory at src to host memory at dst (waits for them).
  static void copy_to_host(void* dst, const void* src, size_t bytes) {
    if (bytes == 0) return;
    if (bytes > kPinnedBytes) {
      check(cudaMemcpyAsync(dst, src, bytes, cudaMemcpyDeviceToHost, cudaStreamPerThread), "download");
      check(cudaStreamSynchronize(cudaStreamPerThread), "download");
      return;
    }
    thread_local void* pinned = nullptr;
    if (pinned == nullptr) check(cudaMallocHost(&pinned, kPinnedBytes), "cudaMallocHost of the read-back buffer");
    check(cudaMemcpyAsync(pinned, src, bytes, cudaMemcpyDeviceToHost, cudaStreamPerThread), "download");
    check(cudaStreamSynchronize(cudaStreamPerThread), "download");
    std::memcpy(dst, pinned, bytes);
  }
  template <class T>
  static void resize(Vector<T>& v, size_t n) { v.assign(n, T{}); }
  /// n elements whose values the caller overwrites before reading: keeps what is there and
  /// reallocates only to grow (per-pair buffers change size every Newton iteration; zeroing
  /// ~10 MB of them per step was ~2% of a 2-thread T-shirt step, on one thread).
  template <class T>
  static void resize_for_overwrite(Vector<T>& v, size_t n) { v.resize(n); }
  template <class T>
  static void fill(Vector<T>& v, T value) { thrust::fill(v.begin(), v.end(), value); }

  static constexpr int kParallelMin = 0;
  static constexpr int kParallelMinHeavy = 0;
  static constexpr int kParallelMinVector = 0;

  /// Throws BackendError naming `what` when the runtime reports an error (of this call or an
  /// earlier asynchronous one).
  static void check(cudaError_t e, const char* what) {
    if (e != cudaSuccess)
      throw BackendError(std::string("CUDA backend: ") + what + " failed: " + cudaGetErrorName(e) + " (" +
                         cudaGetErrorString(e) + ")");
  }

  template <class F>
  static void for_each(int n, const F& f, int /*parallel_min*/ = 0) {
    if (n <= 0) return;
    constexpr int kBlock = 256;
    gd_for_each_kernel<<<(n + kBlock - 1) / kBlock, kBlock>>>(n, f);
    check(cudaGetLastError(), "kernel launch");
  }

  /// The team of for_each_team's work items (sim/team.h): one warp.
  using Team = WarpTeam;

  /// Runs f(team, t) for t in [0, n), one warp per work item: for work items whose inner
  /// loops (a domain's dense block) are too long for one thread.
  template <class F>
  static void for_each_team(int n, const F& f, int /*parallel_min*/ = 0) {
    if (n <= 0) return;
    constexpr int kTeamsPerBlock = 4;
    gd_for_each_team_kernel<<<(n + kTeamsPerBlock - 1) / kTeamsPerBlock, kTeamsPerBlock * kWarpLanes>>>(n, f);
    check(cudaGetLastError(), "kernel launch");
  }

  /// Device scratch of at least `bytes` for slot `k` (0: CUB's temporary storage, 1: values of
  /// sum_effects, 2: one double read back by sum/max, 3: the second buffer of sort and
  /// exclusive_scan), this thread's, kept until the process ends and grown as needed: no
  /// allocation per reduction, sort or scan (thrust's allocated and freed per call, and a free
  /// waits for the whole device).
  static void* scratch(int k, size_t bytes) {
    thread_local void* buffer[4] = {nullptr, nullptr, nullptr, nullptr};
    thread_local size_t capacity[4] = {0, 0, 0, 0};
    if (bytes > capacity[k]) {
      if (buffer[k]) check(cudaFree(buffer[k]), "cudaFree of scratch");
      buffer[k] = nullptr;
      capacity[k] = 0;
      const size_t want = bytes + bytes / 2 + 256;
      check(cudaMalloc(&buffer[k], want), "cudaMalloc of scratch");
      capacity[k] = want;
    }
    return buffer[k];
  }

  /// Sum of f(i) over [0, n) into *out, device memory: a CUB reduction queued on this thread's
  /// stream; no value returns to the host.
  template <class F>
  static void sum_to(int n, const F& f, double* out, int /*parallel_min*/ = 0) {
    if (n <= 0) {
      check(cudaMemsetAsync(out, 0, sizeof(double)), "cudaMemsetAsync");
      return;
    }
    auto in = thrust::make_transform_iterator(thrust::counting_iterator<int>(0), f);
    size_t bytes = 0;
    check(cub::DeviceReduce::Sum(nullptr, bytes, in, out, n), "reduction (size)");
    check(cub::DeviceReduce::Sum(scratch(0, bytes), bytes, in, out, n), "reduction");
  }

  /// One double of device memory read back to the host (a round trip).
  static double read_back(const double* d) {
    double h = 0;
    copy_to_host(&h, d, sizeof(double));
    return h;
  }

  template <class F>
  static double sum(int n, const F& f, int /*parallel_min*/ = 0) {
    if (n <= 0) return 0.0;
    ++host_round_trips().reductions;
    double* out = static_cast<double*>(scratch(2, sizeof(double)));
    sum_to(n, f, out);
    return read_back(out);
  }

  /// Sum of f(i) where f also writes memory, into *out (device memory, nothing read back): a
  /// reduction may evaluate an element more than once, so each value goes to scratch first (one
  /// kernel), then a plain sum.
  template <class F>
  static void sum_effects_to(int n, const F& f, double* out, int /*parallel_min*/ = 0) {
    if (n <= 0) {
      check(cudaMemsetAsync(out, 0, sizeof(double)), "cudaMemsetAsync");
      return;
    }
    double* values = static_cast<double*>(scratch(1, sizeof(double) * static_cast<size_t>(n)));
    for_each(n, [=] __host__ __device__(int i) { values[i] = f(i); });
    size_t bytes = 0;
    check(cub::DeviceReduce::Sum(nullptr, bytes, values, out, n), "reduction (size)");
    check(cub::DeviceReduce::Sum(scratch(0, bytes), bytes, values, out, n), "reduction");
  }

  /// sum_effects_to: a GPU's threads take items, not blocks, so the work weights of the CPU's
  /// split (CpuExec::sum_effects_balanced_to) have nothing to balance.
  template <class F, class W>
  static void sum_effects_balanced_to(int n, const F& f, const W& /*work_before*/, double* out, int = 0) {
    sum_effects_to(n, f, out);
  }

  /// Two sums of one loop into *out_a and *out_b, device memory: f(i) returns both terms of i as
  /// a Sum2 and may write memory (each i evaluated exactly once); one kernel writes the terms,
  /// two CUB reductions add them.
  template <class F>
  static void sum2_effects_to(int n, const F& f, double* out_a, double* out_b, int /*parallel_min*/ = 0) {
    if (n <= 0) {
      check(cudaMemsetAsync(out_a, 0, sizeof(double)), "cudaMemsetAsync");
      check(cudaMemsetAsync(out_b, 0, sizeof(double)), "cudaMemsetAsync");
      return;
    }
    double* values = static_cast<double*>(scratch(1, 2 * sizeof(double) * static_cast<size_t>(n)));
    for_each(n, [=] __host__ __device__(int i) {
      const Sum2 s = f(i);
      values[i] = s.a;
      values[n + i] = s.b;
    });
    size_t bytes = 0;
    check(cub::DeviceReduce::Sum(nullptr, bytes, values, out_a, n), "reduction (size)");
    check(cub::DeviceReduce::Sum(scratch(0, bytes), bytes, values, out_a, n), "reduction");
    check(cub::DeviceReduce::Sum(scratch(0, bytes), bytes, values + n, out_b, n), "reduction");
  }

  /// Sum of f(i) where f also writes memory (each i evaluated exactly once), read back.
  template <class F>
  static double sum_effects(int n, const F& f, int /*parallel_min*/ = 0) {
    if (n <= 0) return 0.0;
    ++host_round_trips().reductions;
    double* out = static_cast<double*>(scratch(2, sizeof(double)));
    sum_effects_to(n, f, out);
    return read_back(out);
  }

  /// Maximum of f(i) over [0, n), at least 0 (the solver's maxima are of non-negative values),
  /// into *out, device memory: a CUB reduction queued on this thread's stream, nothing read back.
  template <class F>
  static void max_to(int n, const F& f, double* out, int /*parallel_min*/ = 0) {
    if (n <= 0) {
      check(cudaMemsetAsync(out, 0, sizeof(double)), "cudaMemsetAsync");
      return;
    }
    auto in = thrust::make_transform_iterator(thrust::counting_iterator<int>(0), f);
    size_t bytes = 0;
    check(cub::DeviceReduce::Reduce(nullptr, bytes, in, out, n, thrust::maximum<double>(), 0.0), "reduction (size)");
    check(cub::DeviceReduce::Reduce(scratch(0, bytes), bytes, in, out, n, thrust::maximum<double>(), 0.0), "reduction");
  }

  /// Minimum of f(i) over [0, n) into *out (+infinity for n == 0), device memory, queued.
  template <class F>
  static void min_to(int n, const F& f, double* out, int /*parallel_min*/ = 0) {
    if (n <= 0) {
      for_each(1, [=] __host__ __device__(int) { *out = INFINITY; });
      return;
    }
    auto in = thrust::make_transform_iterator(thrust::counting_iterator<int>(0), f);
    size_t bytes = 0;
    check(cub::DeviceReduce::Reduce(nullptr, bytes, in, out, n, thrust::minimum<double>(), INFINITY), "reduction (size)");
    check(cub::DeviceReduce::Reduce(scratch(0, bytes), bytes, in, out, n, thrust::minimum<double>(), INFINITY),
          "reduction");
  }

  /// max_to, read back.
  template <class F>
  static double max(int n, const F& f, int /*parallel_min*/ = 0) {
    if (n <= 0) return 0.0;
    ++host_round_trips().reductions;
    double* out = static_cast<double*>(scratch(2, sizeof(double)));
    max_to(n, f, out);
    return read_back(out);
  }

  __host__ __device__ static inline void add(double* p, double v) {
#if defined(__CUDA_ARCH__)
    atomicAdd(p, v);
#else
    *p += v;
#endif
  }

  /// A row of the block product (sim/block_row.h), one thread per row.
  __host__ __device__ static inline void block_row(int i, const BlockRows& A, const BlockRows& C, const double* x,
                                                   double* y) {
    block_row_product(i, A, C, x, y);
  }

  /// MAS domains solved together: one, by a warp (sim/solver/mas_dense.h, cholesky_solve_packed).
  static constexpr int kMasLanes = 1;

  /// Adds 1 to *p (other threads may too) and returns the value before; fenced on both sides, so
  /// what the incrementing threads wrote before is visible after it (read through volatile).
  __host__ __device__ static inline int atomic_increment(int* p) {
#if defined(__CUDA_ARCH__)
    __threadfence();
    const int old = atomicAdd(p, 1);
    __threadfence();
    return old;
#else
    return (*p)++;
#endif
  }

  /// Ascending radix sort of the whole vector (CUB, scratch buffers).
  static void sort(Vector<uint64_t>& v) {
    const int n = static_cast<int>(v.size());
    if (n < 2) return;
    uint64_t* keys = ptr(v);
    cub::DoubleBuffer<uint64_t> buf(keys, static_cast<uint64_t*>(scratch(3, sizeof(uint64_t) * n)));
    size_t bytes = 0;
    check(cub::DeviceRadixSort::SortKeys(nullptr, bytes, buf, n), "sort (size)");
    check(cub::DeviceRadixSort::SortKeys(scratch(0, bytes), bytes, buf, n), "sort");
    if (buf.Current() != keys)
      check(cudaMemcpyAsync(keys, buf.Current(), sizeof(uint64_t) * n, cudaMemcpyDeviceToDevice), "sort (copy)");
  }
  /// Exclusive prefix sum of v[0, count) in place (CUB into scratch, copied back).
  template <class T>
  static void exclusive_scan(Vector<T>& v, int count) {
    if (count <= 0) return;
    T* data = ptr(v);
    T* out = static_cast<T*>(scratch(3, sizeof(T) * static_cast<size_t>(count)));
    size_t bytes = 0;
    check(cub::DeviceScan::ExclusiveSum(nullptr, bytes, data, out, count), "scan (size)");
    check(cub::DeviceScan::ExclusiveSum(scratch(0, bytes), bytes, data, out, count), "scan");
    check(cudaMemcpyAsync(data, out, sizeof(T) * static_cast<size_t>(count), cudaMemcpyDeviceToDevice), "scan (copy)");
  }
  template <class T>
  static T read(const Vector<T>& v, size_t i) {
    ++host_round_trips().downloads;
    T h{};
    copy_to_host(&h, ptr(v) + i, sizeof(T));
    return h;
  }

  /// PCG reads its stop flag every this many iterations (Solver::solve_pcg): a stopped solve then
  /// runs at most 7 iterations that change nothing, instead of a round trip per iteration.
  static constexpr int kPcgCheckEvery = 8;
  template <class T>
  static void take(Vector<T>& dst, std::vector<T>& src) { upload(dst, src); }
  /// Waits for this thread's queued work (its stream, not the whole device: other scenes' work
  /// goes on) and reports any asynchronous fault.
  static void sync() { check(cudaStreamSynchronize(cudaStreamPerThread), "a queued kernel"); }
};

}  // namespace gd::sim
