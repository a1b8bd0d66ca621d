// The direct solve's factorisation (sim/solver/direct_solver.h): CHOLMOD's supernodal Cholesky
// against a dense solve, a pattern that changes between factorisations (self-contact pairs come and
// go), a matrix that is not positive definite, and OpenMP's settings left as they were.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

#include "sim/backend/cpu/omp_threads.h"
#include "sim/solver/direct_solver.h"

namespace gd::sim {
namespace {

/// A symmetric positive definite matrix with a 2-D grid's pattern (k x k nodes, 3 values each, as
/// a cloth's Newton matrix), plus `extra` random symmetric couplings (contact pairs).
Eigen::SparseMatrix<double> grid_matrix(int k, int extra, unsigned seed) {
  const int n = 3 * k * k;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Triplet<double>> t;
  auto couple = [&](int a, int b) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        const double v = 0.3 * u(rng);
        t.emplace_back(3 * a + r, 3 * b + c, v);
        t.emplace_back(3 * b + c, 3 * a + r, v);
      }
  };
  for (int i = 0; i < k; ++i)
    for (int j = 0; j < k; ++j) {
      const int a = i * k + j;
      if (j + 1 < k) couple(a, a + 1);
      if (i + 1 < k) couple(a, a + k);
    }
  std::uniform_int_distribution<int> node(0, k * k - 1);
  for (int e = 0; e < extra; ++e) {
    const int a = node(rng), b = node(rng);
    if (a != b) couple(a, b);
  }
  Eigen::SparseMatrix<double> A(n, n);
  A.setFromTriplets(t.begin(), t.end());
  // Diagonally dominant: positive definite.
  Eigen::VectorXd rowsum = Eigen::VectorXd::Zero(n);
  for (int c = 0; c < A.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(A, c); it; ++it) rowsum[it.row()] += std::abs(it.value());
  for (int i = 0; i < n; ++i) A.coeffRef(i, i) += rowsum[i] + 1.0;
  A.makeCompressed();
  return A;
}

double relative_error(const Eigen::SparseMatrix<double>& A, const Eigen::VectorXd& b, const Eigen::VectorXd& x) {
  const Eigen::VectorXd exact = Eigen::MatrixXd(A).ldlt().solve(b);
  return (x - exact).norm() / exact.norm();
}

TEST(DirectSolver, SolvesAGridMatrixAsADenseSolveDoes) {
  const Eigen::SparseMatrix<double> A = grid_matrix(12, 0, 1);
  const Eigen::VectorXd b = Eigen::VectorXd::LinSpaced(A.rows(), -1.0, 2.0);
  DirectSolver s;
  ASSERT_TRUE(s.factorize(A));
  Eigen::VectorXd x(A.rows());
  s.solve(b, x);
  EXPECT_LT(relative_error(A, b, x), 1e-12);
}

TEST(DirectSolver, FollowsAPatternThatChangesBetweenFactorisations) {
  DirectSolver s;
  const Eigen::VectorXd b = Eigen::VectorXd::Ones(3 * 10 * 10);
  for (unsigned seed = 1; seed <= 4; ++seed) {  // other contact couplings each time
    const Eigen::SparseMatrix<double> A = grid_matrix(10, 15, seed);
    ASSERT_TRUE(s.factorize(A)) << seed;
    Eigen::VectorXd x(A.rows());
    s.solve(b, x);
    EXPECT_LT(relative_error(A, b, x), 1e-12) << seed;
  }
}

TEST(DirectSolver, RefusesAMatrixThatIsNotPositiveDefinite) {
  Eigen::SparseMatrix<double> A = grid_matrix(6, 0, 2);
  A.coeffRef(7, 7) = -50.0;  // one negative pivot
  DirectSolver s;
  EXPECT_FALSE(s.factorize(A));
  // And recovers on the next good matrix.
  const Eigen::SparseMatrix<double> B = grid_matrix(6, 0, 2);
  EXPECT_TRUE(s.factorize(B));
}

#ifdef _OPENMP
TEST(DirectSolver, LeavesOpenMpsNestingAsItWas) {
  // One thread asked for: the factorisation runs CHOLMOD's regions serially and restores
  // max-active-levels afterwards, so later parallel loops get their threads again.
  const int levels = omp_get_max_active_levels();
  const int threads = omp_threads();
  set_omp_threads(1);
  DirectSolver s;
  ASSERT_TRUE(s.factorize(grid_matrix(8, 0, 3)));
  Eigen::VectorXd x(3 * 64);
  s.solve(Eigen::VectorXd::Ones(3 * 64), x);
  EXPECT_EQ(omp_get_max_active_levels(), levels);
  set_omp_threads(threads);
}
#endif

}  // namespace
}  // namespace gd::sim
