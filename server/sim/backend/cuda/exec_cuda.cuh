#pragma once
/// \file
/// The CUDA execution policy of the shared solver: device vectors, one kernel per loop,
/// thrust reductions, and atomic adds for element scatter (no colouring needed on the GPU).

#include <cub/device/device_reduce.cuh>
#include <thrust/device_vector.h>
#include <thrust/execution_policy.h>
#include <thrust/fill.h>
#include <thrust/functional.h>
#include <thrust/reduce.h>
#include <thrust/iterator/counting_iterator.h>
#include <thrust/iterator/transform_iterator.h>
#include <thrust/scan.h>
#include <thrust/sort.h>
#include <thrust/transform_reduce.h>

#include <cstdint>
#include <vector>

#include "sim/backend/round_trips.h"

namespace gd::sim {

template <class F>
__global__ void gd_for_each_kernel(int n, F f) {
  const int i = blockIdx.x * blockDim.x + threadIdx.x;
  if (i < n) f(i);
}

struct CudaExec {
  static constexpr const char* kName = "cuda";
  static constexpr bool kColoring = false;
  static constexpr bool kHostMemory = false;  ///< device vectors: host-side stages copy them

  template <class T>
  using Vector = thrust::device_vector<T>;

  template <class T>
  static T* ptr(Vector<T>& v) { return thrust::raw_pointer_cast(v.data()); }
  template <class T>
  static const T* ptr(const Vector<T>& v) { return thrust::raw_pointer_cast(v.data()); }
  template <class T>
  static void upload(Vector<T>& dst, const std::vector<T>& src) { dst.assign(src.begin(), src.end()); }
  template <class T>
  static void download(std::vector<T>& dst, const Vector<T>& src) {
    ++host_round_trips().downloads;
    dst.resize(src.size());
    thrust::copy(src.begin(), src.end(), dst.begin());
  }
  template <class T>
  static void resize(Vector<T>& v, size_t n) { v.assign(n, T{}); }
  template <class T>
  static void fill(Vector<T>& v, T value) { thrust::fill(v.begin(), v.end(), value); }

  static constexpr int kParallelMin = 0;
  static constexpr int kParallelMinHeavy = 0;

  template <class F>
  static void for_each(int n, const F& f, int /*parallel_min*/ = 0) {
    if (n <= 0) return;
    constexpr int kBlock = 256;
    gd_for_each_kernel<<<(n + kBlock - 1) / kBlock, kBlock>>>(n, f);
  }

  template <class F>
  static double sum(int n, const F& f, int /*parallel_min*/ = 0) {
    if (n <= 0) return 0.0;
    ++host_round_trips().reductions;
    return thrust::transform_reduce(thrust::device, thrust::counting_iterator<int>(0), thrust::counting_iterator<int>(n),
                                    f, 0.0, thrust::plus<double>());
  }

  /// Sum of f(i) where f also writes memory: thrust's reductions may evaluate an element more
  /// than once, so each value goes to a buffer first (one kernel), then a plain reduction.
  template <class F>
  static double sum_effects(int n, const F& f, int /*parallel_min*/ = 0) {
    if (n <= 0) return 0.0;
    ++host_round_trips().reductions;
    thrust::device_vector<double> values(n);
    double* out = thrust::raw_pointer_cast(values.data());
    for_each(n, [=] __host__ __device__(int i) { out[i] = f(i); });
    return thrust::reduce(thrust::device, values.begin(), values.end(), 0.0);
  }

  template <class F>
  static double max(int n, const F& f, int /*parallel_min*/ = 0) {
    if (n <= 0) return 0.0;
    ++host_round_trips().reductions;
    return thrust::transform_reduce(thrust::device, thrust::counting_iterator<int>(0), thrust::counting_iterator<int>(n),
                                    f, 0.0, thrust::maximum<double>());
  }

  __host__ __device__ static inline void add(double* p, double v) {
#if defined(__CUDA_ARCH__)
    atomicAdd(p, v);
#else
    *p += v;
#endif
  }

  static void sort(Vector<uint64_t>& v) { thrust::sort(thrust::device, v.begin(), v.end()); }
  template <class T>
  static void exclusive_scan(Vector<T>& v, int count) {
    thrust::exclusive_scan(thrust::device, v.begin(), v.begin() + count, v.begin());
  }
  template <class T>
  static T read(const Vector<T>& v, size_t i) {
    ++host_round_trips().downloads;
    return v[i];
  }

  /// Sum of f(i) over [0, n) into *out, device memory: a CUB reduction queued on the stream, no
  /// value returns to the host. Its scratch memory is kept per thread and only grows.
  template <class F>
  static void sum_to(int n, const F& f, double* out, int /*parallel_min*/ = 0) {
    if (n <= 0) {
      cudaMemsetAsync(out, 0, sizeof(double));
      return;
    }
    auto in = thrust::make_transform_iterator(thrust::counting_iterator<int>(0), f);
    size_t bytes = 0;
    cub::DeviceReduce::Sum(nullptr, bytes, in, out, n);
    cub::DeviceReduce::Sum(scratch(bytes), bytes, in, out, n);
  }
  /// Device scratch of at least `bytes`, this thread's (kept until the process ends).
  static void* scratch(size_t bytes) {
    thread_local void* buffer = nullptr;
    thread_local size_t capacity = 0;
    if (bytes > capacity) {
      if (buffer) cudaFree(buffer);
      capacity = bytes + bytes / 2 + 256;
      if (cudaMalloc(&buffer, capacity) != cudaSuccess) buffer = nullptr, capacity = 0;
    }
    return buffer;
  }
  /// PCG reads its stop flag every this many iterations (Solver::solve_pcg): a stopped solve then
  /// runs at most 7 iterations that change nothing, instead of a round trip per iteration.
  static constexpr int kPcgCheckEvery = 8;
  template <class T>
  static void take(Vector<T>& dst, std::vector<T>& src) { upload(dst, src); }
  static void sync() { cudaDeviceSynchronize(); }
};

}  // namespace gd::sim
