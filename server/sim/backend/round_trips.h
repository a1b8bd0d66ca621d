#pragma once
/// \file
/// Blocking round trips from a backend's memory to the host: what a GPU stalls on (a reduction
/// whose value the host reads, a device-to-host copy). CudaExec and CpuGpuPathsExec count them
/// per calling thread (a scene steps on one thread), so CPU tests can hold the solver to a budget
/// (tests/sim/backend/round_trips_test.cpp). CpuExec counts nothing: on the CPU they cost nothing.

namespace gd::sim {

struct HostRoundTrips {
  long reductions = 0;  ///< sums and maxima whose value returned to the host
  long downloads = 0;   ///< device-to-host copies and single-element reads
  long total() const { return reductions + downloads; }
};

/// This thread's counts since it started (compare before and after).
HostRoundTrips& host_round_trips();

}  // namespace gd::sim
