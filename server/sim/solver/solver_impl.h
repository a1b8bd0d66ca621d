#pragma once
/// \file
/// The implicit-Euler solver, written once over an execution policy `Exec` (CpuExec: OpenMP,
/// CudaExec: kernels, CpuGpuPathsExec: the kernels' paths on OpenMP). Paths differ only by the
/// policy's traits (kColoring, kHostMemory, kHostMerge), never by its type. One step minimises
///   L(x) = 1/(2h^2)|x - x_hat|_M^2 + E_membrane + E_bend + E_gravity + E_table + E_friction
///          + D_drag + D_damping
/// with a few inexact Newton iterations: assemble the gradient and PSD-projected Hessian, solve
/// with PCG (MAS or block-Jacobi, SceneOptions::preconditioner), cap the step by CCD (table,
/// colliders, self-contact pairs), and backtrack until L decreases. Dirichlet (kinematic) vertices are set to their targets and
/// removed from the solve. Included only by the backend translation units.
///
/// This file holds the class, its constructor, the step driver (the table of contents) and the
/// SolverBase interface; the per-element terms are in element_terms.h and each stage's member
/// functions in a file of its own (predictor.h, contact_stage.h, candidates.h, active_set.h,
/// stopping_rule.h, assembly.h, linear_solve.h, step_bounds.h, vector_ops.h, diagnostics.h),
/// included at the end.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <type_traits>

#include "sim/contact/lbvh_broad_phase.h"
#include "sim/contact/surface_samples.h"
#include "sim/solver/direct_solver.h"
#include "sim/solver/element_terms.h"
#include "sim/solver/pair_blocks.h"
#include "sim/solver/preconditioner.h"
#include "sim/solver/self_contact.h"
#include "sim/solver/solver.h"
#include "sim/log.h"

namespace gd::sim {

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
    hinge_rest_host_ = d.hinge_rest;
    hinge_clamped_.assign(d.hinge_count(), 0);
    {  // bending friction's sliders start unloaded at the rest angles
      std::vector<double> theta_f(d.hinge_count());
      for (int h = 0; h < d.hinge_count(); ++h) {
        theta_f[h] = d.hinge_rest[h].theta0;
        bend_friction_ = bend_friction_ || d.hinge_rest[h].friction_moment > 0;
      }
      Exec::upload(hinge_theta_f_, theta_f);
    }
    Exec::upload(row_ptr_, d.row_ptr);
    Exec::upload(cols_, d.cols);
    Exec::upload(diag_, d.diag);
    Exec::upload(tri_slots_, d.tri_slots);
    Exec::upload(hinge_slots_, d.hinge_slots);
    Exec::upload(x_, d.x);
    Exec::upload(v_, d.v);
    for (auto* vec : {&x_t_, &v_t_, &g_, &g_trial_, &dx_, &dx_full_, &r_, &z_, &p_, &ap_, &x_trial_}) Exec::resize(*vec, 3 * n_);
    Exec::resize(vals_, 9 * static_cast<size_t>(d.blocks()));
    Exec::resize(pcg_s_, kPcgScalars);
    Exec::resize(red_, kReductions);
    host_red_.assign(kReductions, 0.0);
    Exec::resize(hinge_grad_t_, 12 * static_cast<size_t>(d.hinge_count()));
    if (!Exec::kColoring && opt.deterministic) {  // atomic policy asked for fixed-order sums
      deterministic_ = true;
      tri_order_.upload(color_elements(d.tris, 3, n_, 1));
      hinge_order_.upload(color_elements(d.hinges, 4, n_, 1));
      Exec::resize(elem_e_, static_cast<size_t>(std::max(d.triangles(), d.hinge_count())));
    }
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

    P_.gravity = opt.gravity;
    P_.table = opt.table;
    P_.table_n = Vec3::UnitZ();
    P_.table_offset = opt.table_height;
    P_.dhat = effective_contact_distance(opt, d.thickness);
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
    select_contact_hessian(false);
    P_.membrane_ref = d.stiffness_ref;
    P_.kin_stiffness = opt.grip_stiffness;
    P_.kin_force_max = opt.grip_force_limit;
    P_.self_contact = opt.self_contact && d.triangles() > 1;
    if (P_.self_contact) {
      P_.dhat_self = P_.dhat;
      P_.ccd_floor = kCcdFloorFraction * P_.dhat_self;
      P_.mu_self = opt.self_friction >= 0 ? opt.self_friction : d.friction;
      // The LBVH on this policy (the solver queries it on the backend: candidates.h), or Embree.
      const auto make_broad_phase = [&](const std::vector<int>& tris, const std::vector<Eigen::Vector2i>& edges,
                                        int n) -> std::unique_ptr<BroadPhase> {
        if (opt.broad_phase == BroadPhaseKind::kEmbree) return make_embree_broad_phase(tris, edges, n);
        auto lbvh = std::make_unique<LbvhBroadPhase<Exec>>(tris, edges, n);
        pair_bp_ = lbvh.get();
        return lbvh;
      };
      self_ = std::make_unique<SelfContact>(d, P_.dhat_self, make_broad_phase, opt.self_contact_pair_budget);
      Exec::upload(edges_, self_->edges());
      Exec::upload(edge_len2_, self_->edge_rest_length2());
      for (auto* vec : {&x1_, &qlo_, &qhi_, &mlo_, &mhi_}) Exec::resize(*vec, 3 * n_);
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
    const long halvings_at_start = self_ ? self_->flood_halvings() : 0;
    timed(T.predictor, [&] { begin_step(kin, quasi_static); });   // lagged data, Dirichlet targets, predictor
    begin_pad_dofs();                                               // hands stopped short join the solve
    bool gradient_known = false;                                    // g_ is the gradient at x (line search)
    double scale = 0;                                               // the first Newton step's size, m/s
    double taken = 0;                                               // the last correction made, m/s
    const int newton_cap = newton_max_iters();                      // higher while fingers pinch the cloth
    for (int k = 0; k < newton_cap; ++k) {
      if (k > 0 && residual_rule() && pads_settled() && converged(&st, k, gradient_known, scale, taken))
        break;                                                      // residual small
      timed(T.contacts, [&] { select_contacts(); });                // active self-contact pairs at x
      double e0 = 0;
      timed(T.assembly, [&] { e0 = assemble() + pad_spring_energy(0.0); });  // L, gradient and PSD Hessian at x
      if (!std::isfinite(e0)) {                                     // e.g. a target that tears the cloth apart
        gd::log().warn("newton {}: the energy at the iterate is not finite: {}", k, infinite_terms());
        st.finite = false;
        break;
      }
      if (k == 0 && residual_rule() && pad_hands_.empty() && predictor_converged(&st)) break;  // nothing left to solve
      timed(T.couplings, [&] { merge_couplings(); });               // contact pairs' blocks as a matrix
      timed(T.precond, [&] { prepare_linear_solve(); });            // PCG's preconditioner
      timed(T.stopping, [&] { order_estimator(); });                // the stopping rule's, ordered at x
      timed(T.pcg, [&] { st.pcg_iters += solve_with_pads(scale); });  // dx = -H^-1 g (inexact), hands too
      bool direction_finite = true;
      timed(T.contacts, [&] { direction_finite = find_contacts_along_step(); });  // broad phase on x -> x + dx
      if (!direction_finite) {                                      // a linear solve that broke down
        gd::log().warn("newton {}: the Newton direction is not finite", k);
        st.finite = false;
        break;
      }
      double alpha_max = 1, alpha = 0;
      timed(T.ccd, [&] { alpha_max = std::min(max_step(), pad_step_bound()); });  // CCD: largest safe fraction of dx
      timed(T.line_search, [&] { alpha = step_length(alpha_max, e0, &st); });  // table cut or Armijo backtracking
      gradient_known = accept_step(alpha);                          // x += alpha dx
      st.newton_iters = k + 1;
      st.min_alpha = std::min(st.min_alpha, alpha);
      const double* dxn = dx_norms();                               // |dx|_M and max |dx|, read together
      taken = alpha * rms_of_sum(dxn[kRedDxMass]);                  // the correction just made, m/s
      if (k == 0) scale = taken;
      st.step_norm = dxn[kRedDxMax] / P_.h;
      gd::log().trace("newton {}: step rms {:.3g} m/s (max |dx|/h {:.3g}), alpha {:.3g} (max {:.3g}), pcg {}, "
                      "candidates {}, evaluations {}", k, taken, st.step_norm, alpha, alpha_max, st.pcg_iters, cand_.n,
                      st.energy_evals);
      if (k > 0 && residual_rule() && correction_measures(alpha, alpha_max) && taken <= residual_threshold(scale) &&
          pads_settled() && !pressed() && pinch_settled(dx_, alpha, residual_threshold(scale))) {
        st.converged = true;                                        // last correction small, at the pinch too
        break;
      }
      // Also converged when the Newton direction itself is small: a step cut short by CCD or the
      // line search (alpha << 1) moves little without being at the minimum.
      if (st.step_norm < opt_.newton_tol && pads_settled()) {
        st.converged = true;
        break;
      }
    }
    end_step();                                                     // v = (x - x_t)/h
    if (bend_friction_) slip_bending_friction();                    // bending friction's sliders follow
    if (self_) st.min_self_distance = min_active_distance(x_, x_gen_);  // closest active pair
    st.max_grip_force = max_grip_force();
    adapt_barrier_stiffness(st.min_self_distance);                  // stiffer barriers if gaps got tiny
    st.barrier_scale = kappa_scale_;
    check_intersections(&st);                                       // exact count; untangle if any (fail-safe)
    if (self_) {
      st.contacts = act_.n;
      st.candidates = cand_.n;
      st.broad_phase_seconds = self_->broad_phase_seconds() - bp_seconds_at_start;
      st.broad_phase_queries = static_cast<int>(self_->broad_phase_queries() - bp_queries_at_start);
      st.flood_halvings = static_cast<int>(self_->flood_halvings() - halvings_at_start);
      st.contact_hessian = contact_kind_;
    }
    st.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return st;
  }

  void get_positions(std::vector<double>& x) override { Exec::download(x, x_); }
  void get_velocities(std::vector<double>& v) override { Exec::download(v, v_); }
  void set_state(const std::vector<double>& x, const std::vector<double>& v) override {
    Exec::upload(x_, x);
    Exec::upload(v_, v);
    moved_x();
  }

  void set_external_forces(const std::vector<double>& f) override { Exec::upload(f_ext_, f); }

  void set_colliders(const std::vector<Collider>& colliders, double t0, double t1) override {
    colliders_ = &colliders;
    col_t1_ = t1;
    col_t0_ = t0;
    n_col_ = static_cast<int>(colliders.size());
    col_reached_.assign(n_col_, 1.0);
    col_clear_.assign(n_col_, 0);
    col_end_.clear();
    select_contact_hessian(n_col_ > 0);  // SceneOptions::contact_hessian's kAuto
    samp_live_ = false;
    if (n_col_ == 0) return;
    PackedColliders packed = pack_colliders(colliders);
    for (ColliderShape& s : packed.shapes) s.mesh_cull = 2 * P_.dhat;  // meshes: the far cull (collider.h)
    std::vector<double> poses, mu, kappa;
    for (const Collider& c : colliders) {
      for (const double t : {t0, t1}) {
        const Eigen::Isometry3d p = c.checked_pose(t);
        for (int r = 0; r < 3; ++r)
          for (int k = 0; k < 3; ++k) poses.push_back(p.linear()(r, k));
        for (int r = 0; r < 3; ++r) poses.push_back(p.translation()[r]);
      }
      col_end_.push_back(c.checked_pose(t1));
      mu.push_back(c.friction());
      kappa.push_back(c.stiffness_scale());
    }
    Exec::upload(col_shape_, packed.shapes);
    Exec::upload(col_vertices_, packed.vertices);
    Exec::upload(col_tris_, packed.triangles);
    Exec::upload(col_pose_, poses);
    col_pose_host_ = std::move(poses);
    Exec::upload(col_mu_, mu);
    Exec::upload(col_kappa_, kappa);
    pad_hands_.clear();
    still_colliders();
    build_samples();
    if (opt_.pad_stiffness > 0) {  // host copies for the pads' couplings (pads_in_solve.h)
      col_shape_host_ = std::move(packed.shapes);
      col_vertices_host_ = std::move(packed.vertices);
      col_tris_host_ = std::move(packed.triangles);
      col_mu_host_ = std::move(mu);
      col_kappa_host_ = std::move(kappa);
    }
  }

  // The stages, declared here and defined one file each (included at the end of this file). They
  // are public only because nvcc requires the functions that enclose extended __host__ __device__
  // lambdas to be public; SolverBase is the interface.

  // Start, accept and end of a step (predictor.h)
  void begin_step(const KinematicTargets& kin, bool quasi_static);
  int newton_max_iters() const;
  void clamp_hinges(const std::vector<int>& fixed, const std::vector<int>& gripped);
  bool accept_step(double alpha);
  void end_step();
  void slip_bending_friction();

  // Self-contact pair lists, barrier stiffness, intersection check (contact_stage.h)
  void select_contacts();
  bool find_contacts_along_step();
  void adapt_barrier_stiffness(double min_distance);
  void stiffen_pressed_pairs(double closest);
  void scale_barrier_stiffness(double factor);
  void check_intersections(StepStats* st);
  double max_grip_force();

  // The candidates of a motion from the broad phase's last answer, on the backend (candidates.h)
  int find_candidates(const Vec<double>& x0, Vec<double>& x1, bool refuse_non_finite);
  bool motion_covered(const Vec<double>& x0, const Vec<double>& x1, bool* finite);
  bool query_pairs(const Vec<double>& x0, const Vec<double>& x1, bool finite, std::size_t max_pairs);
  double longest_move(const Vec<double>& x0, const Vec<double>& x1);
  double select_along(const Vec<double>& xs, int gen);
  /// The host's SelfContact (its broad phase and counters), for tests and reports.
  const SelfContact* self_contact() const { return self_.get(); }

  // The active pairs, their distances and friction frames on the backend (active_set.h)
  double select_active(const Vec<double>& xs, int gen);
  template <class Source>
  double select_from(const Source& S, int n, const Vec<double>& xs, int gen);
  double min_active_distance(const Vec<double>& xs, int gen);
  void build_friction(const Vec<double>& xs, int gen);
  void store_candidate_distances(int gen);
  void scale_pair_stiffness(double factor);
  /// The backend's lists on the host (tests and diagnostics).
  struct FrictionPairs {
    std::vector<int> v;                 ///< 4 per pair
    std::vector<double> w, T, lambda;  ///< 4 weights, the 3x2 tangent basis (column-major), the normal force
  };
  ContactPairs active_pairs() const { return act_.to_host(); }
  ContactPairs candidate_pairs() const { return cand_.to_host(); }
  FrictionPairs friction_pairs() const;
  /// The closest active pair at x_, m (infinity when none).
  double closest_active_pair() { return min_active_distance(x_, x_gen_); }

  // Newton stopping rule (stopping_rule.h)
  bool converged(StepStats* st, int k, bool gradient_known, double scale, double last_taken);
  bool pressed();
  bool predictor_converged(StepStats* st);
  double residual_bound();
  void update_free_mass();
  double rms_velocity(const Vec<double>& d);
  void rms_velocity_to(const Vec<double>& d, double* out);
  double rms_of_sum(double num) const { return std::sqrt(num / free_mass()) / P_.h; }
  double pinch_rms_velocity(const Vec<double>& d, double scale);
  double pinch_residual_bound();
  bool pinch_settled(const Vec<double>& d, double scale, double threshold);
  bool correction_measures(double alpha, double alpha_max) const;

  // L, its gradient and PSD-projected Hessian (assembly.h)
  double assemble();
  double evaluate(const Vec<double>& xs, Vec<double>& gs, bool hessian);
  void evaluate_pairs(const double* x, double* g, double* H, double* e_pairs, double* e_friction);
  GD_HD static void store_pair(const detail::View& V, const int* vs, const Vec12& ge, const Mat12* Hp,
                               double* Hpair, double* gd);
  GD_HD static void add_pair(const detail::View& V, const int* vs, const double* gd, double* g, double* H,
                              int owner = 0, int owners = 1);
  template <int K>
  GD_HD static void scatter(const detail::View& V, const int* vs, const int* slots, const VecN<3 * K>& ge,
                            const MatN<3 * K>& He, double* g, double* H);
  GD_HD static void scatter_rank2(const detail::View& V, const int* vs, const int* slots, const Vec12& ge,
                                  const detail::HingeHessian& He, double* g, double* H);
  /// An element colouring of single elements on the backend (SceneOptions::deterministic on an
  /// atomic policy): element ids colour by colour, the colours' offsets on the host.
  struct ElementOrder {
    Vec<int> elems;
    std::vector<int> offsets;
    void upload(const Coloring& c) {
      Exec::upload(elems, c.chunks);
      offsets = c.offsets;
    }
  };
  template <class F>
  void sum_elements(const Coloring& coloring, const ElementOrder& order, int count, const F& f, double* out);
  void add_pairs_in_order(const detail::View& V, const detail::PairView& L, const int* live, const double* GA,
                          const double* GF, int gs, double* g, double* H);

  // Linear solve: matrix-vector product, contact couplings, PCG, direct (linear_solve.h)
  void spmv_dot_to(const Vec<double>& xs, Vec<double>& ys, double* xy);  ///< y = A x, and x·y into *xy
  void merge_pair_blocks();
  // ... on the backend, the GPU's path (coupling_merge.h)
  bool backend_merge_fits() const;
  void merge_pair_blocks_on_backend();
  void merge_couplings();
  void prepare_linear_solve();
  void order_estimator();
  BlockMatrixView matrix_view();
  int solve_linear(double first_step);
  int solve_pcg(double first_step);
  int solve_direct();

  // CCD step bounds and line search (step_bounds.h)
  double max_step();
  /// The CCD bounds along dx_ (1 where none applies), read back together.
  struct CcdBounds {
    double table = 1, self = 1, collider = 1;
  };
  CcdBounds ccd_bounds(bool table, bool self, bool collider, bool slope = false);
  void collider_step_inverse_to(double* out);
  void table_ccd_inverse_to(double* out);
  void self_ccd_inverse_to(double* out);
  double step_length(double alpha_max, double e0, StepStats* st);
  double table_cut_step(double alpha_max, double e0, int* evals);
  double line_search(double alpha_max, double e0, int* evals);

  // Vector operations over 3n values (vector_ops.h)
  double dot(const Vec<double>& a, const Vec<double>& b);
  void max_abs_to(const Vec<double>& a, double* out);
  /// |dx_|²_M and max |dx_| into their slots of red_, read back together (host_red_).
  const double* dx_norms() {
    rms_velocity_to(dx_, Exec::ptr(red_) + kRedDxMass);
    max_abs_to(dx_, Exec::ptr(red_) + kRedDxMax);
    return read_reductions();
  }
  void axpy(double a, const Vec<double>& xs, Vec<double>& ys);
  void xpby(const Vec<double>& xs, double b, Vec<double>& ys);
  void scale(double a, Vec<double>& ys);
  void copy(const Vec<double>& src, Vec<double>& dst);
  // ... and with the result or a coefficient in the backend's memory (no round trip to the host)
  void dot_to(const Vec<double>& a, const Vec<double>& b, double* out, int parallel_min = Exec::kParallelMinVector);
  void mass_norm_to(const Vec<double>& d, double* out);  ///< sum of m_i |d_i|² over free vertices
  /// x += a p, r -= a q and |r|² into *rr, one pass (PCG's update; a in the backend's memory).
  void pcg_update_to(const double* a, const Vec<double>& ps, const Vec<double>& qs, Vec<double>& xs, Vec<double>& rs,
                     double* rr);
  /// The same update with a block-diagonal preconditioner applied in the same pass: also z = D r
  /// (D: 9 values per vertex) and r·z into *rz.
  void pcg_update_precond_to(const double* a, const Vec<double>& ps, const Vec<double>& qs, Vec<double>& xs,
                             Vec<double>& rs, const double* D, Vec<double>& zs, double* rr, double* rz);
  void xpby_scalar(const Vec<double>& xs, const double* b, Vec<double>& ys);  ///< y = x + b y

  // Energies, strain and memory for reports (diagnostics.h)
  EnergyReport energies() override;
  std::vector<double> collider_forces() override;
  std::vector<double> collider_pushes() override;
  std::vector<double> collider_reached() const override { return col_reached_; }
  /// Which barriers are infinite at x_ (a diagnostic for a failed step): vertices inside each
  /// collider's end pose or below the table, and the closest self-contact pair.
  std::string infinite_terms();
  /// Whether a free vertex of x (host, 3 per vertex), or with `samples` a surface sample, lies on
  /// or inside a collider's end pose.
  bool inside_a_collider(const std::vector<double>& x, bool samples = false) const;
  void project_out_of_colliders(bool skip_clear, bool skip_yielding);  ///< predictor.h
  void stop_yielding_colliders();                    ///< predictor.h
  void carry_pinched_cloth();                        ///< predictor.h
  bool guess_pinch_first();                          ///< predictor.h
  std::vector<std::vector<double>> yielding_clearances();  ///< predictor.h
  Eigen::Isometry3d pose_along(int k, double s) const;           ///< predictor.h
  void set_collider_end(int k, const Eigen::Isometry3d& pose);   ///< predictor.h
  // The pads in the solve (pads_in_solve.h; SceneOptions::pad_stiffness)
  void begin_pad_dofs();
  void set_pads_at(double alpha);
  Eigen::VectorXd solve_pad_complement(const Eigen::MatrixXd& S, const Eigen::VectorXd& r) const;
  double pad_spring_energy(double alpha) const;
  double pad_slope() const;
  void pad_couplings();
  int solve_with_pads(double first_step);
  double pad_step_bound() const;
  void move_pads(double alpha);
  bool pads_settled() const;
  void still_colliders();
  std::vector<double> still_moves() const;
  bool keeps_clear(int k, const Eigen::Isometry3d& pose, double b,
                   const std::vector<std::vector<double>>& keep) const;  ///< predictor.h
  Vec3 guess_at(int i, double b) const;              ///< predictor.h
  Vec3 sample_guess_at(int s, double b) const;       ///< predictor.h
  // The surface samples (surface_samples.h) against thin yielding colliders (sample_stage.h)
  void build_samples();
  Vec3 sample_at(const std::vector<double>& x, int s) const;
  void find_near_samples(const std::vector<double>& xa, const std::vector<double>& xb);
  bool samples_inside(int k, const std::vector<double>& x, const Eigen::Isometry3d& pose) const;
  void switch_samples();
  /// Surface samples (for tests and reports).
  const SurfaceSamples& surface_samples() const { return samples_; }
  /// How many samples the last step left out of its solve (inside a collider at Newton's guess).
  int samples_off() const { return static_cast<int>(samp_off_.size()); }
  bool pinched(int i) const;                         ///< predictor.h
  void log_what_cuts(const char* leg, const CcdBounds& b);  ///< predictor.h
  void log_what_stops(const std::vector<int>& stop, const std::vector<double>& reach, double b,
                      const std::vector<std::vector<double>>& keep) const;  ///< predictor.h
  double max_strain() override;
  size_t bytes() const override;

  std::string backend_name() const override { return Exec::kName; }

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
    V.hinge_theta_f = Exec::ptr(hinge_theta_f_);
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
    V.col_kappa = Exec::ptr(col_kappa_);
    V.col_move = Exec::ptr(col_move_);
    V.col_moving = !pad_hands_.empty();
    V.col_mesh = ColliderMeshView{Exec::ptr(col_vertices_), Exec::ptr(col_tris_)};
    V.col_sampled = Exec::ptr(col_sampled_);
    V.n_samp = samp_live_ ? samples_.size() : 0;
    V.samp_ptr = Exec::ptr(samp_ptr_);
    V.samp_tri = Exec::ptr(samp_tri_);
    V.samp_w = Exec::ptr(samp_w_);
    V.samp_mass = Exec::ptr(samp_mass_);
    V.samp_on = Exec::ptr(samp_on_);
    V.cand = cand_.view();
    V.act = act_.view();
    V.n_fr = n_fr_;
    V.fr_v = Exec::ptr(fr_v_);
    V.fr_w = Exec::ptr(fr_w_);
    V.fr_T = Exec::ptr(fr_T_);
    V.fr_lambda = Exec::ptr(fr_lambda_);
    return V;
  }

  /// Runs f and adds its wall time to `seconds` (the backend's queued work included).
  template <class F>
  static void timed(double& seconds, F&& f) {
    const auto t0 = std::chrono::steady_clock::now();
    f();
    Exec::sync();
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  }

  /// The pair Hessian the assembly makes, from SceneOptions::contact_hessian (kAuto: by whether the
  /// scene has colliders, effective_contact_hessian).
  void select_contact_hessian(bool colliders) {
    contact_kind_ = effective_contact_hessian(opt_, colliders);
    switch (contact_kind_) {
      case ContactHessianKind::kGaussNewton: P_.contact_hessian = HessianKind::kGaussNewton; break;
      case ContactHessianKind::kProjected: P_.contact_hessian = HessianKind::kProjected; break;
      default: P_.contact_hessian = HessianKind::kTermwise; break;
    }
  }

  /// Whether the residual stopping rule is on (SceneOptions::newton_rtol / newton_atol): in
  /// dynamic steps. Quasi-static steps (Scene::relax, static validation) are solves for an
  /// equilibrium, stopped by newton_tol and relax's own tolerance alone.
  bool residual_rule() const { return !P_.quasi_static && (opt_.newton_rtol > 0 || opt_.newton_atol > 0); }
  /// The velocity correction below which Newton stops, given the first Newton step's (m/s).
  double residual_threshold(double first_step) const {
    return std::max(opt_.newton_atol, opt_.newton_rtol * first_step);
  }

  /// Whether the linear solve is the sparse direct one (host memory only): no couplings' CSR and
  /// no preconditioner to prepare.
  bool direct_solve() const { return Exec::kHostMemory && opt_.linear_solver == LinearSolverKind::kDirect; }

  /// Total mass of the free vertices, kg (set by begin_step: the Dirichlet set changes only there).
  double free_mass() const { return free_mass_; }

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
  Vec<double> x_, v_, x_t_, v_t_, g_, dx_, dx_full_, r_, z_, p_, ap_, x_trial_, kin_target_, hinge_grad_t_;
  Vec<double> hinge_theta_f_;  ///< per hinge: bending friction's slider angle (bending_friction.h)
  bool bend_friction_ = false;  ///< some hinge has internal friction
  typename Exec::template LargeVector<double> vals_;  ///< the Hessian's 3x3 blocks (SceneData's pattern)
  std::unique_ptr<Preconditioner<Exec>> precond_;
  std::unique_ptr<MultilevelAdditiveSchwarz<Exec>> estimator_;  ///< MAS for the stopping rule when PCG's is not
  bool estimator_pending_ = false;  ///< estimator_ is ordered for the current matrix but not built
  std::vector<int> kin_fixed_host_;
  std::vector<HingeRest> hinge_rest_host_;  ///< hinge_rest_ as uploaded (clamp_hinges)
  std::vector<char> hinge_clamped_;         ///< per hinge: 0, or which wing (1: x2's, 2: x3's) is held
  std::vector<int> clamp_held_;             ///< the held vertices clamp_hinges last saw
  // self-contact (host bookkeeping, device pair lists)
  std::unique_ptr<SelfContact> self_;
  double kappa_scale_ = 1;
  ContactHessianKind contact_kind_ = ContactHessianKind::kAuto;  ///< select_contact_hessian's resolved kind
  static constexpr double kKappaScaleMax = 1e4;  // adaptive barrier stiffness: at most this x
  /// adapt_barrier_stiffness halves the stiffness when every active pair is this far apart (x dhat).
  static constexpr double kRelaxGapFraction = 0.5;
  static constexpr double kClearanceFloor = 1e-3;  // project_out_of_colliders: least clearance kept, in dhat
  static constexpr double kPinchReach = 4.0;  // carry_pinched_cloth: a pinched vertex's farthest pad, in dhat
  static constexpr double kPressedGapFloors = 10;  // stiffen_pressed_pairs: gap in CCD floors
  /// converged(): no estimate after a correction this many times the threshold (fold/5000: no
  /// step the estimate stopped had taken one above 9x; docs/physics.md "Thirty-fifth round").
  static constexpr double kEstimateRatio = 10;
  // kinematic colliders (host objects owned by the Scene; packed copies on the backend)
  const std::vector<Collider>* colliders_ = nullptr;
  double col_t1_ = 0;
  double col_t0_ = 0;
  int n_col_ = 0;
  /// Per collider: the fraction of its motion made this step (< 1: a yielding one stopped short)
  /// and its end pose there; the poses as uploaded (R0, t0, R1, t1 row-major, 24 per collider).
  std::vector<double> col_reached_;
  std::vector<char> col_clear_;  ///< stop_yielding_colliders: the guess is clear of it (no projection)
  std::vector<Eigen::Isometry3d> col_end_;
  std::vector<double> col_pose_host_;
  Vec<ColliderShape> col_shape_;
  Vec<Vec3> col_vertices_;
  Vec<Eigen::Vector3i> col_tris_;
  Vec<double> col_pose_, col_mu_, col_kappa_;
  std::vector<double> host_x_, host_xt_;
  /// The cloth's surface samples (sample_stage.h): built for the thinnest sampled collider's
  /// half thickness; samp_live_ while some collider of the scene is sampled (col_sampled_).
  SurfaceSamples samples_;
  bool samp_live_ = false;
  Vec<int> col_sampled_, samp_ptr_, samp_tri_, samp_on_;
  Vec<double> samp_w_, samp_mass_;
  std::vector<int> col_sampled_host_;
  std::vector<int> samp_off_;  ///< the samples switch_samples left out this step
  /// Per collider: the samples whose triangle comes within reach of it this step (find_near_samples).
  std::vector<std::vector<int>> samp_near_;
  /// A hand in the solve (pads_in_solve.h): its pads (colliders), how far along the step's motion
  /// they are (s, 0..1), the Newton direction's part for it (ds), the spring's K |path|^2, and its
  /// gradient, Hessian and coupling to the cloth (3 per vertex) at the current iterate.
  struct PadHand {
    int group = -1;
    std::vector<int> pads;
    double s = 1, ds = 0, k_path2 = 0, grad = 0, hess = 0;
    std::vector<double> coupling;
    std::vector<Eigen::Matrix<double, 3, 4>> rate;  ///< per pad: its displacement per unit s at p, A p + b
  };
  std::vector<PadHand> pad_hands_;
  /// A hand this close to an end of its step's motion (in s) is at it (solve_pad_complement).
  static constexpr double kPadEndTolerance = 1e-9;
  /// The least fraction of its direction a step the line search cut short must keep for its
  /// correction to end Newton (correction_measures).
  static constexpr double kMeasuredStepFraction = 0.5;
  double pad_moved_ = 0;  ///< the largest path a hand moved in the last Newton iteration, m
  Vec<double> col_move_;
  std::vector<ColliderShape> col_shape_host_;
  std::vector<Vec3> col_vertices_host_;
  std::vector<Eigen::Vector3i> col_tris_host_;
  std::vector<double> col_mu_host_, col_kappa_host_;
  /// The cloth pinched between a hand's pads this step (carry_pinched_cloth): per vertex its mass
  /// where pinched, else 0, and their total (0: no pinch; SceneOptions::pinch_stopping_rule).
  std::vector<double> pinch_w_host_;
  Vec<double> pinch_w_;
  double pinch_mass_ = 0;
  /// At least n values in v for the caller to overwrite, grown only: the pair lists and their
  /// scratch change length every Newton iteration, and a shrink then a grow would reallocate or
  /// zero megabytes each time.
  template <class T>
  static void grow_for_overwrite(Vec<T>& v, size_t n) {
    if (v.size() < n) Exec::resize_for_overwrite(v, n);
  }
  /// A pair list on the backend (candidates for the line search and CCD, active pairs for the
  /// Hessian), with each pair's index in the broad phase's answer (raw).
  struct DevicePairs {
    int n = 0;
    Vec<int> v, type, raw;
    Vec<double> kappa, eps;
    /// Room for `count` pairs whose values the caller writes (grown only: see grow_for_overwrite).
    void resize_for_overwrite(int count) {
      n = count;
      grow_for_overwrite(v, 4 * static_cast<size_t>(count));
      grow_for_overwrite(type, static_cast<size_t>(count));
      grow_for_overwrite(raw, static_cast<size_t>(count));
      grow_for_overwrite(kappa, static_cast<size_t>(count));
      grow_for_overwrite(eps, static_cast<size_t>(count));
    }
    void swap(DevicePairs& o) {
      std::swap(n, o.n);
      v.swap(o.v), type.swap(o.type), raw.swap(o.raw), kappa.swap(o.kappa), eps.swap(o.eps);
    }
    detail::PairView view() const {
      return {n, Exec::ptr(v), Exec::ptr(type), Exec::ptr(kappa), Exec::ptr(eps), Exec::ptr(raw)};
    }
    /// Writable pointers (select_active's compaction).
    detail::PairSlots slots() {
      return {Exec::ptr(v), Exec::ptr(type), Exec::ptr(kappa), Exec::ptr(eps), Exec::ptr(raw)};
    }
    ContactPairs to_host() const {
      ContactPairs p;
      if (n == 0) return p;
      Exec::download(p.v, v), Exec::download(p.type, type), Exec::download(p.kappa, kappa), Exec::download(p.eps_x, eps);
      p.v.resize(4 * static_cast<size_t>(n)), p.type.resize(n), p.kappa.resize(n), p.eps_x.resize(n);
      return p;
    }
  };
  DevicePairs cand_, act_;
  DevicePairs cand_next_;  ///< select_active's compacted candidates, swapped into cand_
  /// select_active's per-candidate distance and positions in the compacted lists (flags, then
  /// their exclusive scans); build_friction's per-active-pair results (11 values) and positions.
  Vec<double> pair_d_, fr_scratch_;
  Vec<int> keep_pos_, act_pos_, fr_pos_;
  /// Per pair of the broad phase's answer: its distance at positions of generation raw_stamp_
  /// (-1: none). Reset when the answer changes (a new query, SelfContact::pair_queries()).
  Vec<double> raw_dist_;
  Vec<int> raw_stamp_;
  bool act_raw_known_ = false;  ///< act_'s raw indices are the current answer's
  /// The LBVH broad phase on this policy (SelfContact's, null with Embree): the pair queries run
  /// on it and leave their answer in raw_vf_/raw_ee_.
  LbvhBroadPhase<Exec>* pair_bp_ = nullptr;
  /// The broad phase's last answer on the backend (Embree's on a host-memory policy: read from
  /// SelfContact's in place), the mesh's edges and their rest squared lengths, the boxes of the
  /// last query's motion and of the current one (3 per vertex each), and the end of the current
  /// motion.
  Vec<Eigen::Vector2i> raw_vf_, raw_ee_, edges_;
  Vec<double> edge_len2_, qlo_, qhi_, mlo_, mhi_, x1_;
  bool have_query_ = false;  ///< qlo_/qhi_ hold a query's boxes (its answer was kept)
  std::vector<double> host_q0_, host_q1_;  ///< a host query's motion (Embree; a non-finite motion's error)
  bool raw_in_self() const { return Exec::kHostMemory && pair_bp_ == nullptr; }
  const Eigen::Vector2i* raw_vf_ptr() const { return raw_in_self() ? self_->raw().vf.data() : Exec::ptr(raw_vf_); }
  const Eigen::Vector2i* raw_ee_ptr() const { return raw_in_self() ? self_->raw().ee.data() : Exec::ptr(raw_ee_); }
  int raw_vf_count() const { return static_cast<int>(pair_bp_ ? raw_vf_.size() : self_->raw().vf.size()); }
  int raw_ee_count() const { return static_cast<int>(pair_bp_ ? raw_ee_.size() : self_->raw().ee.size()); }
  /// Generations of x_'s and x_t_'s contents (bumped whenever x_ changes: pair distances are kept
  /// per generation, active_set.h); gen_counter_ the last one given.
  int x_gen_ = 0, xt_gen_ = 0, gen_counter_ = 0;
  void moved_x() { x_gen_ = ++gen_counter_; }
  std::vector<int> host_act_v_, host_fr_v_;  ///< merge_pair_blocks on the host for a GPU policy
  int n_fr_ = 0;
  Vec<int> fr_v_;
  Vec<double> act_H_, fr_w_, fr_T_, fr_lambda_, fr_H_;
  Vec<double> act_gd_, fr_gd_;  ///< per pair: gradient (12) and diagonal blocks (4 x 9), see store_pair
  /// The contact pairs' off-diagonal blocks merged per vertex pair (merge_pair_blocks): built on
  /// the host (*_h_), handed to the backend.
  CouplingMatrix cpl_h_;  ///< merge_pair_blocks' host result (its storage reused)
  std::vector<double> host_act_H_, host_fr_H_;
  std::vector<double> chunk_energy_;  ///< sum_elements: per chunk (CPU)
  /// SceneOptions::deterministic on an atomic policy: the element loops' single-element colourings,
  /// per-element energies (summed by one fixed-order reduction) and the pairs' sorted
  /// (vertex, pair corner) keys (add_pairs_in_order).
  bool deterministic_ = false;
  ElementOrder tri_order_, hinge_order_;
  Vec<double> elem_e_;
  Vec<uint64_t> pair_keys_;
  double free_mass_ = 1.0;           ///< free_mass()
  Vec<int> cpl_row_ptr_, cpl_cols_;
  Vec<double> cpl_vals_;
  /// merge_pair_blocks_on_backend's scratch: sorted block keys, run numbers, per block its first
  /// key and its row.
  Vec<uint64_t> mkeys_;
  Vec<int> mrun_, mblock_start_, mblock_row_;
  /// PCG's scalars in the backend's memory (solve_pcg), at these indices.
  Vec<double> pcg_s_;
  /// Reductions queued on the backend into these slots and read back together (read_reductions):
  /// one round trip for an evaluation's five energy terms (with the line search's slope, queued
  /// before its first trial), one for the CCD bounds, one for an accepted step's two norms.
  Vec<double> red_;
  std::vector<double> host_red_;
  static constexpr int kRedVertex = 0, kRedTriangles = 1, kRedHinges = 2, kRedPairs = 3, kRedFriction = 4,
                       kRedTable = 5, kRedSelf = 6, kRedCollider = 7, kRedSlope = 8, kRedDxMass = 9, kRedDxMax = 10,
                       kRedCandidates = 11, kRedActive = 12, kRedClosest = 13, kRedFrictionPairs = 14,
                       kRedMotionNonFinite = 15, kRedMotionUp = 16, kRedMotionDown = 19, kReductions = 22;
  /// The slots of red_, on the host (one copy from the backend).
  const double* read_reductions() {
    Exec::download_to(host_red_.data(), red_);
    return host_red_.data();
  }
  static constexpr int kPcgRz = 0, kPcgPap = 1, kPcgRr = 2, kPcgRzNew = 3, kPcgAlpha = 4, kPcgBeta = 5,
                       kPcgStop = 6, kPcgIters = 7, kPcgZm = 8, kPcgDxm = 9, kPcgScalars = 10;
  bool precond_ready_ = false;  ///< precond_ was set up in this step (not with the direct solver)
  /// The step fraction of the line search's accepted trial (accept_step swaps it in).
  double last_trial_alpha_ = -1;
  double table_bound_ = 1;  ///< the table's CCD bound on the current dx (max_step), for table_cut_step
  Vec<double> g_trial_, cand_gd_;  ///< gradient at the trial point; candidate pairs' gradients
  Vec<double> cand_d2_;            ///< per candidate: squared distance at the last evaluation without Hessian
  Vec<int> live_;                  ///< per pair of the last evaluate_pairs: whether it added anything
  std::unique_ptr<DirectSolver> direct_;  ///< kDirect's factorisation (made at the first direct solve)
};

}  // namespace gd::sim

// The stages, one file each (definitions of the member functions declared above).
#include "sim/solver/predictor.h"
#include "sim/solver/contact_stage.h"
#include "sim/solver/candidates.h"
#include "sim/solver/active_set.h"
#include "sim/solver/stopping_rule.h"
#include "sim/solver/assembly.h"
#include "sim/solver/linear_solve.h"
#include "sim/solver/coupling_merge.h"
#include "sim/solver/step_bounds.h"
#include "sim/solver/vector_ops.h"
#include "sim/solver/diagnostics.h"
#include "sim/solver/pads_in_solve.h"
#include "sim/solver/sample_stage.h"

#if !defined(__CUDACC__)
#include "sim/backend/cpu/exec_cpu.h"
namespace gd::sim {
// The CPU backend's two instances are compiled once, in backend/cpu/cpu_solver.cpp: a test that
// includes this header to reach a stage links them instead of compiling the whole solver again
// (each such test's unity batch took ~2 min to compile).
extern template class Solver<CpuExec>;
extern template class Solver<CpuGpuPathsExec>;
}  // namespace gd::sim
#endif
