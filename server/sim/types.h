#pragma once
/// \file
/// Scalar and small fixed-size matrix types shared by every simulator file. SI units throughout
/// (m, kg, s, N); conversions from catalogue units happen only where material files are read.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/LU>

#include "sim/hd.h"

namespace gd::sim {

using Real = double;
using Vec2 = Eigen::Matrix<Real, 2, 1>;
using Vec3 = Eigen::Matrix<Real, 3, 1>;
using Mat2 = Eigen::Matrix<Real, 2, 2>;
using Mat3 = Eigen::Matrix<Real, 3, 3>;
template <int N>
using VecN = Eigen::Matrix<Real, N, 1>;
template <int N>
using MatN = Eigen::Matrix<Real, N, N>;
using Vec9 = VecN<9>;
using Mat9 = MatN<9>;
using Vec12 = VecN<12>;
using Mat12 = MatN<12>;

/// Which Hessian an energy evaluation should produce.
enum class HessianKind {
  kNone,       ///< value (and gradient) only
  kExact,      ///< the true second derivative (may be indefinite); used by finite-difference tests
  kProjected,  ///< a positive semi-definite approximation; what the Newton solver assembles
  /// Contact barriers only: the barrier's curvature along the distance gradient, c ∇d ∇dᵀ with
  /// c >= 0 (PSD by construction, no eigen-decomposition). It drops b'(d) ∇²d, which is negative
  /// semi-definite where the distance is convex and is what a projection mostly removes.
  kGaussNewton,
  /// Contact barriers only: b'' ∇d ∇dᵀ plus the PSD part of b' ∇²d, each term projected on its
  /// own in closed form (contact/barrier_hessian.h, termwise_barrier_hessian).
  kTermwise,
};

/// Standard gravity, m/s^2.
inline constexpr Real kGravity = 9.80665;

}  // namespace gd::sim
