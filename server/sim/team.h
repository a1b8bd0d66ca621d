#pragma once
/// \file
/// Teams: the threads that share one work item of Exec::for_each_team. Code written against a
/// team reads as serial code: `range(lo, hi, g)` runs g(i) for every i in [lo, hi), split over
/// the team's lanes, and returns once every lane is done (what one lane wrote, every lane then
/// sees); `single(g)` runs g once; `dot(a, b, n)` gives every lane the same dot product and
/// `reduce_or(lo, hi, f)` the bitwise or of f(i) over [lo, hi). The iterations of one range must
/// be independent of each other. `kLanes` is the team's width, for code that splits its work
/// more finely where lanes would otherwise idle.
///
/// Three teams, one per execution policy, with the same interface:
/// - SerialTeam (CpuExec): the calling thread alone; a range is a plain loop and `dot` is
///   mas_detail's four-sum order, so a team function does exactly the arithmetic of the serial
///   loop it replaced.
/// - WarpTeam (CudaExec): one warp of 32 lanes; lane l runs i = lo + l, lo + l + 32, ... and the
///   lanes meet at __syncwarp(); `dot` adds per-lane partial sums with a butterfly of shuffles.
/// - WarpOrderTeam (CpuGpuPathsExec): the warp's decomposition replayed on one CPU thread, lanes
///   in reverse order and `dot` in the warp's order of additions, so that the CPU tests run the
///   GPU's arithmetic and catch a range whose iterations are not independent.

#include <cmath>
#include <cstdint>

#include "sim/hd.h"

namespace gd::sim {

/// Dot product of a[0, n) and b[0, n) with four partial sums (one running sum is bound by the
/// latency of its adds, not by the multiplies); a in double or single precision.
template <class A>
GD_HD double dot4(const A* __restrict__ a, const double* __restrict__ b, int n) {
  double t0 = 0, t1 = 0, t2 = 0, t3 = 0;
  int k = 0;
  for (; k + 4 <= n; k += 4) {
    t0 += a[k] * b[k];
    t1 += a[k + 1] * b[k + 1];
    t2 += a[k + 2] * b[k + 2];
    t3 += a[k + 3] * b[k + 3];
  }
  for (; k < n; ++k) t0 += a[k] * b[k];
  return (t0 + t1) + (t2 + t3);
}

/// The calling thread as a team of one (CpuExec).
struct SerialTeam {
  static constexpr int kLanes = 1;
  template <class G>
  GD_HD void range(int lo, int hi, const G& g) const {
    for (int i = lo; i < hi; ++i) g(i);
  }
  template <class G>
  GD_HD void single(const G& g) const { g(); }
  template <class A>
  GD_HD double dot(const A* a, const double* b, int n) const { return dot4(a, b, n); }
  template <class F>
  GD_HD uint64_t reduce_or(int lo, int hi, const F& f) const {
    uint64_t m = 0;
    for (int i = lo; i < hi; ++i) m |= f(i);
    return m;
  }
};

inline constexpr int kWarpLanes = 32;

/// One warp (CudaExec). Host code never runs it (the host pass of nvcc compiles it only); its
/// host branch is SerialTeam's.
struct WarpTeam {
  static constexpr int kLanes = kWarpLanes;
  template <class G>
  GD_HD void range(int lo, int hi, const G& g) const {
#if defined(__CUDA_ARCH__)
    for (int i = lo + static_cast<int>(threadIdx.x % kWarpLanes); i < hi; i += kWarpLanes) g(i);
    __syncwarp();
#else
    for (int i = lo; i < hi; ++i) g(i);
#endif
  }
  template <class G>
  GD_HD void single(const G& g) const {
#if defined(__CUDA_ARCH__)
    if (threadIdx.x % kWarpLanes == 0) g();
    __syncwarp();
#else
    g();
#endif
  }
  /// Every lane gets the same bits: a butterfly adds t_l + t_(l^o) on lane l and t_(l^o) + t_l
  /// on its partner, equal sums.
  template <class A>
  GD_HD double dot(const A* a, const double* b, int n) const {
#if defined(__CUDA_ARCH__)
    double t = 0;
    for (int k = static_cast<int>(threadIdx.x % kWarpLanes); k < n; k += kWarpLanes) t += a[k] * b[k];
    for (int o = kWarpLanes / 2; o > 0; o /= 2) t += __shfl_xor_sync(0xffffffffu, t, o);
    return t;
#else
    return dot4(a, b, n);
#endif
  }
  template <class F>
  GD_HD uint64_t reduce_or(int lo, int hi, const F& f) const {
    uint64_t m = 0;
#if defined(__CUDA_ARCH__)
    for (int i = lo + static_cast<int>(threadIdx.x % kWarpLanes); i < hi; i += kWarpLanes) m |= f(i);
    for (int o = kWarpLanes / 2; o > 0; o /= 2) m |= __shfl_xor_sync(0xffffffffu, m, o);
#else
    for (int i = lo; i < hi; ++i) m |= f(i);
#endif
    return m;
  }
};

/// WarpTeam's lanes replayed on one CPU thread (CpuGpuPathsExec).
struct WarpOrderTeam {
  static constexpr int kLanes = kWarpLanes;
  template <class G>
  GD_HD void range(int lo, int hi, const G& g) const {
    for (int lane = kWarpLanes - 1; lane >= 0; --lane)
      for (int i = lo + lane; i < hi; i += kWarpLanes) g(i);
  }
  template <class G>
  GD_HD void single(const G& g) const { g(); }
  template <class A>
  GD_HD double dot(const A* a, const double* b, int n) const {
    double t[kWarpLanes];
    for (int lane = 0; lane < kWarpLanes; ++lane) {
      t[lane] = 0;
      for (int k = lane; k < n; k += kWarpLanes) t[lane] += a[k] * b[k];
    }
    // Lane 0's sums of the butterfly (every lane ends with the same bits): at each stage it adds
    // the value lane o held after the stage before, so the lanes below o are all it needs.
    for (int o = kWarpLanes / 2; o > 0; o /= 2)
      for (int lane = 0; lane < o; ++lane) t[lane] += t[lane + o];
    return t[0];
  }
  template <class F>
  GD_HD uint64_t reduce_or(int lo, int hi, const F& f) const {
    uint64_t m = 0;
    for (int lane = kWarpLanes - 1; lane >= 0; --lane)
      for (int i = lo + lane; i < hi; i += kWarpLanes) m |= f(i);
    return m;
  }
};

}  // namespace gd::sim
