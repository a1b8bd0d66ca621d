// Without the CUDA backend compiled in, asking for it is a clear user error.
#include "sim/contact/broad_phase.h"
#include "sim/demand.h"
#include "sim/solver/solver.h"

#if !defined(GD_WITH_CUDA)
namespace gd::sim {

bool cuda_available() { return false; }

std::unique_ptr<SolverBase> make_cuda_solver(std::shared_ptr<const SceneData>, const SceneOptions&) {
  throw InputError("this build has no CUDA backend (configure with -DGD_WITH_CUDA=ON on a machine with nvcc)");
}

std::unique_ptr<BroadPhase> make_cuda_lbvh_broad_phase_unchecked(const std::vector<int>&,
                                                                 const std::vector<Eigen::Vector2i>&, int) {
  throw InputError("this build has no CUDA backend (configure with -DGD_WITH_CUDA=ON on a machine with nvcc)");
}

}  // namespace gd::sim
#endif
