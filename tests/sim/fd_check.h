#pragma once
/// \file
/// Small reusable finite-difference checker for element energies: central-difference gradients
/// of scalar functions and Jacobians (Hessians) of vector functions over VecN<N>, a relative +
/// absolute closeness assertion, and a PSD test.

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>

#include "sim/types.h"

namespace gd::sim::test {

/// Central-difference step for coordinates of characteristic size `length` (m): 1e-6 relative.
inline Real fd_step(Real length) { return Real(1e-6) * length; }

/// Central-difference gradient of f: VecN<N> -> Real with absolute step h.
template <int N, class F>
VecN<N> fd_gradient(const F& f, const VecN<N>& x, Real h) {
  VecN<N> g;
  for (int i = 0; i < N; ++i) {
    VecN<N> xp = x;
    VecN<N> xm = x;
    xp[i] += h;
    xm[i] -= h;
    g[i] = (f(xp) - f(xm)) / (Real(2) * h);
  }
  return g;
}

/// Central-difference Jacobian of g: VecN<N> -> VecN<M> (column j = ∂g/∂x_j) with step h.
/// For g = ∇E this is the Hessian of E.
template <int M, int N, class G>
Eigen::Matrix<Real, M, N> fd_jacobian(const G& g, const VecN<N>& x, Real h) {
  Eigen::Matrix<Real, M, N> J;
  for (int j = 0; j < N; ++j) {
    VecN<N> xp = x;
    VecN<N> xm = x;
    xp[j] += h;
    xm[j] -= h;
    J.col(j) = (g(xp) - g(xm)) / (Real(2) * h);
  }
  return J;
}

/// Passes when ||a - b|| <= rel * max(||a||, ||b||) + abs (Frobenius norms).
template <class A, class B>
::testing::AssertionResult near_rel(const Eigen::MatrixBase<A>& a, const Eigen::MatrixBase<B>& b,
                                    Real rel, Real abs = 0) {
  const Real err = (a - b).norm();
  const Real tol = rel * std::max(a.norm(), b.norm()) + abs;
  if (err <= tol) return ::testing::AssertionSuccess();
  std::ostringstream os;
  os << "|a-b| = " << err << " > tol " << tol << " (|a| = " << a.norm() << ", |b| = " << b.norm()
     << ")\na =\n"
     << a << "\nb =\n"
     << b;
  return ::testing::AssertionFailure() << os.str();
}

/// Smallest eigenvalue of the symmetric part of H.
template <class D>
Real min_eigenvalue(const Eigen::MatrixBase<D>& H) {
  using M = Eigen::Matrix<Real, D::RowsAtCompileTime, D::ColsAtCompileTime>;
  const M S = Real(0.5) * (H + H.transpose());
  Eigen::SelfAdjointEigenSolver<M> es(S, Eigen::EigenvaluesOnly);
  return es.eigenvalues().minCoeff();
}

/// Passes when H is symmetric and its smallest eigenvalue is >= -rel * ||H||.
template <class D>
::testing::AssertionResult is_psd(const Eigen::MatrixBase<D>& H, Real rel = Real(1e-9)) {
  const Real n = H.norm();
  const Real asym = (H - H.transpose()).norm();
  if (asym > Real(1e-12) * n) return ::testing::AssertionFailure() << "not symmetric: " << asym;
  const Real lmin = min_eigenvalue(H);
  if (lmin >= -rel * n) return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure() << "min eigenvalue " << lmin << " < -" << rel << " * " << n;
}

/// Uniform random 3-vector with components in [-1, 1].
inline Vec3 random_vec3(std::mt19937& rng) {
  std::uniform_real_distribution<Real> u(-1, 1);
  return Vec3(u(rng), u(rng), u(rng));
}

/// Uniform random rotation (from a normalised random quaternion).
inline Mat3 random_rotation(std::mt19937& rng) {
  std::normal_distribution<Real> n(0, 1);
  Eigen::Quaternion<Real> q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  return q.toRotationMatrix();
}

/// The four points of a 12-vector (a pair or a hinge) stacked as one.
inline VecN<12> stack4(const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& d) {
  VecN<12> x;
  x << a, b, c, d;
  return x;
}

/// Point i (0-3) of a stacked 12-vector.
inline Vec3 seg(const VecN<12>& x, int i) { return x.segment<3>(3 * i); }

/// Fabric parameters used across the energy tests (catalogue numbers of real fabrics).
struct Fabric {
  const char* name;
  Real stretch;    ///< N/m
  Real bending;    ///< N·m
  Real thickness;  ///< m
  Real density;    ///< kg/m^2
};

inline constexpr Fabric kFabrics[] = {
    {"cotton", 1000.0, 2.8e-6, 0.26e-3, 0.17},
    {"silk", 30.0, 1.5e-7, 0.19e-3, 0.05},
    {"leather", 1000.0, 2e-5, 1.74e-3, 0.9},
};

}  // namespace gd::sim::test
