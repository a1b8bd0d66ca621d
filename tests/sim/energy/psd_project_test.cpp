// The small symmetric eigen-decomposition (Householder + implicit QL, its Jacobi fallback) and the
// PSD projection built on it, against Eigen's self-adjoint eigensolver as the reference.
#include "sim/energy/psd_project.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <random>
#include <vector>

namespace gd::sim {
namespace {

using Dyn = Eigen::MatrixXd;

/// Eigen's self-adjoint eigensolver's projection: the reference. Dynamic sizes, so that its
/// templates are instantiated once for all N (fixed ones cost this file minutes of compile time).
Dyn reference_projection(const Dyn& A) {
  const Eigen::SelfAdjointEigenSolver<Dyn> es(A);
  return es.eigenvectors() * es.eigenvalues().cwiseMax(Real(0)).asDiagonal() * es.eigenvectors().transpose();
}

Eigen::VectorXd reference_eigenvalues(const Dyn& A) {
  return Eigen::SelfAdjointEigenSolver<Dyn>(A, Eigen::EigenvaluesOnly).eigenvalues();
}

/// An orthogonal matrix from the QR of a random one.
Dyn orthogonal_factor(const Dyn& A) {
  const Eigen::HouseholderQR<Dyn> qr(A);
  return qr.householderQ();
}

/// Symmetric test matrices of size N: random dense ones, and the shapes that break eigen
/// iterations: zero, diagonal, repeated eigenvalues, rank one, zero rows (padding), huge and
/// tiny scales, and the bordered form of the contact barrier's reduced Hessian.
template <int N>
std::vector<MatN<N>> cases(std::mt19937* rng) {
  std::normal_distribution<Real> nd;
  auto random = [&] {
    MatN<N> r;
    for (int i = 0; i < N * N; ++i) r(i) = nd(*rng);
    return MatN<N>(r + r.transpose());
  };
  std::vector<MatN<N>> out;
  for (int k = 0; k < 40; ++k) out.push_back(random());
  out.push_back(MatN<N>::Zero());
  out.push_back(MatN<N>::Identity());
  out.push_back(-2.5 * MatN<N>::Identity());
  VecN<N> diag;
  for (int i = 0; i < N; ++i) diag(i) = i % 2 ? -Real(i) : Real(i) + 0.5;
  out.push_back(diag.asDiagonal());
  VecN<N> u;
  for (int i = 0; i < N; ++i) u(i) = nd(*rng);
  out.push_back(u * u.transpose());
  out.push_back(-3 * u * u.transpose());
  {  // a rotated matrix with a repeated negative and a repeated positive eigenvalue
    const MatN<N> Q = orthogonal_factor(random());
    VecN<N> lam;
    for (int i = 0; i < N; ++i) lam(i) = i < N / 2 ? -1.0 : 2.0;
    out.push_back(Q * lam.asDiagonal() * Q.transpose());
  }
  if (N > 2) {  // zero padding: the last row and column zero
    MatN<N> m = random();
    m.row(N - 1).setZero();
    m.col(N - 1).setZero();
    out.push_back(m);
  }
  out.push_back(1e12 * random());
  out.push_back(1e-12 * random());
  if (N > 2) {  // bordered: a zero leading block coupled to a PSD trailing block
    MatN<N> m = MatN<N>::Zero();
    const int k = N / 2;
    for (int i = 0; i < k; ++i)
      for (int j = k; j < N; ++j) m(i, j) = m(j, i) = nd(*rng);
    for (int i = k; i < N; ++i)
      for (int j = k; j < N; ++j) {
        Real s = 0;
        for (int l = k; l < N; ++l) s += m(i, l) * m(j, l);
        m(i, j) += s;
      }
    out.push_back(m);
  }
  return out;
}

template <int N>
void check_size() {
  SCOPED_TRACE("N = " + std::to_string(N));
  std::mt19937 rng(11 + N);
  for (const MatN<N>& A : cases<N>(&rng)) {
    const Real scale = std::max(A.norm(), Real(1e-300));
    for (const bool jacobi : {false, true}) {
      VecN<N> lam;
      MatN<N> V;
      symmetric_eigen<N>(A, &lam, &V, jacobi);
      const Dyn Ad = A, Vd = V;
      const Eigen::VectorXd lamd = lam;
      EXPECT_LE((Vd.transpose() * Vd - Dyn::Identity(N, N)).norm(), 1e-13) << "eigenvectors orthonormal";
      EXPECT_LE((Vd * lamd.asDiagonal() * Vd.transpose() - Ad).norm(), 1e-13 * scale) << "A = V diag(lambda) V^T";
      Eigen::VectorXd sorted = lamd;
      std::sort(sorted.data(), sorted.data() + N);
      EXPECT_LE((sorted - reference_eigenvalues(Ad)).norm(), 1e-13 * scale) << "eigenvalues as Eigen's";

      MatN<N> P = A;
      project_psd<N>(&P, jacobi);
      const Dyn Pd = P;
      EXPECT_LE((Pd - reference_projection(Ad)).norm(), 1e-12 * scale) << (jacobi ? "Jacobi" : "QL");
      EXPECT_LE((Pd - Pd.transpose()).norm(), 0.0) << "exactly symmetric";
      EXPECT_GE(reference_eigenvalues(Pd).minCoeff(), -1e-12 * scale) << "PSD";
    }
  }
}

TEST(PsdProjection, EqualsTheReferenceAtEverySizeTheSolverUses) {
  check_size<1>();
  check_size<2>();
  check_size<3>();
  check_size<4>();
  check_size<5>();
  check_size<9>();
  check_size<12>();
}

TEST(PsdProjection, LeavesAPsdMatrixUnchanged) {
  std::mt19937 rng(5);
  std::normal_distribution<Real> nd;
  MatN<12> B;
  for (int i = 0; i < 144; ++i) B(i) = nd(rng);
  const MatN<12> A = B * B.transpose();
  MatN<12> P = A;
  project_psd<12>(&P);
  EXPECT_EQ(P, A);
}

}  // namespace
}  // namespace gd::sim
