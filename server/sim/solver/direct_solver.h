#pragma once
/// \file
/// The sparse direct solve of SceneOptions::linear_solver = kDirect (CPU only): a supernodal
/// Cholesky factorisation by SuiteSparse's CHOLMOD (Debian libsuitesparse-dev) behind a narrow
/// interface, so that neither CHOLMOD's headers nor its workspace reach the solver's templates
/// (which nvcc compiles too). On a Cusick drape's Newton matrix (2791 vertices, 8373 unknowns) it
/// factorised in 29 ms where Eigen's SimplicialLDLT, which it replaced, took about 80 ms
/// (docs/physics.md, "The direct solver").

#include <Eigen/SparseCore>
#include <memory>

namespace gd::sim {

class DirectSolver {
 public:
  DirectSolver();
  ~DirectSolver();
  DirectSolver(const DirectSolver&) = delete;
  DirectSolver& operator=(const DirectSolver&) = delete;

  /// Factorises the symmetric, compressed matrix A (both triangles stored; only the lower one is
  /// read, in place).
  /// The fill-reducing ordering is computed again only when A's pattern (size, column pointers or
  /// row indices) differs from the last one's. Returns false where A is not positive definite
  /// (the caller falls back to PCG).
  bool factorize(const Eigen::SparseMatrix<double>& A);
  /// x = A⁻¹ b with the last successful factorisation.
  void solve(const Eigen::Ref<const Eigen::VectorXd>& b, Eigen::Ref<Eigen::VectorXd> x);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace gd::sim
