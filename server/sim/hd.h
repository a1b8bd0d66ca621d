#pragma once
/// \file
/// GD_HD marks per-element functions that compile for both the CPU backend and, under nvcc,
/// the CUDA backend (`__host__ __device__`). Write element math once, call it from both loops.

#if defined(__CUDACC__)
#define GD_HD __host__ __device__ __forceinline__
#define GD_HD_LAMBDA __host__ __device__
#define GD_HD_ALWAYS_INLINE __host__ __device__ __forceinline__
#else
#define GD_HD inline
#define GD_HD_LAMBDA
/// GD_HD for a small function on a hot path that the host compiler must inline wherever it is
/// called (a per-pair test in loops over ~100k pairs, where an out-of-line call costs ~10%).
#define GD_HD_ALWAYS_INLINE inline __attribute__((always_inline))
#endif

namespace gd::sim {

/// Two sums taken by one loop (Exec::sum2_effects_to): each iteration returns its two terms.
struct Sum2 {
  double a = 0, b = 0;
  GD_HD Sum2& operator+=(const Sum2& o) {
    a += o.a, b += o.b;
    return *this;
  }
};

}  // namespace gd::sim
