#pragma once
/// \file
/// The linear solve of each Newton iteration: the block matrix-vector product, the contact
/// couplings merged into a block CSR, PCG with the preconditioner, and sparse LDLT on the CPU.
/// Member functions of Solver<Exec> (solver_impl.h), written once for every backend.

#include "sim/solver/solver_impl.h"

namespace gd::sim {

/// y = A x over free vertices (Dirichlet rows and columns act as identity / zero), and x·y into
/// *xy (the backend's memory) in the same pass. Each row is summed in lanes (sim/block_row.h;
/// the CPU backend's with AVX2 where it can, the same bits). A Dirichlet column needs no test: assembly and
/// the couplings' merge leave its blocks zero (scatter and merge_pair_blocks skip it).
template <class Exec>
void Solver<Exec>::spmv_dot_to(const Vec<double>& xs, Vec<double>& ys, double* xy) {
  const detail::View V = view();
  const double* x = Exec::ptr(xs);
  double* y = Exec::ptr(ys);
  const BlockRows A{V.row_ptr, V.cols, Exec::ptr(vals_)};
  BlockRows C;  // the contact pairs' blocks
  if (self_) C = BlockRows{Exec::ptr(cpl_row_ptr_), Exec::ptr(cpl_cols_), Exec::ptr(cpl_vals_)};
  // A row's work: its blocks, the mesh's and the contact couplings' (rows where layers touch
  // carry more), and one block's worth for the row itself. The CPU deals the rows to its
  // threads by it (a GPU does not read it).
  auto work_before = [A, C](int i) -> int64_t {
    return static_cast<int64_t>(A.row_ptr[i]) + (C.row_ptr ? C.row_ptr[i] : 0) + i;
  };
  Exec::sum_effects_balanced_to(n_, [=] GD_HD_LAMBDA(int i) {
    const double* xi = x + 3 * i;
    if (V.fixed[i]) {
      detail::store3(y, i, detail::load3(x, i));
      return xi[0] * xi[0] + xi[1] * xi[1] + xi[2] * xi[2];
    }
    double acc[3];
    Exec::block_row(i, A, C, x, acc);  // sim/block_row.h
    y[3 * i] = acc[0], y[3 * i + 1] = acc[1], y[3 * i + 2] = acc[2];
    return xi[0] * acc[0] + xi[1] * acc[1] + xi[2] * acc[2];
  }, work_before, xy, Exec::kParallelMinHeavy);
}

/// The pairs' off-diagonal blocks summed per coupled (row, column) vertex pair into a block CSR
/// (cpl_*), once per linear solve, on the host for the CPU backend. The layers of a garment lying flat make ~8
/// contact pairs per vertex that share most of their vertex pairs, so each PCG iteration then
/// touches every coupling once instead of once per pair that contains it, rows are gathered
/// without atomics, and the preconditioner sees the couplings as a matrix. Policies without
/// kHostMerge (the GPU's) build it on the backend (coupling_merge.h) unless the scene outgrows its
/// keys; then the pairs' Hessians travel to the host and the CSR back.
template <class Exec>
void Solver<Exec>::merge_pair_blocks() {
  if constexpr (!Exec::kHostMerge) {
    if (backend_merge_fits()) return merge_pair_blocks_on_backend();  // coupling_merge.h
  }
  const int* VA = nullptr;
  const int* VF = nullptr;
  const double* HA = nullptr;
  const double* HF = nullptr;
  if constexpr (Exec::kHostMemory) {
    VA = act_.v.data();
    VF = fr_v_.data();
    HA = act_H_.data();
    HF = fr_H_.data();
  } else {
    Exec::download(host_act_v_, act_.v);
    Exec::download(host_fr_v_, fr_v_);
    Exec::download(host_act_H_, act_H_);
    Exec::download(host_fr_H_, fr_H_);
    VA = host_act_v_.data();
    VF = host_fr_v_.data();
    HA = host_act_H_.data();
    HF = host_fr_H_.data();
  }
  std::vector<PairHessians> lists(2);
  lists[0].count = act_.n, lists[0].v = VA, lists[0].H = HA;
  lists[1].count = n_fr_, lists[1].v = VF, lists[1].H = HF;
  gd::sim::merge_pair_blocks(n_, kin_fixed_host_.data(), lists, &cpl_h_);
  Exec::take(cpl_row_ptr_, cpl_h_.row_ptr);
  Exec::take(cpl_cols_, cpl_h_.cols);
  Exec::take(cpl_vals_, cpl_h_.vals);
}

/// Before a linear solve: the contact couplings as a matrix, then the preconditioners' setup.
template <class Exec>
void Solver<Exec>::prepare_linear_solve() {
  if (direct_solve()) return;
  precond_->setup(matrix_view());
  precond_ready_ = true;
}

/// Before a linear solve: the contact couplings as a matrix (PCG's and the preconditioners').
template <class Exec>
void Solver<Exec>::merge_couplings() {
  if (direct_solve()) return;
  if (self_) merge_pair_blocks();
}

/// After the preconditioner's setup: the stopping rule's own MAS instance, where PCG's
/// preconditioner is not one, ordered at this iterate (built by converged() if the step goes on).
template <class Exec>
void Solver<Exec>::order_estimator() {
  if (!precond_ready_ || !estimator_) return;
  estimator_->order(matrix_view());
  estimator_pending_ = true;
}

/// The assembled Hessian and contact couplings at x_, as the preconditioners read them.
template <class Exec>
BlockMatrixView Solver<Exec>::matrix_view() {
  BlockMatrixView A{n_, Exec::ptr(row_ptr_), Exec::ptr(cols_), Exec::ptr(diag_), Exec::ptr(vals_), Exec::ptr(fixed_)};
  if (self_) {
    A.cpl_row_ptr = Exec::ptr(cpl_row_ptr_);
    A.cpl_cols = Exec::ptr(cpl_cols_);
    A.cpl_vals = Exec::ptr(cpl_vals_);
  }
  A.x = Exec::ptr(x_);
  return A;
}

/// Solves H dx = -g. Returns the iterations spent (1 for the direct solver).
template <class Exec>
int Solver<Exec>::solve_linear(double first_step) {
  if constexpr (Exec::kHostMemory) {
    if (opt_.linear_solver == LinearSolverKind::kDirect) return solve_direct();
  }
  return solve_pcg(first_step);
}

/// PCG on H dx = -g with the preconditioner set up by prepare_linear_solve. Its scalars (alpha,
/// beta, the residual tests) live in the backend's memory (pcg_s_) and are computed there, so an
/// iteration needs no round trip to the host; the host reads the stop flag every
/// Exec::kPcgCheckEvery iterations (1 on the CPU, where reading costs nothing: the same control
/// flow as a plain loop; 8 on the GPU, where a stopped solve runs at most 7 iterations that
/// change nothing). Round trips per solve: r0, the iteration count, and one flag read per check.
template <class Exec>
int Solver<Exec>::solve_pcg(double first_step) {
  // With MAS, z = P⁻¹r estimates the correction PCG has still to make (as in converged()):
  // stop once it is a fraction of what the Newton rule will accept (pcg_newton_fraction), so the
  // linear solve is no more exact than the Newton iteration needs. In the first Newton iteration
  // the step built so far stands for the first step (it only grows, so the test stays strict).
  const bool newton_stop = residual_rule() && opt_.pcg_newton_fraction > 0 && precond_->estimates_smooth_modes();
  // A block-diagonal preconditioner (block-Jacobi) is applied inside the update pass, which then
  // also takes r·z: three passes over the vectors per iteration instead of six.
  const double* block_diag = newton_stop ? nullptr : precond_->block_inverse();
  Exec::fill(dx_, 0.0);
  copy(g_, r_);
  scale(-1.0, r_);  // r = -g (free rows; Dirichlet rows of g are zero)
  const double r0 = std::sqrt(dot(r_, r_));
  if (r0 == 0.0) return 0;
  precond_->apply(Exec::ptr(r_), Exec::ptr(z_));
  copy(z_, p_);
  Exec::fill(pcg_s_, 0.0);
  double* S = Exec::ptr(pcg_s_);
  dot_to(r_, z_, S + kPcgRz);
  // The scalar steps, each one thread of work on the backend.
  const double tol_r = opt_.pcg_tol * r0;
  const double fraction = opt_.pcg_newton_fraction, atol = opt_.newton_atol, rtol = opt_.newton_rtol;
  const double mass = free_mass(), h = P_.h;  // rms_velocity's arithmetic, on the backend
  const double first = first_step;
  auto stopped = [&] { return Exec::read(pcg_s_, kPcgStop) != 0.0; };
  const int cap = effective_pcg_max_iters(opt_, n_);
  for (int k = 0; k < cap; ++k) {
    const bool check = (k + 1) % Exec::kPcgCheckEvery == 0;
    spmv_dot_to(p_, ap_, S + kPcgPap);  // Ap, and pAp
    Exec::for_each(1, [=] GD_HD_LAMBDA(int) {  // alpha = rz / pAp, or stop where pAp is not positive
      const double pap = S[kPcgPap];
      if (S[kPcgStop] == 0.0 && !(pap > 0)) S[kPcgStop] = 1.0;
      S[kPcgAlpha] = S[kPcgStop] == 0.0 ? S[kPcgRz] / pap : 0.0;
      if (S[kPcgStop] == 0.0) S[kPcgIters] += 1.0;
    });
    if (block_diag) {  // dx += alpha p, r -= alpha Ap, |r|², z = D r and r·z in one pass
      pcg_update_precond_to(S + kPcgAlpha, p_, ap_, dx_, r_, block_diag, z_, S + kPcgRr, S + kPcgRzNew);
    } else {
      pcg_update_to(S + kPcgAlpha, p_, ap_, dx_, r_, S + kPcgRr);  // dx += alpha p, r -= alpha Ap, |r|²
    }
    Exec::for_each(1, [=] GD_HD_LAMBDA(int) {  // the relative residual test
      if (std::sqrt(S[kPcgRr]) <= tol_r) S[kPcgStop] = 1.0;
    });
    if (Exec::kPcgCheckEvery == 1 && stopped()) break;
    if (!block_diag) precond_->apply(Exec::ptr(r_), Exec::ptr(z_));
    if (newton_stop) {
      mass_norm_to(z_, S + kPcgZm);
      if (first <= 0) mass_norm_to(dx_, S + kPcgDxm);
      Exec::for_each(1, [=] GD_HD_LAMBDA(int) {  // the correction still to come against the Newton rule
        const double built = first > 0 ? first : std::sqrt(S[kPcgDxm] / mass) / h;
        const double target = fmax(atol, rtol * built);
        if (std::sqrt(S[kPcgZm] / mass) / h <= fraction * target) S[kPcgStop] = 1.0;
      });
      if (Exec::kPcgCheckEvery == 1 && stopped()) break;
    }
    if (!block_diag) dot_to(r_, z_, S + kPcgRzNew);
    Exec::for_each(1, [=] GD_HD_LAMBDA(int) {  // beta = rz_new / rz (0 once stopped)
      S[kPcgBeta] = S[kPcgStop] == 0.0 ? S[kPcgRzNew] / S[kPcgRz] : 0.0;
      if (S[kPcgStop] == 0.0) S[kPcgRz] = S[kPcgRzNew];
    });
    xpby_scalar(z_, S + kPcgBeta, p_);  // p = z + beta p
    if (check && stopped()) break;
  }
  return static_cast<int>(Exec::read(pcg_s_, kPcgIters));
}

/// Sparse Cholesky on the CPU (DirectSolver: validation and small scenes).
template <class Exec>
int Solver<Exec>::solve_direct() {
  if constexpr (Exec::kHostMemory) {
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
      auto add_pairs = [&](const Vec<int>& vs, int count, const Vec<double>& Hs) {
        for (int c = 0; c < count; ++c)
          for (int a = 0; a < 4; ++a)
            for (int b = a + 1; b < 4; ++b)
              for (int r = 0; r < 3; ++r)
                for (int k = 0; k < 3; ++k) {  // block (a, b) and its transpose (b, a)
                  const double h = Hs[kPairBlockValues * c + pair_block_offset(a, b) + 3 * r + k];
                  if (h == 0.0) continue;
                  trip.emplace_back(3 * vs[4 * c + a] + r, 3 * vs[4 * c + b] + k, h);
                  trip.emplace_back(3 * vs[4 * c + b] + k, 3 * vs[4 * c + a] + r, h);
                }
      };
      add_pairs(act_.v, act_.n, act_H_);
      add_pairs(fr_v_, n_fr_, fr_H_);
    }
    Eigen::SparseMatrix<double> A(3 * n_, 3 * n_);
    A.setFromTriplets(trip.begin(), trip.end());
    // Contact pairs add entries that change from one solve to the next: the ordering is computed
    // again where the pattern changed (DirectSolver::factorize).
    Eigen::Map<const Eigen::VectorXd> g(g_.data(), 3 * n_);
    Eigen::Map<Eigen::VectorXd> dx(dx_.data(), 3 * n_);
    if (!direct_) direct_ = std::make_unique<DirectSolver>();
    if (!direct_->factorize(A)) {
      if (self_) merge_pair_blocks();
      precond_->setup(matrix_view());
      return solve_pcg(0);
    }
    direct_->solve(-g, dx);
    return 1;
  } else {
    return solve_pcg(0);
  }
}

}  // namespace gd::sim
