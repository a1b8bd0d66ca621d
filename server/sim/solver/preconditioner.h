#pragma once
/// \file
/// Preconditioners of the PCG solve, behind one interface: block-Jacobi (the inverse of each
/// vertex's 3x3 diagonal block) and the multilevel additive Schwarz preconditioner of Wu et al.
/// 2022 (mas_preconditioner.h). Written over the execution policy like the solver.

#include <memory>

#include "sim/demand.h"
#include "sim/solver/options.h"
#include "sim/types.h"

namespace gd::sim {

/// What a preconditioner sees of the system (device or host pointers): the 3x3-block matrix of
/// the mesh pattern (row_ptr/cols/diag/vals), the contact couplings outside that pattern as a
/// second block CSR (cpl_*; null without self-contact), the Dirichlet flags (identity rows) and
/// the current positions (3n).
struct BlockMatrixView {
  int n = 0;
  const int* row_ptr = nullptr;
  const int* cols = nullptr;
  const int* diag = nullptr;
  const double* vals = nullptr;
  const int* fixed = nullptr;
  const int* cpl_row_ptr = nullptr;
  const int* cpl_cols = nullptr;
  const double* cpl_vals = nullptr;
  const double* x = nullptr;
};

template <class Exec>
class Preconditioner {
 public:
  virtual ~Preconditioner() = default;
  /// Called once per Newton iteration, after assembly.
  virtual void setup(const BlockMatrixView& A) = 0;
  /// z = M^-1 r (3n flat vectors).
  virtual void apply(const double* r, double* z) = 0;
  /// Whether M^-1 r estimates H^-1 r for smooth residuals too (a coarse level, as MAS has), so
  /// that the Newton stopping rule may use it to predict the next correction. Block-Jacobi
  /// underestimates a uniform force by the stiffness ratio and does not.
  virtual bool estimates_smooth_modes() const { return false; }
  /// Where M^-1 is block-diagonal: its 3x3 blocks, row-major, 9 per vertex (the backend's
  /// memory), so that PCG can apply it inside its update pass (Solver::pcg_update_precond_to);
  /// null otherwise.
  virtual const double* block_inverse() const { return nullptr; }
};

template <class Exec>
class BlockJacobi final : public Preconditioner<Exec> {
 public:
  explicit BlockJacobi(int n) : n_(n) { Exec::resize(inv_, 9 * static_cast<size_t>(n)); }

  void setup(const BlockMatrixView& A) override {
    double* inv = Exec::ptr(inv_);
    Exec::for_each(n_, [=] GD_HD_LAMBDA(int i) {
      Mat3 m = Mat3::Identity();
      if (!A.fixed[i]) {
        const double* b = A.vals + 9 * A.diag[i];
        Mat3 D;
        D << b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7], b[8];
        if (fabs(D.determinant()) > 1e-300) m = D.inverse();
      }
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) inv[9 * i + 3 * r + c] = m(r, c);
    }, Exec::kParallelMinHeavy);
  }

  void apply(const double* r, double* z) override {
    const double* inv = Exec::ptr(inv_);
    Exec::for_each(n_, [=] GD_HD_LAMBDA(int i) {
      const double* m = inv + 9 * i;
      const double r0 = r[3 * i], r1 = r[3 * i + 1], r2 = r[3 * i + 2];
      z[3 * i] = m[0] * r0 + m[1] * r1 + m[2] * r2;
      z[3 * i + 1] = m[3] * r0 + m[4] * r1 + m[5] * r2;
      z[3 * i + 2] = m[6] * r0 + m[7] * r1 + m[8] * r2;
    }, Exec::kParallelMinVector / 3);
  }

  const double* block_inverse() const override { return Exec::ptr(inv_); }

 private:
  int n_;
  typename Exec::template Vector<double> inv_;
};

}  // namespace gd::sim

#include "sim/solver/mas_preconditioner.h"

namespace gd::sim {

/// The preconditioner named by the options.
template <class Exec>
std::unique_ptr<Preconditioner<Exec>> make_preconditioner(const SceneOptions& opt, int n) {
  switch (effective_preconditioner(opt)) {
    case PreconditionerKind::kAuto:
    case PreconditionerKind::kBlockJacobi:
      return std::make_unique<BlockJacobi<Exec>>(n);
    case PreconditionerKind::kMas:
      return std::make_unique<MultilevelAdditiveSchwarz<Exec>>(n, opt.mas_domain_size);
  }
  GD_DEMAND(false, "unknown preconditioner kind");
  return nullptr;
}

}  // namespace gd::sim
