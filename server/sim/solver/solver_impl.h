#pragma once
/// \file
/// The implicit-Euler solver, written once over an execution policy `Exec` (CpuExec: OpenMP,
/// CudaExec: kernels). One step minimises
///   L(x) = 1/(2h^2)|x - x_hat|_M^2 + E_membrane + E_bend + E_gravity + E_table + E_friction
///          + D_drag + D_damping
/// with a few inexact Newton iterations: assemble the gradient and PSD-projected Hessian, solve
/// with PCG (MAS or block-Jacobi, SceneOptions::preconditioner), cap the step so no vertex reaches the table (CCD on a plane), and
/// backtrack until L decreases. Dirichlet (kinematic) vertices are set to their targets and
/// removed from the solve. Included only by the backend translation units.

#include <Eigen/SparseCholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <type_traits>

#include "sim/energy/bending.h"
#include "sim/energy/damping.h"
#include "sim/energy/drag.h"
#include "sim/energy/gravity.h"
#include "sim/energy/grip_spring.h"
#include "sim/energy/inertia.h"
#include "sim/energy/mass_damping.h"
#include "sim/energy/psd_project.h"
#include "sim/energy/stretch_shear.h"
#include "sim/energy/table_barrier.h"
#include "sim/energy/table_friction.h"
#include "sim/contact/barrier.h"
#include "sim/contact/ccd.h"
#include "sim/contact/collider.h"
#include "sim/contact/friction.h"
#include "sim/solver/pair_blocks.h"
#include "sim/solver/preconditioner.h"
#include "sim/solver/self_contact.h"
#include "sim/solver/solver.h"
#include "sim/log.h"

namespace gd::sim {

struct CpuExec;

namespace detail {

GD_HD Vec3 load3(const double* p, int i) { return Vec3(p[3 * i], p[3 * i + 1], p[3 * i + 2]); }
GD_HD void store3(double* p, int i, const Vec3& v) {
  p[3 * i] = v.x();
  p[3 * i + 1] = v.y();
  p[3 * i + 2] = v.z();
}

/// Scalars every element kernel needs, passed by value into kernels.
struct Params {
  Real h = 0;
  Vec3 gravity = Vec3::Zero();
  bool quasi_static = false;
  bool table = false;
  Vec3 table_n = Vec3::UnitZ();
  Real table_offset = 0, dhat = 0, kappa_per_mass = 0, table_mu = 0, friction_eps = 0;
  Real air_density = 0, drag_cd = 0, drag_linear = 0, drag_tangent_ratio = 0;
  Real beta_membrane = 0, beta_bend = 0, alpha_mass = 0;
  bool bending_exact_projected = false;
  HessianKind contact_hessian = HessianKind::kGaussNewton;  ///< self-contact pairs
  bool self_contact = false;
  Real dhat_self = 0, mu_self = 0;
  /// Smallest gap CCD lets a self-contact pair close to, m (kCcdFloorFraction * dhat_self).
  Real ccd_floor = 0;
  Real kin_stiffness = 30;  // SceneOptions::grip_stiffness
  Real kin_force_max = INFINITY;  // N, SceneOptions::grip_force_limit
  Real membrane_ref = 0;  // N/m, the material's largest stretch stiffness
};

/// A list of contact pairs: 4 vertices, type (0 VF, 1 EE), barrier stiffness, EE mollifier.
struct PairView {
  int n = 0;
  const int* v = nullptr;
  const int* type = nullptr;
  const double* kappa = nullptr;
  const double* eps = nullptr;
};

/// Raw pointers into the backend's arrays (host or device), copied into kernels.
struct View {
  int n = 0, nt = 0, nh = 0;
  const double* mass;
  const int* tris;
  const StretchShearRest* tri_rest;
  const int* hinges;
  const HingeRest* hinge_rest;
  const double* hinge_grad_t;  // per hinge: the dihedral angle's gradient at x_t (12), for damping
  const int* row_ptr;
  const int* cols;
  const int* diag;
  const int* tri_slots;
  const int* hinge_slots;
  const int* fixed;      // 1 for Dirichlet vertices
  const double* x_t;     // positions at step start
  const double* v_t;     // velocities at step start
  const double* f_ext;   // external forces, N (3 per vertex)
  const int* kin;            // 1 for kinematic vertices held by a spring (self-contact mode)
  const double* kin_target;  // their targets at the end of the step (3 per vertex)
  // kinematic colliders: shape, poses (R0 row-major, t0, R1, t1: 24 doubles), friction, meshes
  int n_col = 0;
  const ColliderShape* col_shape;
  const double* col_pose;
  const double* col_mu;
  ColliderMeshView col_mesh;
  // self-contact: candidate pairs (line search, CCD), active pairs (Hessian), lagged friction
  PairView cand, act;
  int n_fr = 0;
  const int* fr_v;
  const double* fr_w;
  const double* fr_T;
  const double* fr_lambda;
};

/// Self-contact barrier of pair c of a list (vertex-face or edge-edge), PSD-projected Hessian.
GD_HD Real pair_barrier(const Params& P, const PairView& L, int c, const double* x, Vec12* g, Mat12* H) {
  const int* v = L.v + 4 * c;
  const Vec3 a = load3(x, v[0]), b = load3(x, v[1]), q = load3(x, v[2]), d = load3(x, v[3]);
  return L.type[c] == 0
             ? vf_contact_energy(a, b, q, d, 0.0, P.dhat_self, L.kappa[c], g, H, P.contact_hessian)
             : ee_contact_energy(a, b, q, d, 0.0, P.dhat_self, L.kappa[c], L.eps[c], g, H, P.contact_hessian);
}

/// Lagged cloth-cloth friction of friction pair k.
GD_HD Real pair_friction(const View& V, const Params& P, int k, const double* x, Vec12* g, Mat12* H) {
  const int* v = V.fr_v + 4 * k;
  Vec12 xs, ys;
  for (int a = 0; a < 4; ++a) {
    xs.segment<3>(3 * a) = load3(x, v[a]);
    ys.segment<3>(3 * a) = load3(V.x_t, v[a]);
  }
  const VecN<4> w(V.fr_w[4 * k], V.fr_w[4 * k + 1], V.fr_w[4 * k + 2], V.fr_w[4 * k + 3]);
  const Eigen::Map<const Eigen::Matrix<Real, 3, 2>> T(V.fr_T + 6 * k);
  return contact_friction_energy(xs, ys, w, T, P.mu_self, V.fr_lambda[k], P.friction_eps, g, H);
}

/// Inertia target x_hat = x_t + h v_t (gravity is its own energy).
GD_HD Vec3 inertia_target(const View& V, const Params& P, int i) {
  const Vec3 xt = load3(V.x_t, i);
  return P.quasi_static ? xt : Vec3(xt + P.h * load3(V.v_t, i));
}

/// Stiffness of the grip spring of a held vertex of mass m, N/m: far stiffer than its inertia and
/// the membrane (SceneOptions::grip_stiffness).
GD_HD Real grip_stiffness(const Params& P, Real m) { return P.kin_stiffness * (m / (P.h * P.h) + P.membrane_ref); }

/// Per-vertex terms: inertia, gravity, mass damping, table barrier, lagged friction and grip springs.
GD_HD Real vertex_terms(const View& V, const Params& P, int i, const Vec3& x, Vec3* g, Mat3* H) {
  const Real m = V.mass[i];
  const Vec3 xt = load3(V.x_t, i);
  Vec3 gi;
  Mat3 Hi;
  Real e = inertia_energy(x, inertia_target(V, P, i), m, P.h, g ? &gi : nullptr, H ? &Hi : nullptr);
  Vec3 gk;
  e += gravity_energy(x, m, P.gravity, g ? &gk : nullptr);
  const Vec3 f = load3(V.f_ext, i);
  e -= f.dot(x);  // external load: potential -f.x
  if (g) *g = gi + gk - f;
  if (H) *H = Hi;
  Real hd = 0;
  e += mass_damping_energy(x, xt, m, P.alpha_mass, P.h, g ? &gk : nullptr, H ? &hd : nullptr);
  if (g) *g += gk;
  if (H) *H += hd * Mat3::Identity();
  if (V.kin[i]) {  // stiff spring to the kinematic target, far stiffer than inertia and membrane
    Mat3 Hk;
    e += grip_spring_energy(x, load3(V.kin_target, i), grip_stiffness(P, m), P.kin_force_max, g ? &gk : nullptr,
                            H ? &Hk : nullptr);
    if (g) *g += gk;
    if (H) *H += Hk;
  }
  if (!V.fixed[i]) {  // kinematic colliders: barrier at the end pose, friction lagged
    for (int c = 0; c < V.n_col; ++c) {
      const double* q = V.col_pose + 24 * c;
      const Mat3 R0 = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(q);
      const Vec3 t0(q[9], q[10], q[11]);
      const Mat3 R1 = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(q + 12);
      const Vec3 t1(q[21], q[22], q[23]);
      const Real kappa = P.kappa_per_mass * m;
      Mat3 Hc;
      e += point_collider_energy(x, R1, t1, V.col_shape[c], 0.0, P.dhat, kappa, g ? &gk : nullptr, H ? &Hc : nullptr,
                                 HessianKind::kProjected, &V.col_mesh);
      if (g) *g += gk;
      if (H) *H += Hc;
      if (V.col_mu[c] > 0) {
        const ColliderContactFrame f =
            collider_contact_frame(xt, R0, t0, R1, t1, V.col_shape[c], 0.0, P.dhat, kappa, &V.col_mesh);
        if (f.lambda > 0) {
          e += point_collider_friction(x, xt, f.surface_displacement, f.T, V.col_mu[c], f.lambda, P.friction_eps,
                                       g ? &gk : nullptr, H ? &Hc : nullptr);
          if (g) *g += gk;
          if (H) *H += Hc;
        }
      }
    }
  }
  if (P.table && !V.fixed[i]) {
    const Real kappa = P.kappa_per_mass * m;
    Mat3 Hb;
    e += plane_barrier_energy(x, P.table_n, P.table_offset, P.dhat, kappa, g ? &gk : nullptr, H ? &Hb : nullptr);
    if (g) *g += gk;
    if (H) *H += Hb;
    // Friction with the normal force lagged at the start of the step.
    const Real dt = P.table_n.dot(xt) - P.table_offset;
    if (P.table_mu > 0 && dt < P.dhat) {
      const Real lambda = plane_barrier_force_magnitude(dt, P.dhat, kappa);
      Eigen::Matrix<Real, 3, 2> T;
      plane_tangent_basis(P.table_n, &T);
      e += plane_friction_energy(x, xt, T, P.table_mu, lambda, P.friction_eps, g ? &gk : nullptr, H ? &Hb : nullptr);
      if (g) *g += gk;
      if (H) *H += Hb;
    }
  }
  return e;
}

/// Triangle terms: anisotropic stretch/shear, strain-rate damping and air drag.
GD_HD Real triangle_terms(const View& V, const Params& P, int t, const double* x, Vec9* g, Mat9* H) {
  const int i0 = V.tris[3 * t], i1 = V.tris[3 * t + 1], i2 = V.tris[3 * t + 2];
  const Vec3 x0 = load3(x, i0), x1 = load3(x, i1), x2 = load3(x, i2);
  const StretchShearRest& r = V.tri_rest[t];
  Vec9 ge;
  Mat9 He;
  // Membrane stretch/shear and its damping, summed in (w_u, w_v) space and mapped to the
  // positions once.
  Vec3 wu, wv;
  deformation_columns(x0, x1, x2, r.Dm_inv, &wu, &wv);
  VecN<6> gw, gwd;
  MatN<6> Hw, Hwd;
  Real e = stretch_shear_energy_w(wu, wv, r, g ? &gw : nullptr, H ? &Hw : nullptr, HessianKind::kProjected);
  const Vec3 y0 = load3(V.x_t, i0), y1 = load3(V.x_t, i1), y2 = load3(V.x_t, i2);
  if (P.beta_membrane > 0) {
    Vec3 wu_t, wv_t;
    deformation_columns(y0, y1, y2, r.Dm_inv, &wu_t, &wv_t);
    e += membrane_damping_energy_w(wu, wv, wu_t, wv_t, r, P.beta_membrane, P.h, g ? &gwd : nullptr,
                                   H ? &Hwd : nullptr);
    if (g) gw += gwd;
    if (H) Hw += Hwd;
  }
  if (g || H) {
    Vec3 cu, cv;
    membrane_weights(r.Dm_inv, &cu, &cv);
    if (g) membrane_map_gradient(cu, cv, gw.segment<3>(0), gw.segment<3>(3), g);
    if (H) membrane_map_hessian(cu, cv, Hw, H);
  }
  if (P.air_density > 0 && !P.quasi_static) {
    const Vec3 nrm = (y1 - y0).cross(y2 - y0);
    const Real len = nrm.norm();
    if (len > 0) {
      const Vec3 n = nrm / len;
      const Vec3 vc = (load3(V.v_t, i0) + load3(V.v_t, i1) + load3(V.v_t, i2)) / 3.0;
      const Real cn = drag_normal_coefficient(P.air_density, P.drag_cd, fabs(vc.dot(n)), P.drag_linear);
      const Vec3 c_prev = (y0 + y1 + y2) / 3.0;
      e += drag_energy(x0, x1, x2, c_prev, n, r.area, cn, cn * P.drag_tangent_ratio, P.h, g ? &ge : nullptr,
                       H ? &He : nullptr);
      if (g) *g += ge;
      if (H) *H += He;
    }
  }
  return e;
}

/// A hinge's Hessian as two rank-one terms, cu u uᵀ + cw w wᵀ: bending's Gauss-Newton term
/// (u = ∇θ) and curvature-rate damping (w = ∇θ at the step start). Assembled block by block
/// without forming the 12x12 matrix (Solver::scatter_rank2).
struct HingeHessian {
  Vec12 u, w;
  Real cu = 0, cw = 0;
};

/// Hinge terms with the Hessian in factored form (the default Gauss-Newton bending Hessian):
/// the same energy, gradient and, summed out, Hessian as hinge_terms with kProjected.
GD_HD Real hinge_terms_rank2(const View& V, const Params& P, int h, const double* x, Vec12* g, HingeHessian* H) {
  const int* hv = V.hinges + 4 * h;
  const HingeRest& r = V.hinge_rest[h];
  Vec12 xs, gth;
  Real d2E;
  for (int k = 0; k < 4; ++k) xs.segment<3>(3 * k) = load3(x, hv[k]);
  Real e = bending_energy_rank1(xs.segment<3>(0), xs.segment<3>(3), xs.segment<3>(6), xs.segment<3>(9), r, g,
                                H ? &H->u : &gth, H ? &H->cu : &d2E);
  if (H) H->cw = 0, H->w.setZero();  // no damping: a zero term (w must not hold garbage)
  if (P.beta_bend > 0) {
    Vec12 ys;
    for (int k = 0; k < 4; ++k) ys.segment<3>(3 * k) = load3(V.x_t, hv[k]);
    const Eigen::Map<const Vec12> gt(V.hinge_grad_t + 12 * h);
    Vec12 ge;
    e += bending_damping_energy(xs, ys, gt, r, P.beta_bend, P.h, g ? &ge : nullptr, nullptr);
    if (g) *g += ge;
    if (H) {
      H->w = gt;
      H->cw = bending_damping_coef(r, P.beta_bend, P.h);
    }
  }
  return e;
}

/// Hinge terms: nonlinear bending and curvature-rate damping, the Hessian as a 12x12 matrix
/// (with the projected exact bending Hessian; hinge_terms_rank2 otherwise).
GD_HD Real hinge_terms(const View& V, const Params& P, int h, const double* x, Vec12* g, Mat12* H) {
  const int* hv = V.hinges + 4 * h;
  const HingeRest& r = V.hinge_rest[h];
  Vec12 xs;
  for (int k = 0; k < 4; ++k) xs.segment<3>(3 * k) = load3(x, hv[k]);
  Real e = bending_energy(xs.segment<3>(0), xs.segment<3>(3), xs.segment<3>(6), xs.segment<3>(9), r, g, H,
                          P.bending_exact_projected ? HessianKind::kExact : HessianKind::kProjected);
  if (H && P.bending_exact_projected) project_psd<12>(H);
  if (P.beta_bend > 0) {
    Vec12 ys;
    for (int k = 0; k < 4; ++k) ys.segment<3>(3 * k) = load3(V.x_t, hv[k]);
    const Eigen::Map<const Vec12> gt(V.hinge_grad_t + 12 * h);
    Vec12 ge;
    Mat12 He;
    e += bending_damping_energy(xs, ys, gt, r, P.beta_bend, P.h, g ? &ge : nullptr, H ? &He : nullptr);
    if (g) *g += ge;
    if (H) *H += He;
  }
  return e;
}

/// The dihedral angle's gradient at the step start, which curvature-rate damping holds fixed
/// through the step (computed once per step instead of at every evaluation).
GD_HD void hinge_step_start(const View& V, int h, double* grad_t) {
  const int* hv = V.hinges + 4 * h;
  Vec12 gt;
  dihedral_angle_derivatives(load3(V.x_t, hv[0]), load3(V.x_t, hv[1]), load3(V.x_t, hv[2]), load3(V.x_t, hv[3]), &gt,
                             nullptr);
  for (int k = 0; k < 12; ++k) grad_t[12 * h + k] = gt(k);
}

}  // namespace detail

template <class Exec>
class Solver final : public SolverBase {
  template <class T>
  using Vec = typename Exec::template Vector<T>;

 public:
  Solver(std::shared_ptr<const SceneData> data, const SceneOptions& opt) : data_(std::move(data)), opt_(opt) {
    const SceneData& d = *data_;
    n_ = d.n;
    Exec::upload(mass_, d.mass);
    Exec::upload(tris_, d.tris);
    Exec::upload(tri_rest_, d.tri_rest);
    Exec::upload(hinges_, d.hinges);
    Exec::upload(hinge_rest_, d.hinge_rest);
    Exec::upload(row_ptr_, d.row_ptr);
    Exec::upload(cols_, d.cols);
    Exec::upload(diag_, d.diag);
    Exec::upload(tri_slots_, d.tri_slots);
    Exec::upload(hinge_slots_, d.hinge_slots);
    Exec::upload(x_, d.x);
    Exec::upload(v_, d.v);
    for (auto* vec : {&x_t_, &v_t_, &g_, &g_trial_, &dx_, &r_, &z_, &p_, &ap_, &x_trial_}) Exec::resize(*vec, 3 * n_);
    Exec::resize(vals_, 9 * static_cast<size_t>(d.blocks()));
    Exec::resize(hinge_grad_t_, 12 * static_cast<size_t>(d.hinge_count()));
    precond_ = make_preconditioner<Exec>(opt, n_);
    // The Newton stopping rule predicts the next correction with a preconditioner that carries
    // smooth modes: PCG's own when it does (MAS), else a MAS instance kept for that alone.
    if (!precond_->estimates_smooth_modes() && (opt.newton_rtol > 0 || opt.newton_atol > 0))
      estimator_ = std::make_unique<MultilevelAdditiveSchwarz<Exec>>(n_, opt.mas_domain_size);
    Exec::resize(fixed_, n_);
    Exec::resize(kin_flag_, n_);
    Exec::resize(kin_target_, 3 * static_cast<size_t>(n_));
    Exec::resize(f_ext_, 3 * static_cast<size_t>(n_));
    kin_fixed_host_.assign(n_, 0);
    host_dx_.assign(3 * static_cast<size_t>(n_), 0.0);

    P_.gravity = opt.gravity;
    P_.table = opt.table;
    P_.table_n = Vec3::UnitZ();
    P_.table_offset = opt.table_height;
    P_.dhat = opt.contact_distance > 0 ? opt.contact_distance : std::max<Real>(d.thickness, 1e-3);
    // Barrier stiffness per kilogram: a vertex's own weight is balanced at d = dhat/2.
    P_.kappa_per_mass = kGravity / (P_.dhat * 1.1931471805599454);
    P_.table_mu = opt.table_friction;
    P_.air_density = opt.air_density;
    P_.drag_cd = opt.drag_coefficient;
    P_.drag_linear = opt.drag_linear;
    P_.drag_tangent_ratio = opt.drag_tangent_ratio;
    P_.beta_membrane = opt.membrane_damping;
    P_.beta_bend = opt.bending_damping;
    P_.alpha_mass = opt.mass_damping;
    P_.bending_exact_projected = opt.bending_hessian == BendingHessianKind::kProjectedExact;
    P_.contact_hessian = opt.contact_hessian == ContactHessianKind::kGaussNewton ? HessianKind::kGaussNewton
                                                                                 : HessianKind::kProjected;
    P_.membrane_ref = d.stiffness_ref;
    P_.kin_stiffness = opt.grip_stiffness;
    P_.kin_force_max = opt.grip_force_limit;
    P_.self_contact = opt.self_contact && d.triangles() > 1;
    if (P_.self_contact) {
      P_.dhat_self = P_.dhat;
      P_.ccd_floor = kCcdFloorFraction * P_.dhat_self;
      P_.mu_self = opt.self_friction >= 0 ? opt.self_friction : d.friction;
      self_ = std::make_unique<SelfContact>(d, P_.dhat_self, P_.kappa_per_mass);
    }
  }

  // ---------------------------------------------------------------------------------------
  // One time step: the table of contents.
  StepStats step(const KinematicTargets& kin, bool quasi_static) override {
    const auto t0 = std::chrono::steady_clock::now();
    StepStats st;
    StageTimes& T = st.stage;
    const double bp_seconds_at_start = self_ ? self_->broad_phase_seconds() : 0.0;
    const long bp_queries_at_start = self_ ? self_->broad_phase_queries() : 0;
    timed(T.predictor, [&] { begin_step(kin, quasi_static); });   // lagged data, Dirichlet targets, predictor
    bool gradient_known = false;                                    // g_ is the gradient at x (line search)
    double scale = 0;                                               // the first Newton step's size, m/s
    for (int k = 0; k < opt_.newton_max_iters; ++k) {
      if (k > 0 && residual_rule() && converged(&st, k, gradient_known, scale)) break;  // residual small
      timed(T.contacts, [&] { select_contacts(); });                // active self-contact pairs at x
      double e0 = 0;
      timed(T.assembly, [&] { e0 = assemble(); });                  // L, gradient and PSD Hessian at x
      if (!std::isfinite(e0)) {                                     // e.g. a target that tears the cloth apart
        st.finite = false;
        break;
      }
      if (k == 0 && residual_rule() && predictor_converged(&st)) break;  // nothing left to solve
      timed(T.precond, [&] { prepare_linear_solve(); });            // contact couplings, preconditioner
      timed(T.pcg, [&] { st.pcg_iters += solve_linear(scale); });   // dx = -H^-1 g (inexact)
      timed(T.contacts, [&] { find_contacts_along_step(); });       // broad phase on the motion x -> x + dx
      double alpha_max = 1, alpha = 0;
      timed(T.ccd, [&] { alpha_max = max_step(); });                // CCD: largest safe fraction of dx
      timed(T.line_search, [&] { alpha = line_search(alpha_max, e0, &st.energy_evals); });  // Armijo backtracking
      gradient_known = accept_step(alpha);                          // x += alpha dx
      st.newton_iters = k + 1;
      st.min_alpha = std::min(st.min_alpha, alpha);
      const double taken = alpha * rms_velocity(dx_);               // the correction just made, m/s
      if (k == 0) scale = taken;
      st.step_norm = max_abs(dx_) / P_.h;
      gd::log().trace("newton {}: step rms {:.3g} m/s (max |dx|/h {:.3g}), alpha {:.3g} (max {:.3g}), pcg {}, "
                      "candidates {}, evaluations {}", k, taken, st.step_norm, alpha, alpha_max, st.pcg_iters, cand_.n,
                      st.energy_evals);
      if (k > 0 && residual_rule() && taken <= residual_threshold(scale) && !pressed()) {  // last correction small
        st.converged = true;
        break;
      }
      // Also converged when the Newton direction itself is small: a step cut short by CCD or the
      // line search (alpha << 1) moves little without being at the minimum.
      if (st.step_norm < opt_.newton_tol) {
        st.converged = true;
        break;
      }
    }
    end_step();                                                     // v = (x - x_t)/h
    if (self_) Exec::download(host_x_, x_);                         // host copy for the two checks below
    if (self_) st.min_self_distance = self_->min_active_distance(host_x_);
    st.max_grip_force = max_grip_force();
    adapt_barrier_stiffness(st.min_self_distance);                  // stiffer barriers if gaps got tiny
    st.barrier_scale = kappa_scale_;
    check_intersections(&st);                                       // exact count; untangle if any (fail-safe)
    if (self_) {
      st.contacts = self_->active().size();
      st.candidates = self_->candidates().size();
      st.broad_phase_seconds = self_->broad_phase_seconds() - bp_seconds_at_start;
      st.broad_phase_queries = static_cast<int>(self_->broad_phase_queries() - bp_queries_at_start);
    }
    st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return st;
  }

  void get_positions(std::vector<double>& x) override { Exec::download(x, x_); }
  void get_velocities(std::vector<double>& v) override { Exec::download(v, v_); }
  void set_state(const std::vector<double>& x, const std::vector<double>& v) override {
    Exec::upload(x_, x);
    Exec::upload(v_, v);
  }

  void set_external_forces(const std::vector<double>& f) override { Exec::upload(f_ext_, f); }

  void set_colliders(const std::vector<Collider>& colliders, double t0, double t1) override {
    colliders_ = &colliders;
    col_t1_ = t1;
    n_col_ = static_cast<int>(colliders.size());
    if (n_col_ == 0) return;
    const PackedColliders packed = pack_colliders(colliders);
    std::vector<double> poses, mu;
    for (const Collider& c : colliders) {
      for (const double t : {t0, t1}) {
        const Eigen::Isometry3d p = c.checked_pose(t);
        for (int r = 0; r < 3; ++r)
          for (int k = 0; k < 3; ++k) poses.push_back(p.linear()(r, k));
        for (int r = 0; r < 3; ++r) poses.push_back(p.translation()[r]);
      }
      mu.push_back(c.friction());
    }
    Exec::upload(col_shape_, packed.shapes);
    Exec::upload(col_vertices_, packed.vertices);
    Exec::upload(col_tris_, packed.triangles);
    Exec::upload(col_pose_, poses);
    Exec::upload(col_mu_, mu);
  }

  EnergyReport energies() override {
    const detail::View V = view();
    const double* x = Exec::ptr(x_);
    const double* v = Exec::ptr(v_);
    const Vec3 grav = P_.gravity;
    EnergyReport e;
    e.kinetic = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) { return 0.5 * V.mass[i] * detail::load3(v, i).squaredNorm(); });
    e.gravity = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) { return -V.mass[i] * grav.dot(detail::load3(x, i)); });
    e.stretch = Exec::sum(V.nt, [=] GD_HD_LAMBDA(int t) {
      const int* tv = V.tris + 3 * t;
      return stretch_shear_energy(detail::load3(x, tv[0]), detail::load3(x, tv[1]), detail::load3(x, tv[2]),
                                  V.tri_rest[t], nullptr, nullptr, HessianKind::kNone);
    });
    e.bending = Exec::sum(V.nh, [=] GD_HD_LAMBDA(int h) {
      const int* hv = V.hinges + 4 * h;
      return bending_energy(detail::load3(x, hv[0]), detail::load3(x, hv[1]), detail::load3(x, hv[2]),
                            detail::load3(x, hv[3]), V.hinge_rest[h], nullptr, nullptr, HessianKind::kNone);
    });
    if (P_.table) {
      const detail::Params P = P_;
      e.contact = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) {
        return plane_barrier_energy(detail::load3(x, i), P.table_n, P.table_offset, P.dhat, P.kappa_per_mass * V.mass[i],
                                    nullptr, nullptr);
      });
    }
    return e;
  }

  double max_strain() override {
    const detail::View V = view();
    const double* x = Exec::ptr(x_);
    return Exec::max(V.nt, [=] GD_HD_LAMBDA(int t) {
      const int* tv = V.tris + 3 * t;
      Real eu, ev, s;
      triangle_strains(detail::load3(x, tv[0]), detail::load3(x, tv[1]), detail::load3(x, tv[2]), V.tri_rest[t].Dm_inv,
                       &eu, &ev, &s);
      return fmax(fabs(eu), fabs(ev));
    });
  }

  size_t bytes() const override {
    const SceneData& d = *data_;
    size_t b = sizeof(double) * (12 * static_cast<size_t>(n_) * 3 + 9 * static_cast<size_t>(d.blocks()) + 9 * n_ + n_);
    b += sizeof(int) * (d.tris.size() + d.hinges.size() + d.row_ptr.size() + d.cols.size() + d.diag.size() +
                        d.tri_slots.size() + d.hinge_slots.size() + n_);
    b += sizeof(StretchShearRest) * d.tri_rest.size() + sizeof(HingeRest) * d.hinge_rest.size();
    return b;
  }

  std::string backend_name() const override { return Exec::kName; }

 // The stages below are public only because nvcc requires the functions that enclose extended
 // __host__ __device__ lambdas to be public; SolverBase is the interface.
  detail::View view() const {
    detail::View V;
    V.n = n_;
    V.nt = data_->triangles();
    V.nh = data_->hinge_count();
    V.mass = Exec::ptr(mass_);
    V.tris = Exec::ptr(tris_);
    V.tri_rest = Exec::ptr(tri_rest_);
    V.hinges = Exec::ptr(hinges_);
    V.hinge_rest = Exec::ptr(hinge_rest_);
    V.hinge_grad_t = Exec::ptr(hinge_grad_t_);
    V.row_ptr = Exec::ptr(row_ptr_);
    V.cols = Exec::ptr(cols_);
    V.diag = Exec::ptr(diag_);
    V.tri_slots = Exec::ptr(tri_slots_);
    V.hinge_slots = Exec::ptr(hinge_slots_);
    V.fixed = Exec::ptr(fixed_);
    V.x_t = Exec::ptr(x_t_);
    V.v_t = Exec::ptr(v_t_);
    V.f_ext = Exec::ptr(f_ext_);
    V.kin = Exec::ptr(kin_flag_);
    V.kin_target = Exec::ptr(kin_target_);
    V.n_col = n_col_;
    V.col_shape = Exec::ptr(col_shape_);
    V.col_pose = Exec::ptr(col_pose_);
    V.col_mu = Exec::ptr(col_mu_);
    V.col_mesh = ColliderMeshView{Exec::ptr(col_vertices_), Exec::ptr(col_tris_)};
    V.cand = cand_.view();
    V.act = act_.view();
    V.n_fr = n_fr_;
    V.fr_v = Exec::ptr(fr_v_);
    V.fr_w = Exec::ptr(fr_w_);
    V.fr_T = Exec::ptr(fr_T_);
    V.fr_lambda = Exec::ptr(fr_lambda_);
    return V;
  }

  /// Saves the step-start state, applies Dirichlet targets and an inertial predictor that stays
  /// above the table.
  void begin_step(const KinematicTargets& kin, bool quasi_static) {
    P_.h = opt_.dt;
    P_.quasi_static = quasi_static;
    P_.friction_eps = opt_.friction_eps_v * opt_.dt;
    precond_ready_ = false;  // set up again at this step's first Newton iteration
    if (quasi_static) Exec::fill(v_, 0.0);
    copy(x_, x_t_);
    copy(v_, v_t_);
    if (P_.beta_bend > 0) {  // the damping's lagged angle gradient
      const detail::View V0 = view();
      double* grad_t = Exec::ptr(hinge_grad_t_);
      Exec::for_each(V0.nh, [=] GD_HD_LAMBDA(int h) { detail::hinge_step_start(V0, h, grad_t); }, Exec::kParallelMinHeavy);
    }
    // Kinematic vertices: hard Dirichlet without self-contact; with self-contact they stay in the
    // solve, pulled to their targets by a stiff spring, so CCD also guards their motion and a
    // gripper pushes cloth aside instead of jumping through it.
    const bool soft = self_ != nullptr;
    std::fill(kin_fixed_host_.begin(), kin_fixed_host_.end(), 0);
    std::vector<int> kin_flag(n_, 0);
    for (int k : kin.vertices) (soft ? kin_flag : kin_fixed_host_)[k] = 1;
    Exec::upload(fixed_, kin_fixed_host_);
    Exec::upload(kin_flag_, kin_flag);
    update_free_mass();
    std::vector<double> targets(3 * static_cast<size_t>(n_), 0.0);
    for (size_t k = 0; k < kin.vertices.size(); ++k)
      for (int c = 0; c < 3; ++c) targets[3 * kin.vertices[k] + c] = kin.targets[3 * k + c];
    Exec::upload(kin_target_, targets);
    const detail::View V = view();
    const detail::Params P = P_;
    double* x = Exec::ptr(x_);
    Exec::for_each(n_, [=] GD_HD_LAMBDA(int i) {
      if (V.fixed[i] || V.kin[i]) {  // kinematic: straight to the target
        detail::store3(x, i, detail::load3(V.kin_target, i));
        return;
      }
      const Vec3 xt = detail::load3(V.x_t, i);
      Vec3 step = detail::inertia_target(V, P, i) - xt;
      if (P.table) {  // keep the predictor clear of the table
        const Real d = P.table_n.dot(xt) - P.table_offset, dn = P.table_n.dot(step);
        if (dn < 0 && d + dn < 0.5 * d) step *= 0.5 * d / (-dn);
      }
      detail::store3(x, i, xt + step);
    });
    if (n_col_ > 0) {
      // A collider may move into the cloth during the step: start Newton from a guess with
      // every free vertex at least dhat/2 outside each collider's end pose.
      Exec::download(host_x_, x_);
      for (int i = 0; i < n_; ++i) {
        if (kin_fixed_host_[i]) continue;
        Vec3 p(host_x_[3 * i], host_x_[3 * i + 1], host_x_[3 * i + 2]);
        for (const Collider& c : *colliders_) p = c.project_out(p, col_t1_, 0.5 * P_.dhat);
        for (int k = 0; k < 3; ++k) host_x_[3 * i + k] = p[k];
      }
      Exec::upload(x_, host_x_);
    }
    if (self_) {
      // One broad phase on the predictor's motion x_t -> x: its candidates hold every pair within
      // dhat at x_t too (a swept box contains the box at x_t), so the contacts at the start of
      // the step, which lag the friction, are selected from them; then the whole motion is
      // scaled back by CCD where needed.
      Exec::download(host_xt_, x_t_);
      Exec::download(host_x_, x_);
      self_->find(host_xt_, host_x_);
      self_->select_active(host_xt_, kin_fixed_host_);
      self_->build_friction(host_xt_);
      upload_friction();
      upload_candidates();
      for (size_t k = 0; k < host_x_.size(); ++k) host_dx_[k] = host_x_[k] - host_xt_[k];
      Exec::upload(dx_, host_dx_);
      copy(x_t_, x_);
      const double alpha = std::min(self_ccd_bound(), table_ccd_bound());
      axpy(alpha < 1.0 ? 0.9 * alpha : 1.0, dx_, x_);
    }
  }

  /// Active pairs (closer than dhat) at the current x, with their Hessian storage.
  void select_contacts() {
    if (!self_) return;
    Exec::download(host_x_, x_);
    self_->select_active(host_x_, kin_fixed_host_);
    stiffen_pressed_pairs();  // before the pairs go to the backend
    const ContactPairs& a = self_->active();
    act_.upload(a);
    Exec::resize(act_H_, 144 * static_cast<size_t>(act_.n));
    Exec::resize(act_gd_, 48 * static_cast<size_t>(act_.n));
    upload_candidates();  // select_active drops pairs already at zero distance
  }

  /// Candidates along the Newton step x -> x + dx (for CCD and the line search).
  void find_contacts_along_step() {
    if (!self_) return;
    Exec::download(host_x_, x_);
    Exec::download(host_dx_, dx_);
    for (size_t k = 0; k < host_x_.size(); ++k) host_dx_[k] += host_x_[k];
    self_->find(host_x_, host_dx_);
    self_->select_active(host_x_, kin_fixed_host_);
    upload_candidates();
  }

  void upload_candidates() {
    const ContactPairs& c = self_->candidates();
    cand_.upload(c);
  }

  void upload_friction() {
    const FrictionPairs& f = self_->friction();
    n_fr_ = f.size();
    Exec::upload(fr_v_, f.v);
    Exec::upload(fr_w_, f.w);
    Exec::upload(fr_T_, f.T);
    Exec::upload(fr_lambda_, f.lambda);
    Exec::resize(fr_H_, 144 * static_cast<size_t>(n_fr_));
    Exec::resize(fr_gd_, 48 * static_cast<size_t>(n_fr_));
  }

  /// IPC-style adaptive stiffness of the self-contact barrier: it starts so that a vertex's
  /// weight rests at dhat/2, but grippers and stacked layers press harder. When a pair's gap
  /// closes below a tenth of dhat the stiffness doubles (up to 1e4 x); when every active pair is
  /// more than kRelaxGapFraction dhat apart again (nothing pressed; no pair at all counts too) it
  /// halves, back down to 1 x. Kept stiff, the barrier made Newton stop at its iteration cap in
  /// every later step, and the motion crept: a sleeve stood 33 cm tall for seconds after a fold,
  /// then fell to 8 cm in 0.5 s once the stiffness was back at 1 x (docs/validation.md).
  /// (The table keeps its weight-calibrated stiffness: cloth rests on it under gravity alone.)
  /// min_distance: the closest active pair at the end of the step.
  void adapt_barrier_stiffness(double min_distance) {
    if (!self_) return;
    if (min_distance < 0.1 * P_.dhat_self) {
      scale_barrier_stiffness(2);
    } else if (min_distance > kRelaxGapFraction * P_.dhat_self) {
      scale_barrier_stiffness(0.5);
    }
  }

  /// Within the step, before each Newton iteration: while a pair is closer than
  /// kPressedGapFloors CCD floors (10 um at dhat = 1 mm) the barrier stiffness doubles (up to the
  /// same 1e4 x). A grip or a stack pressing harder than the barrier can hold at that gap would
  /// otherwise squeeze the pair towards the floor, where CCD lets it close by half per iteration,
  /// until rounding decides the exact intersection test. Doubling per iteration rather than per
  /// step lifts the equilibrium gap (kappa dhat^2 / force) before the pair gets there.
  /// host_x_ holds the iterate.
  void stiffen_pressed_pairs() {
    if (kappa_scale_ >= kKappaScaleMax) return;  // skip the distance pass when capped
    if (self_->min_active_distance(host_x_) < kPressedGapFloors * P_.ccd_floor) scale_barrier_stiffness(2);
  }

  /// Multiplies the self-contact barrier stiffness by `factor`, kept within [1, kKappaScaleMax];
  /// the current candidate and active pairs take the new stiffness at once.
  void scale_barrier_stiffness(double factor) {
    const double scale = std::clamp(kappa_scale_ * factor, 1.0, kKappaScaleMax);
    if (scale == kappa_scale_) return;
    kappa_scale_ = scale;
    self_->set_kappa_scale(kappa_scale_);
  }

  /// Exact count of intersecting triangle pairs after the step (host_x_ holds the positions);
  /// the untangling fail-safe runs when there are any.
  void check_intersections(StepStats* st) {
    if (!self_ || !opt_.check_intersections) return;
    timed(st->stage.intersections, [&] { st->intersecting_pairs = self_->count_intersections(host_x_); });
    st->intersecting_found = st->intersecting_pairs;
    if (st->intersecting_pairs > 0 && opt_.untangle) {
      st->untangled = true;
      timed(st->stage.untangle, [&] { st->intersecting_pairs = self_->untangle(&host_x_, kin_fixed_host_); });
      Exec::upload(x_, host_x_);
    }
  }

  /// Runs f and adds its wall time to `seconds` (the backend's queued work included).
  template <class F>
  static void timed(double& seconds, F&& f) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    Exec::sync();
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }

  /// Whether the residual stopping rule is on (SceneOptions::newton_rtol / newton_atol): in
  /// dynamic steps. Quasi-static steps (Scene::relax, static validation) are solves for an
  /// equilibrium, stopped by newton_tol and relax's own tolerance alone.
  bool residual_rule() const { return !P_.quasi_static && (opt_.newton_rtol > 0 || opt_.newton_atol > 0); }
  /// The velocity correction below which Newton stops, given the first Newton step's (m/s).
  double residual_threshold(double first_step) const {
    return std::max(opt_.newton_atol, opt_.newton_rtol * first_step);
  }

  /// Before Newton iteration k >= 1: whether the iterate is converged, judged by the correction its
  /// gradient still asks for against the first step's `scale`: estimated with the last
  /// preconditioner where it carries smooth modes (MAS: the next Newton step, P⁻¹g, without
  /// assembling or solving), else bounded by residual_bound. The gradient comes from the line
  /// search when it was computed there.
  bool converged(StepStats* st, int k, bool gradient_known, double scale) {
    if (!gradient_known) timed(st->stage.assembly, [&] { evaluate(x_, g_, false); });
    Preconditioner<Exec>* estimator = estimator_ ? estimator_.get() : precond_.get();
    if (precond_ready_ && estimator->estimates_smooth_modes()) {
      timed(st->stage.pcg, [&] { estimator->apply(Exec::ptr(g_), Exec::ptr(z_)); });
      st->residual = rms_velocity(z_);
    } else {
      st->residual = residual_bound();
    }
    st->converged = st->residual <= residual_threshold(scale) && !pressed();
    gd::log().trace("newton {}: next correction {:.3g} m/s (first step {:.3g}){}", k, st->residual, scale,
                    st->converged ? ", converged" : "");
    return st->converged;
  }

  /// A self-contact pair pressed closer than kPressedGapFloors CCD floors while the barrier can
  /// still stiffen: not converged whatever the residual says, so that stiffen_pressed_pairs gets
  /// its next Newton iteration (the per-iteration guard against grips squeezing cloth through
  /// cloth; validation case self/press).
  bool pressed() {
    if (!self_ || kappa_scale_ >= kKappaScaleMax) return false;
    Exec::download(host_x_, x_);
    return self_->min_active_distance(host_x_) < kPressedGapFloors * P_.ccd_floor;
  }

  /// After the first assembly: whether the predictor is already within newton_atol.
  bool predictor_converged(StepStats* st) {
    st->residual0 = st->residual = residual_bound();
    st->converged = st->residual0 <= opt_.newton_atol;
    return st->converged;
  }

  /// An upper bound of the velocity correction the gradient g_ still asks for: the Hessian is at
  /// least M/h² (inertia; every other term is PSD), so the Newton correction d = -H⁻¹ g has
  /// |d|_M <= h² |g|_M⁻¹, i.e. an RMS velocity of at most h |g|_M⁻¹ / sqrt(M), m/s. A safe test
  /// (it never calls an unconverged iterate converged) that is tight where inertia dominates
  /// (free flight, sliding, the predictor) and pessimistic for stiff membrane errors, which the
  /// step test after each iteration catches instead.
  double residual_bound() {
    const detail::View V = view();
    const double* g = Exec::ptr(g_);
    const double num = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) {
      return V.fixed[i] ? 0.0 : detail::load3(g, i).squaredNorm() / V.mass[i];
    });
    return P_.h * std::sqrt(num / free_mass());
  }

  /// Total mass of the free vertices, kg (set by begin_step: the Dirichlet set changes only there).
  double free_mass() const { return free_mass_; }

  void update_free_mass() {
    const detail::View V = view();
    const double m = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) { return V.fixed[i] ? 0.0 : V.mass[i]; });
    free_mass_ = m > 0 ? m : 1.0;
  }

  /// Mass-weighted RMS of a displacement over the step, |d|_M / (h sqrt(M)) over the free
  /// vertices, m/s.
  double rms_velocity(const Vec<double>& d) {
    const detail::View V = view();
    const double* p = Exec::ptr(d);
    const double num = Exec::sum(n_, [=] GD_HD_LAMBDA(int i) {
      return V.fixed[i] ? 0.0 : V.mass[i] * detail::load3(p, i).squaredNorm();
    });
    return std::sqrt(num / free_mass()) / P_.h;
  }

  /// x += alpha dx, taking the line search's accepted trial point (bit for bit the state it
  /// evaluated) and its gradient. Returns whether g_ now holds the gradient at the new x.
  bool accept_step(double alpha) {
    if (alpha == 0.0) return false;
    if (alpha == last_trial_alpha_) {
      std::swap(x_, x_trial_);
      std::swap(g_, g_trial_);
      return true;
    }
    axpy(alpha, dx_, x_);
    return false;
  }

  /// L at x_ with its gradient g_ and projected Hessian vals_ (the active pairs' off-diagonal
  /// blocks in act_H_/fr_H_).
  double assemble() {
    return evaluate(x_, g_, true);
  }

  /// L(xs), its gradient into gs and, when `hessian` (xs must be x_), the PSD-projected Hessian
  /// into vals_. Dirichlet rows are left zero (identity is implied in the matrix-vector product).
  /// Self-contact pairs: the active ones (selected at x_) with the Hessian, the candidates
  /// otherwise (a line-search trial point: every pair within dhat of it is a candidate).
  double evaluate(const Vec<double>& xs, Vec<double>& gs, bool hessian) {
    if (hessian) Exec::fill(vals_, 0.0);
    Exec::fill(gs, 0.0);
    const detail::View V = view();
    const detail::Params P = P_;
    const double* x = Exec::ptr(xs);
    double* g = Exec::ptr(gs);
    double* H = hessian ? Exec::ptr(vals_) : nullptr;
    double e = Exec::sum_effects(n_, [=] GD_HD_LAMBDA(int i) {
      if (V.fixed[i]) return 0.0;
      Vec3 gi;
      Mat3 Hi;
      const double ei = detail::vertex_terms(V, P, i, detail::load3(x, i), &gi, H ? &Hi : nullptr);
      detail::store3(g, i, gi);
      if (H) {
        double* b = H + 9 * V.diag[i];
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) b[3 * r + c] = Hi(r, c);
      }
      return ei;
    }, Exec::kParallelMinHeavy);
    e += sum_elements(data_->tri_colors, V.nt, [=] GD_HD_LAMBDA(int t) {
      Vec9 ge;
      Mat9 He;
      const double et = detail::triangle_terms(V, P, t, x, &ge, H ? &He : nullptr);
      scatter<3>(V, V.tris + 3 * t, V.tri_slots + 9 * t, ge, He, g, H);
      return et;
    });
    e += sum_elements(data_->hinge_colors, V.nh, [=] GD_HD_LAMBDA(int h) {
      Vec12 ge;
      if (P.bending_exact_projected) {
        Mat12 He;
        const double eh = detail::hinge_terms(V, P, h, x, &ge, H ? &He : nullptr);
        scatter<4>(V, V.hinges + 4 * h, V.hinge_slots + 16 * h, ge, He, g, H);
        return eh;
      }
      detail::HingeHessian He;
      const double eh = detail::hinge_terms_rank2(V, P, h, x, &ge, H ? &He : nullptr);
      scatter_rank2(V, V.hinges + 4 * h, V.hinge_slots + 16 * h, ge, He, g, H);
      return eh;
    });
    if (self_) e += evaluate_pairs(x, g, H);
    return e;
  }

  /// The self-contact pairs' share of evaluate(): the pair terms in parallel into per-pair storage,
  /// then their gradient (and diagonal blocks) added into shared rows (serial on the CPU, atomics
  /// on the GPU). The off-diagonal blocks stay with the pair until merge_pair_blocks.
  double evaluate_pairs(const double* x, double* g, double* H) {
    const detail::View V = view();
    const detail::Params P = P_;
    const bool want_h = H != nullptr;
    const detail::PairView L = want_h ? V.act : V.cand;
    if (!want_h && cand_gd_.size() < 48 * static_cast<size_t>(L.n)) Exec::resize(cand_gd_, 48 * static_cast<size_t>(L.n));
    if (live_.size() < static_cast<size_t>(std::max(L.n, V.n_fr))) Exec::resize(live_, static_cast<size_t>(std::max(L.n, V.n_fr)));
    int* live = Exec::ptr(live_);  // candidates beyond dhat (most of them) add nothing
    double* HA = Exec::ptr(act_H_);
    double* HF = Exec::ptr(fr_H_);
    double* GA = want_h ? Exec::ptr(act_gd_) : Exec::ptr(cand_gd_);
    double* GF = Exec::ptr(fr_gd_);
    double e = Exec::sum_effects(L.n, [=] GD_HD_LAMBDA(int c) {
      const int* vs = L.v + 4 * c;
      live[c] = 0;
      if (V.fixed[vs[0]] && V.fixed[vs[1]] && V.fixed[vs[2]] && V.fixed[vs[3]]) {  // as select_active: no free vertex
        if (want_h)
          for (int k = 0; k < 144; ++k) HA[144 * c + k] = 0.0;
        return 0.0;
      }
      Vec12 ge;
      Mat12 He;
      const double ec = detail::pair_barrier(P, L, c, x, &ge, want_h ? &He : nullptr);
      if (ec == 0.0 && !want_h) return 0.0;  // beyond dhat: no gradient
      live[c] = 1;
      store_pair(V, L.v + 4 * c, ge, want_h ? &He : nullptr, HA + 144 * c, GA + 48 * c);
      return ec;
    }, Exec::kParallelMinHeavy);
    e += Exec::sum_effects(V.n_fr, [=] GD_HD_LAMBDA(int k) {
      Vec12 ge;
      Mat12 He;
      const double ek = detail::pair_friction(V, P, k, x, &ge, want_h ? &He : nullptr);
      store_pair(V, V.fr_v + 4 * k, ge, want_h ? &He : nullptr, HF + 144 * k, GF + 48 * k);
      return ek;
    }, Exec::kParallelMinHeavy);
    Exec::for_each(L.n, [=] GD_HD_LAMBDA(int c) {
      if (live[c]) add_pair(V, L.v + 4 * c, GA + 48 * c, g, H);
    }, kSerialOnCpu);
    Exec::for_each(V.n_fr, [=] GD_HD_LAMBDA(int k) { add_pair(V, V.fr_v + 4 * k, GF + 48 * k, g, H); }, kSerialOnCpu);
    return e;
  }

  /// Loops that add into shared rows without colouring: serial on the CPU, atomics on the GPU.
  static constexpr int kSerialOnCpu = Exec::kColoring ? 0x7fffffff : 0;

  /// Splits a pair's gradient and Hessian (Dirichlet rows/columns dropped): off-diagonal blocks
  /// into Hpair (row-major 12x12, diagonal blocks zero), gradient and diagonal blocks into gd
  /// (12 + 4 x 9 values) for add_pair.
  GD_HD static void store_pair(const detail::View& V, const int* vs, const Vec12& ge, const Mat12* Hp,
                               double* Hpair, double* gd) {
    for (int a = 0; a < 4; ++a) {
      const bool fa = V.fixed[vs[a]];
      for (int c = 0; c < 3; ++c) gd[3 * a + c] = fa ? 0.0 : ge(3 * a + c);
      if (!Hp) continue;
      const Mat12& He = *Hp;
      for (int b = 0; b < 4; ++b) {
        const bool keep = !fa && !V.fixed[vs[b]];
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) {
            const double h = keep ? He(3 * a + r, 3 * b + c) : 0.0;
            Hpair[36 * a + 12 * r + 3 * b + c] = a == b ? 0.0 : h;
            if (a == b) gd[12 + 9 * a + 3 * r + c] = h;
          }
      }
    }
  }

  /// Adds a stored pair's gradient and diagonal blocks into g and the block matrix (H null: the
  /// gradient only).
  GD_HD static void add_pair(const detail::View& V, const int* vs, const double* gd, double* g, double* H) {
    for (int a = 0; a < 4; ++a) {
      if (V.fixed[vs[a]]) continue;
      for (int c = 0; c < 3; ++c) Exec::add(g + 3 * vs[a] + c, gd[3 * a + c]);
      if (!H) continue;
      double* blk = H + 9 * V.diag[vs[a]];
      for (int k = 0; k < 9; ++k) Exec::add(blk + k, gd[12 + 9 * a + k]);
    }
  }

  template <int K>
  GD_HD static void scatter(const detail::View& V, const int* vs, const int* slots, const VecN<3 * K>& ge,
                            const MatN<3 * K>& He, double* g, double* H) {
    for (int a = 0; a < K; ++a) {
      if (V.fixed[vs[a]]) continue;
      for (int c = 0; c < 3; ++c) Exec::add(g + 3 * vs[a] + c, ge(3 * a + c));
      if (!H) continue;
      for (int b = 0; b < K; ++b) {
        if (V.fixed[vs[b]]) continue;
        double* blk = H + 9 * slots[K * a + b];
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) Exec::add(blk + 3 * r + c, He(3 * a + r, 3 * b + c));
      }
    }
  }

  /// scatter<4> for a hinge Hessian in factored form: block (a, b) += cu u_a u_bᵀ + cw w_a w_bᵀ.
  GD_HD static void scatter_rank2(const detail::View& V, const int* vs, const int* slots, const Vec12& ge,
                                  const detail::HingeHessian& He, double* g, double* H) {
    for (int a = 0; a < 4; ++a) {
      if (V.fixed[vs[a]]) continue;
      for (int c = 0; c < 3; ++c) Exec::add(g + 3 * vs[a] + c, ge(3 * a + c));
      if (!H) continue;
      const Vec3 su = He.cu * He.u.segment<3>(3 * a), sw = He.cw * He.w.segment<3>(3 * a);
      for (int b = 0; b < 4; ++b) {
        if (V.fixed[vs[b]]) continue;
        const Vec3 ub = He.u.segment<3>(3 * b), wb = He.w.segment<3>(3 * b);
        double* blk = H + 9 * slots[4 * a + b];
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) Exec::add(blk + 3 * r + c, su(r) * ub(c) + sw(r) * wb(c));
      }
    }
  }

  /// Sum of f over an element loop that scatters into shared rows: on the CPU colour by colour,
  /// a colour's chunks in parallel and each chunk's elements in mesh order (SceneData's
  /// Coloring); all at once with atomics on the GPU.
  template <class F>
  double sum_elements(const Coloring& coloring, int count, const F& f) {
    if constexpr (Exec::kColoring) {
      GD_DEMAND(coloring.elements == count, "element colouring built for another mesh");
      const Coloring* C = &coloring;
      const int* chunks = coloring.chunks.data();
      // Each chunk's energy into its own slot, summed in chunk order: the same bits at any
      // thread count (an OpenMP reduction would sum in an order that depends on it).
      chunk_energy_.resize(coloring.chunks.size());
      double* ce = chunk_energy_.data();
      for (int c = 0; c < coloring.colors(); ++c) {
        const int begin = coloring.offsets[c];
        Exec::for_each(coloring.offsets[c + 1] - begin, [=](int k) {
          double s = 0;
          for (int i = C->first(chunks[begin + k]); i < C->last(chunks[begin + k]); ++i) s += f(i);
          ce[begin + k] = s;
        }, std::max(2, Exec::kParallelMinHeavy / C->chunk));
      }
      double e = 0;
      for (double v : chunk_energy_) e += v;
      return e;
    } else {
      return Exec::sum_effects(count, f, Exec::kParallelMinHeavy);
    }
  }

  /// y = A x over free vertices (Dirichlet rows and columns act as identity / zero).
  void spmv(const Vec<double>& xs, Vec<double>& ys) {
    const detail::View V = view();
    const double* x = Exec::ptr(xs);
    const double* A = Exec::ptr(vals_);
    double* y = Exec::ptr(ys);
    const bool couplings = self_ != nullptr;
    const int* crp = Exec::ptr(cpl_row_ptr_);
    const int* ccols = Exec::ptr(cpl_cols_);
    const double* cvals = Exec::ptr(cpl_vals_);
    Exec::for_each(n_, [=] GD_HD_LAMBDA(int i) {
      double acc[3] = {0, 0, 0};
      if (V.fixed[i]) {
        detail::store3(y, i, detail::load3(x, i));
        return;
      }
      auto add_row = [&](const int* rp, const int* cols, const double* vals) {
        for (int k = rp[i]; k < rp[i + 1]; ++k) {
          const int j = cols[k];
          if (V.fixed[j]) continue;
          const double* b = vals + 9 * k;
          const double* xj = x + 3 * j;
          for (int r = 0; r < 3; ++r) acc[r] += b[3 * r] * xj[0] + b[3 * r + 1] * xj[1] + b[3 * r + 2] * xj[2];
        }
      };
      add_row(V.row_ptr, V.cols, A);
      if (couplings) add_row(crp, ccols, cvals);  // contact pairs' off-diagonal blocks
      y[3 * i] = acc[0], y[3 * i + 1] = acc[1], y[3 * i + 2] = acc[2];
    }, Exec::kParallelMinHeavy);
  }

  /// The pairs' off-diagonal blocks summed per coupled (row, column) vertex pair into a block CSR
  /// (cpl_*), once per linear solve, on the host. The layers of a garment lying flat make ~8
  /// contact pairs per vertex that share most of their vertex pairs, so each PCG iteration then
  /// touches every coupling once instead of once per pair that contains it, rows are gathered
  /// without atomics, and the preconditioner sees the couplings as a matrix. (On CUDA the pairs'
  /// Hessians travel to the host and the CSR back: a device-side merge is still to come.)
  void merge_pair_blocks() {
    const ContactPairs& act = self_->active();
    const FrictionPairs& fr = self_->friction();
    const double* HA = nullptr;
    const double* HF = nullptr;
    if constexpr (std::is_same_v<Exec, CpuExec>) {
      HA = act_H_.data();
      HF = fr_H_.data();
    } else {
      Exec::download(host_act_H_, act_H_);
      Exec::download(host_fr_H_, fr_H_);
      HA = host_act_H_.data();
      HF = host_fr_H_.data();
    }
    gd::sim::merge_pair_blocks(n_, kin_fixed_host_.data(),
                               {PairHessians{act.size(), act.v.data(), HA}, PairHessians{fr.size(), fr.v.data(), HF}},
                               &cpl_h_);
    Exec::take(cpl_row_ptr_, cpl_h_.row_ptr);
    Exec::take(cpl_cols_, cpl_h_.cols);
    Exec::take(cpl_vals_, cpl_h_.vals);
  }

  /// Before a linear solve: the contact couplings as a matrix, then the preconditioner's setup.
  void prepare_linear_solve() {
    if (opt_.linear_solver == LinearSolverKind::kDirect && std::is_same_v<Exec, CpuExec>) return;
    if (self_) merge_pair_blocks();
    BlockMatrixView A{n_, Exec::ptr(row_ptr_), Exec::ptr(cols_), Exec::ptr(diag_), Exec::ptr(vals_), Exec::ptr(fixed_)};
    if (self_) {
      A.cpl_row_ptr = Exec::ptr(cpl_row_ptr_);
      A.cpl_cols = Exec::ptr(cpl_cols_);
      A.cpl_vals = Exec::ptr(cpl_vals_);
    }
    A.x = Exec::ptr(x_);
    precond_->setup(A);
    if (estimator_) estimator_->setup(A);
    precond_ready_ = true;
  }

  /// Solves H dx = -g. Returns the iterations spent (1 for the direct solver).
  int solve_linear(double first_step) {
    if constexpr (std::is_same_v<Exec, CpuExec>) {
      if (opt_.linear_solver == LinearSolverKind::kDirect) return solve_direct();
    }
    return solve_pcg(first_step);
  }

  /// PCG on H dx = -g with the preconditioner set up by prepare_linear_solve.
  int solve_pcg(double first_step) {
    // With MAS, z = P⁻¹r estimates the correction PCG has still to make (as in converged()):
    // stop once it is a fraction of what the Newton rule will accept (pcg_newton_fraction), so the
    // linear solve is no more exact than the Newton iteration needs. In the first Newton iteration
    // the step built so far stands for the first step (it only grows, so the test stays strict).
    const bool newton_stop = residual_rule() && opt_.pcg_newton_fraction > 0 && precond_->estimates_smooth_modes();
    Exec::fill(dx_, 0.0);
    copy(g_, r_);
    scale(-1.0, r_);  // r = -g (free rows; Dirichlet rows of g are zero)
    const double r0 = std::sqrt(dot(r_, r_));
    if (r0 == 0.0) return 0;
    precond_->apply(Exec::ptr(r_), Exec::ptr(z_));
    copy(z_, p_);
    double rz = dot(r_, z_);
    int it = 0;
    while (it < opt_.pcg_max_iters) {
      spmv(p_, ap_);
      const double pap = dot(p_, ap_);
      if (!(pap > 0)) break;
      const double a = rz / pap;
      axpy(a, p_, dx_);
      axpy(-a, ap_, r_);
      ++it;
      if (std::sqrt(dot(r_, r_)) <= opt_.pcg_tol * r0) break;
      precond_->apply(Exec::ptr(r_), Exec::ptr(z_));
      if (newton_stop) {
        const double target = residual_threshold(first_step > 0 ? first_step : rms_velocity(dx_));
        if (rms_velocity(z_) <= opt_.pcg_newton_fraction * target) break;
      }
      const double rz_new = dot(r_, z_);
      const double beta = rz_new / rz;
      rz = rz_new;
      xpby(z_, beta, p_);  // p = z + beta p
    }
    return it;
  }

  /// Sparse LDLT on the CPU (validation and small scenes).
  int solve_direct() {
    if constexpr (std::is_same_v<Exec, CpuExec>) {
      const SceneData& d = *data_;
      std::vector<Eigen::Triplet<double>> trip;
      trip.reserve(9 * d.cols.size());
      for (int i = 0; i < n_; ++i) {
        if (kin_fixed_host_[i]) {
          for (int c = 0; c < 3; ++c) trip.emplace_back(3 * i + c, 3 * i + c, 1.0);
          continue;
        }
        for (int k = d.row_ptr[i]; k < d.row_ptr[i + 1]; ++k) {
          const int j = d.cols[k];
          if (kin_fixed_host_[j]) continue;
          for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 3; ++c) trip.emplace_back(3 * i + r, 3 * j + c, vals_[9 * k + 3 * r + c]);
        }
      }
      if (self_) {
        auto add_pairs = [&](const std::vector<int>& vs, const Vec<double>& Hs) {
          for (size_t c = 0; c < vs.size() / 4; ++c)
            for (int a = 0; a < 4; ++a)
              for (int b = 0; b < 4; ++b)
                for (int r = 0; r < 3; ++r)
                  for (int k = 0; k < 3; ++k) {
                    const double h = Hs[144 * c + 36 * a + 12 * r + 3 * b + k];
                    if (h != 0.0) trip.emplace_back(3 * vs[4 * c + a] + r, 3 * vs[4 * c + b] + k, h);
                  }
        };
        add_pairs(self_->active().v, act_H_);
        add_pairs(self_->friction().v, fr_H_);
      }
      Eigen::SparseMatrix<double> A(3 * n_, 3 * n_);
      A.setFromTriplets(trip.begin(), trip.end());
      // The mesh pattern is fixed, but contact pairs add entries that change from one solve to the
      // next: a factorisation on a stale analysis reads outside the matrix.
      if (!ldlt_analyzed_ || self_) {
        ldlt_.analyzePattern(A);
        ldlt_analyzed_ = true;
      }
      ldlt_.factorize(A);
      Eigen::Map<const Eigen::VectorXd> g(g_.data(), 3 * n_);
      Eigen::Map<Eigen::VectorXd> dx(dx_.data(), 3 * n_);
      if (ldlt_.info() != Eigen::Success) {
        if (self_) merge_pair_blocks();
        BlockMatrixView A{n_, Exec::ptr(row_ptr_), Exec::ptr(cols_), Exec::ptr(diag_), Exec::ptr(vals_),
                          Exec::ptr(fixed_)};
        if (self_) A.cpl_row_ptr = cpl_row_ptr_.data(), A.cpl_cols = cpl_cols_.data(), A.cpl_vals = cpl_vals_.data();
        A.x = x_.data();
        precond_->setup(A);
        return solve_pcg(0);
      }
      dx = ldlt_.solve(-g);
      return 1;
    } else {
      return solve_pcg(0);
    }
  }

  /// Largest step fraction along dx that keeps the state free of crossings (CCD).
  double max_step() { return std::min({table_ccd_bound(), self_ccd_bound(), collider_step_bound()}); }

  /// Conservative bound against colliders (distance is 1-Lipschitz): no free vertex moves more
  /// than 90% of its distance to a collider's surface in one step.
  double collider_step_bound() {
    if (n_col_ == 0) return 1.0;
    const detail::View V = view();
    const double* x = Exec::ptr(x_);
    const double* dx = Exec::ptr(dx_);
    const double inv = Exec::max(n_, [=] GD_HD_LAMBDA(int i) {
      if (V.fixed[i]) return 0.0;
      const Real len = detail::load3(dx, i).norm();
      if (len == 0) return 0.0;
      double worst = 0;
      for (int c = 0; c < V.n_col; ++c) {
        const double* q = V.col_pose + 24 * c;
        const Mat3 R1 = Eigen::Map<const Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(q + 12);
        const Vec3 t1(q[21], q[22], q[23]);
        const Real d = collider_world_distance(detail::load3(x, i), R1, t1, V.col_shape[c], &V.col_mesh, nullptr, nullptr);
        worst = fmax(worst, d > 0 ? len / (0.9 * d) : 1e12);
      }
      return worst;
    }, Exec::kParallelMinHeavy);
    return inv > 1.0 ? 1.0 / inv : 1.0;
  }

  /// Largest step fraction keeping every free vertex at least 10% of its distance above the
  /// table (continuous collision detection against a plane is exact and cheap).
  double table_ccd_bound() {
    if (!P_.table) return 1.0;
    const detail::View V = view();
    const detail::Params P = P_;
    const double* x = Exec::ptr(x_);
    const double* dx = Exec::ptr(dx_);
    // max over vertices of the inverse admissible fraction
    const double inv = Exec::max(n_, [=] GD_HD_LAMBDA(int i) {
      if (V.fixed[i]) return 0.0;
      const Real d = P.table_n.dot(detail::load3(x, i)) - P.table_offset;
      const Real dn = P.table_n.dot(detail::load3(dx, i));
      if (dn >= 0) return 0.0;
      return -dn / (0.9 * d);
    });
    return inv > 1.0 ? 1.0 / inv : 1.0;
  }

  /// Largest fraction of dx along which no candidate pair closes more than 90% of its gap above
  /// the CCD floor. The floor (a micrometre at the default dhat) keeps pairs far above the rounding
  /// of the distance and triangle-triangle tests: without it a pair the barrier could not stop
  /// (a gripper pulling cloth through cloth) closed to 1e-14 m over a few steps, the exact test then
  /// read the touching edges as crossing, and the untangling fail-safe made real crossings of them.
  /// A pair within twice the floor may close to about half its distance (ccd_floor_offset).
  double self_ccd_bound() {
    if (!self_ || cand_.n == 0) return 1.0;
    const detail::View V = view();
    const double* x = Exec::ptr(x_);
    const double* dx = Exec::ptr(dx_);
    const Real ccd_floor = P_.ccd_floor;
    const double inv = Exec::max(V.cand.n, [=] GD_HD_LAMBDA(int c) {
      const int* v = V.cand.v + 4 * c;
      const Vec3 a = detail::load3(x, v[0]), b = detail::load3(x, v[1]), q = detail::load3(x, v[2]),
                 d = detail::load3(x, v[3]);
      const Vec3 da = detail::load3(dx, v[0]), db = detail::load3(dx, v[1]), dq = detail::load3(dx, v[2]),
                 dd = detail::load3(dx, v[3]);
      const Real alpha =
          V.cand.type[c] == 0
              ? point_triangle_ccd(a, b, q, d, da, db, dq, dd, 0.0, kCcdGapFraction, kCcdMaxIterations, ccd_floor)
              : edge_edge_ccd(a, b, q, d, da, db, dq, dd, 0.0, kCcdGapFraction, kCcdMaxIterations, ccd_floor);
      return alpha >= 1.0 ? 0.0 : (alpha > 1e-12 ? 1.0 / alpha : 1e12);
    }, Exec::kParallelMinHeavy);
    return inv > 1.0 ? 1.0 / inv : 1.0;
  }

  /// Backtracking (Armijo) from alpha_max, given L(x) = e0; returns the accepted step fraction.
  /// Each trial also computes the gradient there (g_trial_): the next Newton iteration's residual
  /// check then needs no pass of its own. evals counts the evaluations.
  double line_search(double alpha_max, double e0, int* evals) {
    last_trial_alpha_ = -1;
    const double slope = dot(g_, dx_);
    double alpha = alpha_max;
    for (int k = 0; k < 20; ++k) {
      copy(x_, x_trial_);
      axpy(alpha, dx_, x_trial_);
      const double e = evaluate(x_trial_, g_trial_, false);
      ++*evals;
      if (std::isfinite(e) && e <= e0 + 1e-4 * alpha * std::min(slope, 0.0)) {
        last_trial_alpha_ = alpha;
        return alpha;
      }
      alpha *= 0.5;
    }
    return 0.0;
  }

  /// Largest grip spring pull over the held vertices, N.
  double max_grip_force() {
    const detail::View V = view();
    const detail::Params P = P_;
    const double* x = Exec::ptr(x_);
    return Exec::max(n_, [=] GD_HD_LAMBDA(int i) {
      return V.kin[i] ? grip_spring_force(detail::load3(x, i), detail::load3(V.kin_target, i),
                                          detail::grip_stiffness(P, V.mass[i]), P.kin_force_max)
                      : 0.0;
    });
  }

  void end_step() {
    const double inv_h = 1.0 / P_.h;
    const double* x = Exec::ptr(x_);
    const double* xt = Exec::ptr(x_t_);
    double* v = Exec::ptr(v_);
    Exec::for_each(3 * n_, [=] GD_HD_LAMBDA(int k) { v[k] = (x[k] - xt[k]) * inv_h; });
  }

  // --- vector kernels --------------------------------------------------------------------
  double dot(const Vec<double>& a, const Vec<double>& b) {
    const double* pa = Exec::ptr(a);
    const double* pb = Exec::ptr(b);
    return Exec::sum(3 * n_, [=] GD_HD_LAMBDA(int k) { return pa[k] * pb[k]; });
  }
  double max_abs(const Vec<double>& a) {
    const double* pa = Exec::ptr(a);
    return Exec::max(3 * n_, [=] GD_HD_LAMBDA(int k) { return fabs(pa[k]); });
  }
  void axpy(double a, const Vec<double>& xs, Vec<double>& ys) {
    const double* x = Exec::ptr(xs);
    double* y = Exec::ptr(ys);
    Exec::for_each(3 * n_, [=] GD_HD_LAMBDA(int k) { y[k] += a * x[k]; });
  }
  void xpby(const Vec<double>& xs, double b, Vec<double>& ys) {
    const double* x = Exec::ptr(xs);
    double* y = Exec::ptr(ys);
    Exec::for_each(3 * n_, [=] GD_HD_LAMBDA(int k) { y[k] = x[k] + b * y[k]; });
  }
  void scale(double a, Vec<double>& ys) {
    double* y = Exec::ptr(ys);
    Exec::for_each(3 * n_, [=] GD_HD_LAMBDA(int k) { y[k] *= a; });
  }
  void copy(const Vec<double>& src, Vec<double>& dst) {
    const double* s = Exec::ptr(src);
    double* d = Exec::ptr(dst);
    Exec::for_each(3 * n_, [=] GD_HD_LAMBDA(int k) { d[k] = s[k]; });
  }

 private:
  std::shared_ptr<const SceneData> data_;
  SceneOptions opt_;
  detail::Params P_;
  int n_ = 0;
  Vec<double> mass_;
  Vec<int> tris_, hinges_, row_ptr_, cols_, diag_, tri_slots_, hinge_slots_, fixed_, kin_flag_;
  Vec<StretchShearRest> tri_rest_;
  Vec<HingeRest> hinge_rest_;
  Vec<double> f_ext_;
  Vec<double> x_, v_, x_t_, v_t_, g_, dx_, r_, z_, p_, ap_, x_trial_, vals_, kin_target_, hinge_grad_t_;
  std::unique_ptr<Preconditioner<Exec>> precond_;
  std::unique_ptr<Preconditioner<Exec>> estimator_;  ///< MAS for the stopping rule when PCG's is not
  std::vector<int> kin_fixed_host_;
  // self-contact (host bookkeeping, device pair lists)
  std::unique_ptr<SelfContact> self_;
  double kappa_scale_ = 1;
  static constexpr double kKappaScaleMax = 1e4;  // adaptive barrier stiffness: at most this x
  /// adapt_barrier_stiffness halves the stiffness when every active pair is this far apart (x dhat).
  static constexpr double kRelaxGapFraction = 0.5;
  static constexpr double kPressedGapFloors = 10;  // stiffen_pressed_pairs: gap in CCD floors
  // kinematic colliders (host objects owned by the Scene; packed copies on the backend)
  const std::vector<Collider>* colliders_ = nullptr;
  double col_t1_ = 0;
  int n_col_ = 0;
  Vec<ColliderShape> col_shape_;
  Vec<Vec3> col_vertices_;
  Vec<Eigen::Vector3i> col_tris_;
  Vec<double> col_pose_, col_mu_;
  std::vector<double> host_x_, host_xt_, host_dx_;
  /// A pair list on the backend (candidates for the line search and CCD, active pairs for the Hessian).
  struct DevicePairs {
    int n = 0;
    Vec<int> v, type;
    Vec<double> kappa, eps;
    void upload(const ContactPairs& p) {
      n = p.size();
      Exec::upload(v, p.v);
      Exec::upload(type, p.type);
      Exec::upload(kappa, p.kappa);
      Exec::upload(eps, p.eps_x);
    }
    detail::PairView view() const {
      return {n, Exec::ptr(v), Exec::ptr(type), Exec::ptr(kappa), Exec::ptr(eps)};
    }
  };
  DevicePairs cand_, act_;
  int n_fr_ = 0;
  Vec<int> fr_v_;
  Vec<double> act_H_, fr_w_, fr_T_, fr_lambda_, fr_H_;
  Vec<double> act_gd_, fr_gd_;  ///< per pair: gradient (12) and diagonal blocks (4 x 9), see store_pair
  /// The contact pairs' off-diagonal blocks merged per vertex pair (merge_pair_blocks): built on
  /// the host (*_h_), handed to the backend.
  CouplingMatrix cpl_h_;  ///< merge_pair_blocks' host result (its storage reused)
  std::vector<double> host_act_H_, host_fr_H_;
  std::vector<double> chunk_energy_;  ///< sum_elements: per chunk (CPU)
  double free_mass_ = 1.0;           ///< free_mass()
  Vec<int> cpl_row_ptr_, cpl_cols_;
  Vec<double> cpl_vals_;
  bool precond_ready_ = false;  ///< precond_ was set up in this step (not with the direct solver)
  /// The step fraction of the line search's accepted trial (accept_step swaps it in).
  double last_trial_alpha_ = -1;
  Vec<double> g_trial_, cand_gd_;  ///< gradient at the trial point; candidate pairs' gradients
  Vec<int> live_;                  ///< per pair of the last evaluate_pairs: whether it added anything
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt_;
  bool ldlt_analyzed_ = false;
};

}  // namespace gd::sim
