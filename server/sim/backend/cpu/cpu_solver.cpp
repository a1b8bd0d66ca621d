// The CPU backend: the shared solver instantiated with OpenMP loops (and, for tests of the CUDA
// backend's code paths, with its atomic variant).
#include "sim/backend/cpu/exec_cpu.h"
#include "sim/solver/solver_impl.h"

namespace gd::sim {

template class Solver<CpuExec>;          // the instances solver_impl.h declares extern
template class Solver<CpuGpuPathsExec>;

std::unique_ptr<SolverBase> make_cpu_solver(std::shared_ptr<const SceneData> data, const SceneOptions& opt) {
  if (opt.backend == BackendKind::kCpuGpuPaths) return std::make_unique<Solver<CpuGpuPathsExec>>(std::move(data), opt);
  return std::make_unique<Solver<CpuExec>>(std::move(data), opt);
}

}  // namespace gd::sim
