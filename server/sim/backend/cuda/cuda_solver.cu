// The CUDA backend: the shared solver instantiated with kernels. The element functions are the
// same GD_HD functions the CPU backend runs (sim/energy/*.h).
#include <cuda_runtime.h>
#include <thrust/system_error.h>

#include <new>
#include <string>

#include "sim/backend/cuda/exec_cuda.cuh"
#include "sim/contact/lbvh_broad_phase.h"
#include "sim/demand.h"
#include "sim/solver/solver_impl.h"

namespace gd::sim {
namespace {

/// Solver<CudaExec> with thrust's own errors (a failed allocation, copy or algorithm) turned into
/// BackendError like CudaExec's checked launches, so that Scene fails the step of this scene.
class GuardedCudaSolver final : public SolverBase {
 public:
  GuardedCudaSolver(std::shared_ptr<const SceneData> data, const SceneOptions& opt)
      : s_(guarded([&] { return std::make_unique<Solver<CudaExec>>(std::move(data), opt); })) {}

  StepStats step(const KinematicTargets& kin, bool quasi_static) override {
    return guarded([&] { return s_->step(kin, quasi_static); });
  }
  void get_positions(std::vector<double>& x) override { guarded([&] { s_->get_positions(x); }); }
  void get_velocities(std::vector<double>& v) override { guarded([&] { s_->get_velocities(v); }); }
  void set_state(const std::vector<double>& x, const std::vector<double>& v) override {
    guarded([&] { s_->set_state(x, v); });
  }
  void set_colliders(const std::vector<Collider>& colliders, double t0, double t1) override {
    guarded([&] { s_->set_colliders(colliders, t0, t1); });
  }
  void set_external_forces(const std::vector<double>& f) override { guarded([&] { s_->set_external_forces(f); }); }
  EnergyReport energies() override { return guarded([&] { return s_->energies(); }); }
  std::vector<double> collider_forces() override { return guarded([&] { return s_->collider_forces(); }); }
  std::vector<double> collider_pushes() override { return guarded([&] { return s_->collider_pushes(); }); }
  std::vector<double> collider_reached() const override { return s_->collider_reached(); }
  double max_strain() override { return guarded([&] { return s_->max_strain(); }); }
  size_t bytes() const override { return s_->bytes(); }
  std::string backend_name() const override { return s_->backend_name(); }

 private:
  template <class F>
  static auto guarded(F&& f) -> decltype(f()) {
    try {
      return f();
    } catch (const thrust::system_error& e) {
      throw BackendError(std::string("CUDA backend: ") + e.what());
    } catch (const std::bad_alloc&) {
      throw BackendError("CUDA backend: out of memory");
    }
  }
  std::unique_ptr<Solver<CudaExec>> s_;
};

}  // namespace

bool cuda_available() {
  int count = 0;
  return cudaGetDeviceCount(&count) == cudaSuccess && count > 0;
}

/// The LBVH broad phase on the device (contact/lbvh_broad_phase.h), thrust's errors turned into
/// BackendError.
std::unique_ptr<BroadPhase> make_cuda_lbvh_broad_phase_unchecked(const std::vector<int>& tris,
                                                                 const std::vector<Eigen::Vector2i>& edges,
                                                                 int vertex_count) {
  try {
    return std::make_unique<LbvhBroadPhase<CudaExec>>(tris, edges, vertex_count);
  } catch (const thrust::system_error& e) {
    throw BackendError(std::string("CUDA broad phase: ") + e.what());
  }
}

std::unique_ptr<SolverBase> make_cuda_solver(std::shared_ptr<const SceneData> data, const SceneOptions& opt) {
  if (!cuda_available()) throw InputError("no CUDA device is available; use backend=cpu (or auto)");
  return std::make_unique<GuardedCudaSolver>(std::move(data), opt);
}

}  // namespace gd::sim
