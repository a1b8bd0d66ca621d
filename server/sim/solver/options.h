#pragma once
/// \file
/// Options of a scene: time step, solver tolerances, backend, table contact, drag and damping.
/// Every field has a default a user of a robotics simulator can start from.

#include <algorithm>
#include <cmath>
#include <string>

#include "sim/types.h"

namespace gd::sim {

/// kCpuGpuPaths: the CPU running the CUDA backend's code paths (uncoloured element loops, atomic
/// adds; backend/cpu/exec_cpu.h), for tests of those paths where no GPU is.
enum class BackendKind { kCpu, kCuda, kAuto, kCpuGpuPaths };
enum class LinearSolverKind {
  kPcg,     ///< preconditioned conjugate gradients (both backends; the production path)
  kDirect,  ///< sparse LDLT (CPU only): for small scenes and static validation solves
};
enum class PreconditionerKind {
  kAuto,         ///< MAS without self-contact, block-Jacobi with it (docs/physics.md, "Solver")
  kBlockJacobi,  ///< inverse 3x3 diagonal blocks: cheapest per iteration, weakest
  kMas,          ///< multilevel additive Schwarz (Wu et al. 2022; mas_preconditioner.h)
};
/// How the bending Hessian is made positive semi-definite for Newton.
enum class BendingHessianKind {
  kGaussNewton,    ///< E''(theta) grad(theta) grad(theta)^T: cheap, the default for dynamics
  kProjectedExact  ///< the exact Hessian with negative eigenvalues clamped: faster Newton
                   ///< convergence at large rotations (static solves, validation)
};

/// Which broad phase finds self-contact candidates (contact/broad_phase.h); both report the same
/// pairs.
enum class BroadPhaseKind {
  kAuto,    ///< the default: the LBVH, on the CPU policy for the CPU backends and on the device with
            ///< CUDA (fold steps 1.1-1.35x faster than with Embree on the host, H200; on 2 CPU threads
            ///< its broad phase takes about half Embree's time, docs/physics.md)
  kEmbree,  ///< Embree's BVH collide on the CPU (the CPU default until 2026-11-27)
  kLbvh     ///< the policy-generic LBVH (contact/lbvh.h, Karras 2012), the GPU's algorithm (on the
            ///< CPU with the CPU backends, on the device with CUDA)
};

/// How the self-contact barrier Hessians are made positive semi-definite for Newton.
enum class ContactHessianKind {
  kGaussNewton,  ///< curvature along the distance gradient only: PSD by construction, cheaper per pair
                 ///< but weaker (more Newton/PCG iterations in motion; leaves more for untangling)
  kProjected,    ///< the exact 12x12 Hessian with negative eigenvalues clamped (a <= 5x5 eigen-solve)
  kTermwise,     ///< b''∇d∇dᵀ plus the PSD part of b'∇²d, each term projected on its own in closed
                 ///< form: the projected Hessian's Newton counts on free cloth-cloth contact at about
                 ///< the Gauss-Newton one's cost, but weaker where kinematic colliders press layers
                 ///< together (docs/physics.md, "Contact Hessian term by term")
  kAuto,         ///< the default: kTermwise while the scene has no colliders, kProjected with them
};

/// Smallest time step a scene takes, s: below it a step no longer advances the clock in any
/// useful way (at 1e-300 s the time stayed 0 while steps counted up).
inline constexpr double kMinDt = 1e-6;

struct SceneOptions {
  // --- time stepping and solver ---------------------------------------------------------
  Real dt = 1.0 / 200.0;          ///< time step, s, in [kMinDt, 1]
  Vec3 gravity = Vec3(0, 0, -kGravity);  ///< m/s^2
  int newton_max_iters = 8;       ///< inexact Newton iterations per step (at most)
  /// The cap instead, where it is higher, in a step with a yielding collider that has friction
  /// (a gripper's finger pad): cloth held in a pinch by friction slips out of it when the pinch's
  /// steps end unconverged (a T-shirt lifted by its shoulders lost both hands at 8 and held at 30,
  /// a towel's fling dropped it at 30 and held at 80; every step of those runs converged within
  /// 80: docs/robot.md, "Converged pinches"). Steps that converge sooner cost nothing more.
  int grip_newton_max_iters = 80;
  Real newton_tol = 1e-4;         ///< stop when max |dx|/dt (m/s) falls below this
  /// Residual stopping rule (docs/physics.md, "Solver"), in velocity units: Newton stops once the
  /// correction still to come is at most max(newton_atol, newton_rtol x the first Newton step),
  /// each measured as a mass-weighted RMS velocity over the free vertices, |d|_M / (h sqrt(M)):
  /// after an iteration, the step it took (unless the line search cut it below half its
  /// direction); before iteration k >= 1, the next step predicted by
  /// one MAS apply on the gradient (P⁻¹g, no assembly or solve); before the first, an upper bound
  /// of the step the gradient asks for (h |g|_M⁻¹ / sqrt(M)): a step whose predictor is already
  /// within newton_atol takes no Newton iteration. A self-contact pair pressed below 10 CCD floors
  /// keeps Newton going. Both 0: off (only newton_tol stops Newton). Dynamic steps only:
  /// quasi-static steps (Scene::relax) always run to newton_tol.
  Real newton_rtol = 0.03;
  Real newton_atol = 1e-3;        ///< m/s
  /// The residual rule's test also over the cloth pinched between a hand's pads alone (a yield
  /// group's two colliders; the vertices Solver's predictor carries with them), as a mass-weighted
  /// RMS over those vertices against the same threshold. Over the whole garment a few pinched
  /// vertices weigh little: steps stopped with the pinch's friction unbalanced, a correction of
  /// centimetres per second still to come there, and over a lift the pinch walked out between
  /// the pads (a dress lost both hands at 10 N; held with newton_rtol ten times tighter:
  /// docs/robot.md, "The pinch's own stopping test"). No effect without such a hand.
  bool pinch_stopping_rule = true;
  /// Where CCD cuts the predictor's guess back and cloth is pinched between a hand's pads, the
  /// pinched vertices go their carried way first and the rest of the cloth after, each leg cut
  /// back on its own (Solver's guess_pinch_first): cut back as one motion, contacts anywhere in
  /// the garment held the pinch back while the pads went on (docs/robot.md, "A guess that carries
  /// the pinch first"). Needs pinch_stopping_rule (which finds the pinch); no effect without a hand.
  bool pinch_first_guess = true;
  /// Pads in the solve: where the predictor stopped a hand's pads short of their poses
  /// (yielding colliders), Newton's iterations carry them on along their paths, each hand one
  /// degree of freedom (how far along its step it got) pulled to the step's end by a spring of this
  /// stiffness (N/m) and pushed back by the cloth's barrier and friction: a hand is held back by
  /// the force the cloth resists with, not stopped by where the predictor's guess could go
  /// (docs/robot.md, "Pads in the solve"). 0: off (the pads stay where the predictor stopped them).
  /// Robot mode's scenes set it from tasks::RobotOptions::pad_stiffness (3e5 unless given).
  Real pad_stiffness = 0;
  /// Points sampled over the cloth's triangles, half the thinnest yielding collider's thickness
  /// apart, held out of the yielding colliders (gripper pads) as the vertices are: without them
  /// a pad thinner than the cloth's edges are long passed between the vertices and stood in the
  /// sheet, threaded (contact/surface_samples.h; docs/robot.md, "Pads that cut through the cloth").
  /// On by default (robot mode's scenes take it from tasks::RobotOptions::pad_samples); off, a
  /// pad cuts through coarse cloth between its vertices.
  bool pad_samples = true;
  /// PCG iteration cap per Newton iteration; 0 (the default): max(50, sqrt(n) / 2.5) for n vertices
  /// (effective_pcg_max_iters). Block-Jacobi PCG (self-contact's default) reaches the cap in most
  /// Newton iterations after a step's first, and past ~50 iterations at 5-20k vertices its slow
  /// tail costs more than the Newton iteration it saves; the iterations it needs grow as the mesh
  /// refines (uncapped, 92 per Newton iteration at fold/5000 and 161 at fold/20000), and so does
  /// the cap (docs/physics.md, "Fifty-first round", "Fifty-second round"). MAS solves stop well
  /// before it.
  int pcg_max_iters = 0;
  Real pcg_tol = 1e-2;            ///< PCG relative residual tolerance (inexact Newton)
  /// With MAS in a dynamic step under the residual rule, PCG also stops once its estimate of the
  /// correction still to come (P⁻¹r as a mass-weighted RMS velocity) is at most this fraction of
  /// what the Newton rule accepts, max(newton_atol, newton_rtol x the first step): the linear
  /// solve made no more exact than the Newton iteration asks for (docs/physics.md, "PCG stops
  /// with Newton"). 0: off (pcg_tol and pcg_max_iters alone).
  Real pcg_newton_fraction = 0.1;
  LinearSolverKind linear_solver = LinearSolverKind::kPcg;
  PreconditionerKind preconditioner = PreconditionerKind::kAuto;
  int mas_domain_size = 16;       ///< MAS: nodes per domain (2..64)
  BendingHessianKind bending_hessian = BendingHessianKind::kGaussNewton;
  BackendKind backend = BackendKind::kCpu;
  int threads = 0;                ///< CPU threads (0: OpenMP default)
  /// Assembly whose sums do not depend on thread timing on the atomic backends (CUDA,
  /// cpu-gpu-paths): element loops colour by colour (single-element colours) instead of atomic
  /// adds, and the self-contact pairs' adds sorted by vertex and added in pair order. With it a
  /// scene reset by seed takes the same steps bit for bit on the GPU too (the reductions are CUB's
  /// fixed-order trees). Costs a launch per colour and a sort per evaluation. The CPU backend is
  /// deterministic either way (chunk colouring, fixed-block sums).
  bool deterministic = false;

  // --- rest shape -----------------------------------------------------------------------
  /// Use the mesh's pattern coordinates (UVs) for the rest shape when present; otherwise the
  /// initial 3D shape (hinge rest angles then come from the initial shape too).
  bool rest_from_uv = true;

  // --- membrane -------------------------------------------------------------------------
  /// Compressive / tensile stretch stiffness, in (0, 1] (energy/stretch_shear.h). Fabric buckles
  /// into wrinkles much smaller than a triangle under the slightest compression, so it carries
  /// almost no compressive force; with the full stiffness a coarse mesh holds curved cloth up like
  /// a shell (a folded T-shirt stood 15 cm tall at ~400 vertices). 1: the symmetric model of the
  /// paper (the default: at 0.1 the T-shirt and dress folds lie flat but the cake skirt's gathered
  /// tiers give way in plane; docs/physics.md). Commercial cloth tools call it "buckling ratio".
  Real compression_ratio = 1;

  // --- table (plane z = table_height) --------------------------------------------------
  bool table = true;
  Real table_height = 0.0;        ///< m
  Real table_friction = 0.266;    ///< Coulomb coefficient (RGBench's fitted ground friction)
  /// While cloth lands, a Newton step limited by the table's CCD bound may instead cut each
  /// vertex's motion towards the table to 90% of its own height, when that lets the step go at
  /// least twice as far and Armijo accepts it at once (solver/step_bounds.h, table_cut_step;
  /// docs/physics.md, "Landing steps"). false: the whole step scaled by the most constrained vertex.
  bool table_cut = true;
  Real contact_distance = 0.0;    ///< barrier activation distance dhat, m (0: max(thickness, 1 mm))
  Real friction_eps_v = 1e-3;     ///< m/s: below this slip speed friction is smoothed (static regime)

  // --- cloth self-contact ---------------------------------------------------------------
  /// Vertex-face and edge-edge barriers between cloth triangles, broad phase (broad_phase), CCD,
  /// lagged cloth-cloth friction, intersection count and untangling. Off by default while the
  /// contact work is in progress (docs/physics.md).
  bool self_contact = false;
  Real self_friction = -1;         ///< cloth-cloth Coulomb coefficient (< 0: the material's)
  bool check_intersections = true; ///< exact intersecting-pair count after every step
  bool untangle = true;            ///< run the untangling fail-safe when intersections are found
  ContactHessianKind contact_hessian = ContactHessianKind::kAuto;
  BroadPhaseKind broad_phase = BroadPhaseKind::kAuto;
  /// The most pairs one self-contact broad-phase query may hold (0: SelfContact's default, 200
  /// per vertex and at least 100,000). A motion whose query would hold more (a wild Newton
  /// direction sweeping boxes across the garment) is halved until it fits
  /// (Solver::find_candidates); ordinary steps stay far below it.
  std::size_t self_contact_pair_budget = 0;
  /// With self-contact, grasped (kinematic) vertices stay in the solve, pulled to their targets by
  /// a spring of stiffness grip_stiffness * (m / dt^2 + k_membrane) per vertex (m its mass,
  /// k_membrane the fabric's largest stretch stiffness, N/m): stiff enough that a held vertex
  /// tracks its target to a small fraction of the cloth's own deformation, soft enough that a
  /// gripper pulling cloth into cloth cannot overpower the contact barrier (at 1e3 a fast lift
  /// squeezed gaps to 1e-8 m, stalled CCD and tangled the coat; at 30 the coat, hoodie and dress
  /// grasps run clean, docs/physics.md).
  Real grip_stiffness = 30;
  /// N: the most a grip spring pulls on one held vertex; beyond it the pull stays constant (the
  /// grip stalls rather than squeezing cloth into the table or through other cloth with a
  /// thousand newtons). Infinity: no limit. The default is far above what holding a garment
  /// takes (at most 10 N per held vertex in our 400-vertex tasks, bar one 63 N step; docs/physics.md).
  Real grip_force_limit = 100;

  // --- air drag ---------------------------------------------------------------------------
  Real air_density = 1.2;         ///< kg/m^3
  Real drag_coefficient = 1.0;    ///< normal pressure drag coefficient C_d of a flat plate
  Real drag_linear = 0.0;         ///< extra linear normal drag, kg/(m^2 s)
  Real drag_tangent_ratio = 0.1;  ///< tangential drag as a fraction of the normal coefficient

  // --- damping --------------------------------------------------------------------------
  Real membrane_damping = 1e-4;   ///< strain-rate damping of stretch/shear, s
  Real bending_damping = 1e-3;    ///< curvature-rate damping of bending, s
  Real mass_damping = 0.0;        ///< mass-proportional damping, 1/s (damps rigid motion too)

  /// Throws InputError naming the offending option.
  void validate() const;
};

/// PCG's iteration cap in a scene of n vertices (SceneOptions::pcg_max_iters, 0 resolved).
inline int effective_pcg_max_iters(const SceneOptions& o, int n) {
  if (o.pcg_max_iters > 0) return o.pcg_max_iters;
  return std::max(50, static_cast<int>(std::ceil(std::sqrt(static_cast<double>(n)) / 2.5)));
}

/// The preconditioner a scene with these options uses (kAuto resolved).
inline PreconditionerKind effective_preconditioner(const SceneOptions& o) {
  if (o.preconditioner != PreconditionerKind::kAuto) return o.preconditioner;
  return o.self_contact ? PreconditionerKind::kBlockJacobi : PreconditionerKind::kMas;
}

/// "mas" or "block-jacobi": the preconditioner these options give (summary.json, logs).
inline const char* preconditioner_name(const SceneOptions& o) {
  return effective_preconditioner(o) == PreconditionerKind::kMas ? "mas" : "block-jacobi";
}

/// "lbvh" or "embree": the self-contact broad phase these options give (kAuto resolved;
/// summary.json).
inline const char* broad_phase_name(const SceneOptions& o) {
  return o.broad_phase == BroadPhaseKind::kEmbree ? "embree" : "lbvh";
}

/// "auto", "termwise", "projected" or "gauss-newton": a contact Hessian kind's name (command
/// lines, summary.json).
inline const char* contact_hessian_name(ContactHessianKind k) {
  switch (k) {
    case ContactHessianKind::kGaussNewton: return "gauss-newton";
    case ContactHessianKind::kProjected: return "projected";
    case ContactHessianKind::kTermwise: return "termwise";
    default: return "auto";
  }
}

/// The kind named by contact_hessian_name into *k; false for any other name.
inline bool contact_hessian_from_name(const std::string& name, ContactHessianKind* k) {
  for (const ContactHessianKind c : {ContactHessianKind::kAuto, ContactHessianKind::kTermwise,
                                     ContactHessianKind::kProjected, ContactHessianKind::kGaussNewton}) {
    if (name == contact_hessian_name(c)) {
      *k = c;
      return true;
    }
  }
  return false;
}

/// The self-contact Hessian a scene's solver assembles (kAuto resolved): with colliders in the
/// scene (robot fingers, user-defined kinematic bodies) the exact projection, whose Newton model
/// keeps a stack that a pad pushes through space apart, where the termwise one let it cross
/// (tests/sim/solver/yielding_collider_test.cpp); without them the termwise one.
inline ContactHessianKind effective_contact_hessian(const SceneOptions& o, bool colliders) {
  if (o.contact_hessian != ContactHessianKind::kAuto) return o.contact_hessian;
  return colliders ? ContactHessianKind::kProjected : ContactHessianKind::kTermwise;
}

/// The barrier activation distance a scene uses: options.contact_distance, or else the cloth's
/// thickness, at least 1 mm.
inline Real effective_contact_distance(const SceneOptions& o, Real thickness) {
  return o.contact_distance > 0 ? o.contact_distance : (thickness > Real(1e-3) ? thickness : Real(1e-3));
}

}  // namespace gd::sim
