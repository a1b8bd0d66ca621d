#pragma once
/// \file
/// The OpenMP thread count, in one place: the CPU backend's loops, the broad phase, the pair
/// merges and the scene pool ask here rather than calling omp_* themselves. Without OpenMP (the
/// ThreadSanitizer build, cmake/GdOpenMP.cmake: Debian's libgomp is not instrumented, so TSan
/// cannot see its barriers) every loop runs on the calling thread and these report one thread.

#ifdef _OPENMP
#include <omp.h>
#endif

namespace gd {

/// Threads a parallel region started now would get (omp_get_max_threads; 1 without OpenMP).
inline int omp_threads() {
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

/// The calling thread's number in its parallel region (omp_get_thread_num; 0 without OpenMP).
inline int omp_thread() {
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}

/// Threads in the calling thread's parallel region (omp_get_num_threads; 1 outside one and
/// without OpenMP).
inline int omp_team_size() {
#ifdef _OPENMP
  return omp_get_num_threads();
#else
  return 1;
#endif
}

/// Sets the calling thread's team size for later parallel regions (omp_set_num_threads; nothing
/// without OpenMP).
inline void set_omp_threads(int n) {
#ifdef _OPENMP
  omp_set_num_threads(n);
#else
  (void)n;
#endif
}

}  // namespace gd
