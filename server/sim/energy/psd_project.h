#pragma once
/// \file
/// Projection of a small symmetric matrix onto the positive semi-definite cone (negative
/// eigenvalues clamped to zero): Eigen's self-adjoint eigensolver on the host, cyclic Jacobi
/// rotations (no allocation, no library calls) inside CUDA kernels.

#include <Eigen/Eigenvalues>

#include "sim/types.h"

namespace gd::sim {

/// Replaces the symmetric matrix A by V max(L, 0) V^T where A = V L V^T. On the host Eigen's
/// self-adjoint eigensolver does it (about 3x faster than the rotations at N = 12); in device code
/// cyclic Jacobi rotations.
template <int N>
GD_HD void project_psd(MatN<N>* A) {
#ifndef __CUDA_ARCH__
  {
    const Eigen::SelfAdjointEigenSolver<MatN<N>> es(*A);
    if (es.info() == Eigen::Success) {
      const VecN<N> lam = es.eigenvalues();
      if (lam.minCoeff() >= 0) return;  // already PSD
      *A = es.eigenvectors() * lam.cwiseMax(Real(0)).asDiagonal() * es.eigenvectors().transpose();
      return;
    }
  }
#endif
  MatN<N> a = *A;
  MatN<N> v = MatN<N>::Identity();
  const Real scale = a.cwiseAbs().maxCoeff();
  if (!(scale > 0)) return;
  for (int sweep = 0; sweep < 30; ++sweep) {
    Real off = 0;
    for (int p = 0; p < N; ++p)
      for (int q = p + 1; q < N; ++q) off += a(p, q) * a(p, q);
    if (off <= 1e-30 * scale * scale) break;
    for (int p = 0; p < N; ++p)
      for (int q = p + 1; q < N; ++q) {
        const Real apq = a(p, q);
        if (fabs(apq) <= 1e-300) continue;
        const Real tau = (a(q, q) - a(p, p)) / (2 * apq);
        const Real t = (tau >= 0 ? 1 : -1) / (fabs(tau) + sqrt(1 + tau * tau));
        const Real c = 1 / sqrt(1 + t * t), s = t * c;
        for (int k = 0; k < N; ++k) {  // A <- A J
          const Real akp = a(k, p), akq = a(k, q);
          a(k, p) = c * akp - s * akq;
          a(k, q) = s * akp + c * akq;
        }
        for (int k = 0; k < N; ++k) {  // A <- J^T A
          const Real apk = a(p, k), aqk = a(q, k);
          a(p, k) = c * apk - s * aqk;
          a(q, k) = s * apk + c * aqk;
        }
        for (int k = 0; k < N; ++k) {  // V <- V J
          const Real vkp = v(k, p), vkq = v(k, q);
          v(k, p) = c * vkp - s * vkq;
          v(k, q) = s * vkp + c * vkq;
        }
      }
  }
  MatN<N> out = MatN<N>::Zero();
  for (int k = 0; k < N; ++k) {
    const Real lam = a(k, k);
    if (lam > 0) out += lam * v.col(k) * v.col(k).transpose();
  }
  *A = out;
}

}  // namespace gd::sim
