#pragma once
/// \file
/// The narrow interface between a Scene and its backend. The implicit-Euler Newton solver is
/// written once (solver_impl.h) over an execution policy; the CPU backend instantiates it with
/// OpenMP loops, the CUDA backend with kernels. A Scene only sees SolverBase.

#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "sim/contact/collider.h"
#include "sim/solver/options.h"
#include "sim/solver/scene_data.h"

namespace gd::sim {

/// Wall time of each stage of a step, s, summed over its Newton iterations: where a step goes.
struct StageTimes {
  double predictor = 0;      ///< lagged friction frames, Dirichlet targets, predictor and its CCD
  double contacts = 0;       ///< active-pair selection and the candidate search along each Newton step
  double assembly = 0;       ///< gradient and PSD Hessian (and the gradients of the residual checks)
  double couplings = 0;      ///< the contact pairs' off-diagonal blocks merged into a block CSR
  double precond = 0;        ///< PCG's preconditioner setup
  double pcg = 0;            ///< PCG iterations
  double ccd = 0;            ///< step bound: CCD against cloth, table and colliders
  double line_search = 0;    ///< energy evaluations of the backtracking line search
  double intersections = 0;  ///< exact intersecting-pair count after the step
  double untangle = 0;       ///< untangling fail-safe
  double stopping = 0;       ///< Newton's stopping rule: its estimator's setup and solve, the residual
  double total() const {
    return predictor + contacts + assembly + couplings + precond + pcg + ccd + line_search + intersections +
           untangle + stopping;
  }
  StageTimes& operator+=(const StageTimes& o) {
    predictor += o.predictor, contacts += o.contacts, assembly += o.assembly, couplings += o.couplings;
    precond += o.precond, pcg += o.pcg, ccd += o.ccd, line_search += o.line_search;
    intersections += o.intersections, untangle += o.untangle, stopping += o.stopping;
    return *this;
  }
  StageTimes& operator*=(double f) {
    predictor *= f, contacts *= f, assembly *= f, couplings *= f, precond *= f, pcg *= f;
    ccd *= f, line_search *= f, intersections *= f, untangle *= f, stopping *= f;
    return *this;
  }
  /// Each stage in milliseconds, by name (the keys of gd-bench --json and summary.json).
  template <class F>
  void for_each_ms(F&& f) const {
    f("predictor", 1e3 * predictor), f("contacts", 1e3 * contacts), f("assembly", 1e3 * assembly);
    f("couplings", 1e3 * couplings), f("precond", 1e3 * precond), f("pcg", 1e3 * pcg), f("ccd", 1e3 * ccd);
    f("line_search", 1e3 * line_search), f("intersections", 1e3 * intersections), f("untangle", 1e3 * untangle);
    f("stopping", 1e3 * stopping);
  }
};

/// What one step did.
struct StepStats {
  int newton_iters = 0;        ///< Newton iterations taken
  int pcg_iters = 0;           ///< PCG iterations summed over the Newton iterations
  double step_norm = 0;        ///< max |dx|/dt of the last Newton iteration, m/s
  double min_alpha = 1;        ///< smallest accepted line-search step
  bool converged = false;      ///< the residual rule or newton_tol stopped Newton before its cap
  /// Velocity correction the gradient asks for (SceneOptions::newton_rtol) at the first iterate and
  /// at the last one checked, m/s.
  double residual0 = 0, residual = 0;
  int energy_evals = 0;        ///< evaluations of the objective (line search)
  int table_cuts = 0;          ///< Newton iterations whose step took the per-vertex table cut (step_bounds.h)
  bool finite = true;          ///< false when the objective was not finite (the step is void)
  int contacts = 0;            ///< active self-contact pairs (closer than the contact distance)
  /// Smallest distance over the active self-contact pairs at the end of the step, m (infinity
  /// when none): how hard layers are pressed together.
  double min_self_distance = std::numeric_limits<double>::infinity();
  /// Largest pull of a grip spring on a held vertex at the end of the step, N (0 when nothing
  /// is held by a spring; see SceneOptions::grip_force_limit).
  double max_grip_force = 0;
  /// Multiplier of the self-contact barrier stiffness in effect after the step (1 at the start;
  /// doubled when layers get pressed together, up to 1e4; see docs/physics.md).
  double barrier_scale = 1;
  int candidates = 0;          ///< broad-phase candidate pairs
  int intersecting_pairs = 0;  ///< intersecting triangle pairs after the step (and untangling)
  int intersecting_found = 0;  ///< intersecting triangle pairs the solve left (before untangling)
  bool untangled = false;      ///< the untangling fail-safe ran this step
  double broad_phase_seconds = 0;  ///< broad-phase queries (inside the predictor, contacts and intersections stages)
  int broad_phase_queries = 0;     ///< broad-phase queries run (the others reused candidates)
  /// Halvings of motions (the predictor's, Newton steps) whose broad phase would have held more
  /// than the pair budget (SceneOptions::self_contact_pair_budget); 0 in ordinary steps.
  int flood_halvings = 0;
  /// The self-contact pair Hessian this step assembled (SceneOptions::contact_hessian with kAuto
  /// resolved by the colliders the solver had: effective_contact_hessian); kAuto when the scene
  /// has no self-contact.
  ContactHessianKind contact_hessian = ContactHessianKind::kAuto;
  StageTimes stage;            ///< where the step's time went
  double seconds = 0;          ///< wall time of the step
};

/// Energies of the current state, J. Gravity is m g.x relative to z = 0.
struct EnergyReport {
  /// bending includes bending friction's stored spring energy (sim/energy/bending_friction.h)
  double kinetic = 0, stretch = 0, bending = 0, gravity = 0, contact = 0;
  double total() const { return kinetic + stretch + bending + gravity + contact; }
};

/// Dirichlet vertices for one step: their positions at the end of the step.
struct KinematicTargets {
  std::vector<int> vertices;
  std::vector<double> targets;  ///< 3 per vertex
};

class SolverBase {
 public:
  virtual ~SolverBase() = default;
  /// Advances by options.dt. quasi_static: start from rest (v = 0) and carry no momentum, a
  /// proximal step towards static equilibrium.
  virtual StepStats step(const KinematicTargets& kin, bool quasi_static) = 0;
  virtual void get_positions(std::vector<double>& x) = 0;
  virtual void get_velocities(std::vector<double>& v) = 0;
  virtual void set_state(const std::vector<double>& x, const std::vector<double>& v) = 0;
  /// Kinematic colliders for the next step: their poses at the start (t0) and end (t1) of it.
  virtual void set_colliders(const std::vector<Collider>& colliders, double t0, double t1) = 0;
  /// Constant external forces (3 per vertex, N), e.g. a hanging load.
  virtual void set_external_forces(const std::vector<double>& f) = 0;
  virtual EnergyReport energies() = 0;
  /// The contact (barrier) force each collider of the last set_colliders receives from the cloth
  /// at the current positions, colliders at their end-of-step poses: 3 per collider, N, world
  /// frame (the sum over free vertices, and surface samples where the collider is sampled, of the
  /// barrier's gradient; friction not included). What a force-limited gripper finger feels (robot
  /// mode).
  virtual std::vector<double> collider_forces() = 0;
  /// collider_forces' push along each collider's own local z axis (at its end-of-step pose) split
  /// by sign: 4 per collider, {sum of the pushes towards +z (N, >= 0; the free vertices' and, on a
  /// sampled collider, the surface samples'), sum of those towards -z (N, <= 0), vertices pushing
  /// towards +z, vertices pushing towards -z}. For a gripper
  /// pad whose z is its opening direction: the cloth on its inner face against the cloth wrapped
  /// round its outer face (robot mode's timeseries).
  virtual std::vector<double> collider_pushes() = 0;
  /// Per collider of the last set_colliders: the fraction of its motion over the last step that it
  /// made, 1 unless a yielding collider (Collider::set_yielding) stopped short.
  virtual std::vector<double> collider_reached() const = 0;
  /// Largest |stretch strain| (warp or weft) over all triangles.
  virtual double max_strain() = 0;
  /// Bytes of solver state held by the backend (device memory on CUDA).
  virtual size_t bytes() const = 0;
  virtual std::string backend_name() const = 0;
};

std::unique_ptr<SolverBase> make_cpu_solver(std::shared_ptr<const SceneData> data, const SceneOptions& opt);

/// True when the CUDA backend was built and a device is present.
bool cuda_available();
/// The CUDA backend; throws InputError when cuda_available() is false.
std::unique_ptr<SolverBase> make_cuda_solver(std::shared_ptr<const SceneData> data, const SceneOptions& opt);

}  // namespace gd::sim
