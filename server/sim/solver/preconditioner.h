#pragma once
/// \file
/// Preconditioners of the PCG solve, behind one interface. Block-Jacobi (the inverse of each
/// vertex's 3x3 diagonal block) is what exists; the multilevel additive Schwarz preconditioner
/// (Wu et al. 2022) plugs in here. Written over the execution policy like the solver.

#include <memory>

#include "sim/demand.h"
#include "sim/solver/options.h"
#include "sim/types.h"

namespace gd::sim {

/// What a preconditioner sees of the system: the 3x3-block matrix (row_ptr/cols/diag/vals,
/// device or host pointers) and the Dirichlet flags (identity rows).
struct BlockMatrixView {
  int n = 0;
  const int* row_ptr;
  const int* cols;
  const int* diag;
  const double* vals;
  const int* fixed;
};

template <class Exec>
class Preconditioner {
 public:
  virtual ~Preconditioner() = default;
  /// Called once per Newton iteration, after assembly.
  virtual void setup(const BlockMatrixView& A) = 0;
  /// z = M^-1 r (3n flat vectors).
  virtual void apply(const double* r, double* z) = 0;
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
    });
  }

  void apply(const double* r, double* z) override {
    const double* inv = Exec::ptr(inv_);
    Exec::for_each(n_, [=] GD_HD_LAMBDA(int i) {
      const double* m = inv + 9 * i;
      const double r0 = r[3 * i], r1 = r[3 * i + 1], r2 = r[3 * i + 2];
      z[3 * i] = m[0] * r0 + m[1] * r1 + m[2] * r2;
      z[3 * i + 1] = m[3] * r0 + m[4] * r1 + m[5] * r2;
      z[3 * i + 2] = m[6] * r0 + m[7] * r1 + m[8] * r2;
    });
  }

 private:
  int n_;
  typename Exec::template Vector<double> inv_;
};

/// The preconditioner named by the options.
template <class Exec>
std::unique_ptr<Preconditioner<Exec>> make_preconditioner(PreconditionerKind kind, int n) {
  switch (kind) {
    case PreconditionerKind::kBlockJacobi:
      return std::make_unique<BlockJacobi<Exec>>(n);
  }
  GD_DEMAND(false, "unknown preconditioner kind");
  return nullptr;
}

}  // namespace gd::sim
