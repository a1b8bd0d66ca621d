// The CUDA backend: the shared solver instantiated with kernels. The element functions are the
// same GD_HD functions the CPU backend runs (sim/energy/*.h).
#include <cuda_runtime.h>

#include "sim/backend/cuda/exec_cuda.cuh"
#include "sim/demand.h"
#include "sim/solver/solver_impl.h"

namespace gd::sim {

bool cuda_available() {
  int count = 0;
  return cudaGetDeviceCount(&count) == cudaSuccess && count > 0;
}

std::unique_ptr<SolverBase> make_cuda_solver(std::shared_ptr<const SceneData> data, const SceneOptions& opt) {
  if (!cuda_available()) throw InputError("no CUDA device is available; use backend=cpu (or auto)");
  return std::make_unique<Solver<CudaExec>>(std::move(data), opt);
}

}  // namespace gd::sim
