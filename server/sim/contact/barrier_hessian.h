#pragma once
/// \file
/// The PSD projection of a contact barrier's Hessian, E = b(D), D the distance of a point-triangle
/// or edge-edge pair, computed in the small subspace where the Hessian lives instead of by a
/// 12x12 eigen-decomposition. Same matrix as project_psd<12> of the exact Hessian (up to
/// rounding), several times cheaper.
///
/// Derivation. In every distance region the difference of the closest points is affine in the
/// pair's four vertices and in m free parameters w (m = 0 point-point, 1 point-edge, 2 point-face
/// and edge-edge interiors):  r(w) = Σ_j c_j(w) x_j,  c(w) = c0 + Σ_k w_k c1_k,  s = min_w |r|².
/// With u_k = Σ_j c1_kj x_j (the feature's spanning vectors), G = [u_k·u_l], the envelope theorem
/// gives ∇s = 2 c⊗r and ∇²s = 2 ccᵀ⊗I - 2 Σ_k f_k f_kᵀ with f_k = c⊗ê_k + D b_k⊗n, where
/// G⁻¹ = S Sᵀ (S = L⁻ᵀ, G = L Lᵀ), ê_k = Σ_l u_l S_lk orthonormal in the feature, b_k = Σ_l c1_l S_lk
/// (4-vectors), n = r/D. Writing α_k = (c/|c|)⊗ê_k and splitting I = nnᵀ + P_feature + P_rest:
///   ∇²E = b'' (c⊗n)(c⊗n)ᵀ + (-b') [ |c| Σ_k (α_k β_kᵀ + β_k α_kᵀ) + D Σ_k β_k β_kᵀ ]
///         + (b'/D) ccᵀ⊗P_rest,                                     β_k = b_k⊗n.
/// The last term is negative semi-definite (b' < 0) and orthogonal to everything else, so the
/// projection drops it. The rest lives in the span of the α_k and of z⊗n for z in
/// span{c, b_1..b_m} ⊂ R⁴: at most 2m + 1 <= 5 orthonormal directions. Its matrix in that basis is
/// eigen-decomposed (5x5 at most), negative eigenvalues clamped, and mapped back.

#include <cmath>

#include "sim/contact/distance.h"
#include "sim/energy/psd_project.h"
#include "sim/types.h"

namespace gd::sim {

/// Affine closest-point structure of one distance region (see the file comment): r(w) =
/// Σ_j (c0_j + Σ_k w_k c1_kj) x_j over the pair's vertices, m free parameters.
struct RegionParam {
  Real c0[4];
  Real c1[2][4];
  int m;
};

namespace barrier_hessian_detail {

GD_HD RegionParam make(Real a, Real b, Real c, Real d) {
  RegionParam p{{a, b, c, d}, {{0, 0, 0, 0}, {0, 0, 0, 0}}, 0};
  return p;
}
GD_HD RegionParam make(Real a, Real b, Real c, Real d, Real e0, Real e1, Real e2, Real e3) {
  RegionParam p{{a, b, c, d}, {{e0, e1, e2, e3}, {0, 0, 0, 0}}, 1};
  return p;
}

/// project_psd of H's leading dim x dim block (the rest of H is zero): the reduced Hessian's
/// size is 2 to 5 with the region (m >= 1 feature directions plus at least c), and its zero
/// padding would only cost eigen iterations.
template <int K>
GD_HD void project_leading_block(MatN<5>* H) {
  MatN<K> h = H->template topLeftCorner<K, K>();
  project_psd<K>(&h);
  H->template topLeftCorner<K, K>() = h;
}
GD_HD void project_psd_leading(MatN<5>* H, int dim) {
  switch (dim) {
    case 2: project_leading_block<2>(H); break;
    case 3: project_leading_block<3>(H); break;
    case 4: project_leading_block<4>(H); break;
    default: project_psd<5>(H); break;
  }
}
}  // namespace barrier_hessian_detail

/// The structure of a point-triangle region, vertex order (p, t0, t1, t2), r = p - closest point.
GD_HD RegionParam vf_region_param(PointTriangleRegion region) {
  using barrier_hessian_detail::make;
  switch (region) {
    case PointTriangleRegion::kVertex0: return make(1, -1, 0, 0);
    case PointTriangleRegion::kVertex1: return make(1, 0, -1, 0);
    case PointTriangleRegion::kVertex2: return make(1, 0, 0, -1);
    case PointTriangleRegion::kEdge01: return make(1, -1, 0, 0, 0, 1, -1, 0);   // t0 + s (t1 - t0)
    case PointTriangleRegion::kEdge12: return make(1, 0, -1, 0, 0, 0, 1, -1);   // t1 + s (t2 - t1)
    case PointTriangleRegion::kEdge20: return make(1, 0, 0, -1, 0, -1, 0, 1);   // t2 + s (t0 - t2)
    default: {                                                                 // t0 + β e1 + γ e2
      RegionParam p = make(1, -1, 0, 0, 0, 1, -1, 0);
      p.c1[1][1] = 1, p.c1[1][3] = -1, p.m = 2;
      return p;
    }
  }
}

/// The structure of an edge-edge region, vertex order (a0, a1, b0, b1), r = ca - cb.
GD_HD RegionParam ee_region_param(EdgeEdgeRegion region) {
  using barrier_hessian_detail::make;
  switch (region) {
    case EdgeEdgeRegion::kA0B0: return make(1, 0, -1, 0);
    case EdgeEdgeRegion::kA0B1: return make(1, 0, 0, -1);
    case EdgeEdgeRegion::kA1B0: return make(0, 1, -1, 0);
    case EdgeEdgeRegion::kA1B1: return make(0, 1, 0, -1);
    case EdgeEdgeRegion::kA0EdgeB: return make(1, 0, -1, 0, 0, 0, 1, -1);  // a0 - (b0 + t (b1 - b0))
    case EdgeEdgeRegion::kA1EdgeB: return make(0, 1, -1, 0, 0, 0, 1, -1);
    case EdgeEdgeRegion::kB0EdgeA: return make(1, 0, -1, 0, -1, 1, 0, 0);  // a0 + s (a1 - a0) - b0
    case EdgeEdgeRegion::kB1EdgeA: return make(1, 0, 0, -1, -1, 1, 0, 0);
    default: {  // a0 + s (a1 - a0) - b0 - t (b1 - b0)
      RegionParam p = make(1, 0, -1, 0, -1, 1, 0, 0);
      p.c1[1][2] = 1, p.c1[1][3] = -1, p.m = 2;
      return p;
    }
  }
}

/// PSD projection of the Hessian of E = b(D) over the pair's 12 coordinates, D the region's
/// distance: db = b'(D) (<= 0) and d2b = b''(D) (>= 0). Writes zero when the closest points
/// coincide or the feature is degenerate.
GD_HD void projected_barrier_hessian(const Vec3 x[4], const RegionParam& R, Real db, Real d2b, MatN<12>* H) {
  H->setZero();
  const int m = R.m;
  Vec3 r0 = Vec3::Zero(), u[2] = {Vec3::Zero(), Vec3::Zero()};
  for (int j = 0; j < 4; ++j) {
    r0 += R.c0[j] * x[j];
    for (int k = 0; k < m; ++k) u[k] += R.c1[k][j] * x[j];
  }
  // Closest points: G w = -Uᵀ r0; c = c0 + Σ w_k c1_k.
  Real G[2][2] = {{0, 0}, {0, 0}};
  for (int k = 0; k < m; ++k)
    for (int l = 0; l < m; ++l) G[k][l] = u[k].dot(u[l]);
  Real w[2] = {0, 0};
  if (m == 1) {
    if (!(G[0][0] > 0)) return;
    w[0] = -u[0].dot(r0) / G[0][0];
  } else if (m == 2) {
    const Real det = G[0][0] * G[1][1] - G[0][1] * G[1][0];
    if (!(det > 0)) return;
    const Real q0 = -u[0].dot(r0), q1 = -u[1].dot(r0);
    w[0] = (G[1][1] * q0 - G[0][1] * q1) / det;
    w[1] = (G[0][0] * q1 - G[1][0] * q0) / det;
  }
  Real c[4];
  Vec3 r = Vec3::Zero();
  for (int j = 0; j < 4; ++j) {
    c[j] = R.c0[j];
    for (int k = 0; k < m; ++k) c[j] += w[k] * R.c1[k][j];
    r += c[j] * x[j];
  }
  const Real D = r.norm();
  if (!(D > 0)) return;
  const Vec3 n = r / D;
  Real cn = 0;
  for (int j = 0; j < 4; ++j) cn += c[j] * c[j];
  cn = sqrt(cn);
  // S = L⁻ᵀ with G = L Lᵀ: orthonormal feature directions ê_k and the 4-vectors b_k.
  Real S[2][2] = {{0, 0}, {0, 0}};
  if (m == 1) {
    S[0][0] = 1 / sqrt(G[0][0]);
  } else if (m == 2) {
    const Real l11 = sqrt(G[0][0]), l21 = G[1][0] / l11;
    const Real l22sq = G[1][1] - l21 * l21;
    if (!(l22sq > 0)) return;
    const Real l22 = sqrt(l22sq);
    S[0][0] = 1 / l11, S[0][1] = -l21 / (l11 * l22), S[1][1] = 1 / l22;
  }
  Vec3 e[2];
  Real b[2][4];
  for (int k = 0; k < m; ++k) {
    e[k] = Vec3::Zero();
    for (int l = 0; l < m; ++l) e[k] += S[l][k] * u[l];
    for (int j = 0; j < 4; ++j) {
      b[k][j] = 0;
      for (int l = 0; l < m; ++l) b[k][j] += S[l][k] * R.c1[l][j];
    }
  }
  // Orthonormal basis z of span{c, b_1..b_m} in R⁴ (modified Gram-Schmidt).
  Real z[3][4];
  int nz = 0;
  for (int v = 0; v <= m; ++v) {
    Real q[4];
    for (int j = 0; j < 4; ++j) q[j] = v == 0 ? c[j] : b[v - 1][j];
    Real len0 = 0;
    for (int j = 0; j < 4; ++j) len0 += q[j] * q[j];
    for (int i = 0; i < nz; ++i) {
      Real p = 0;
      for (int j = 0; j < 4; ++j) p += q[j] * z[i][j];
      for (int j = 0; j < 4; ++j) q[j] -= p * z[i][j];
    }
    Real len = 0;
    for (int j = 0; j < 4; ++j) len += q[j] * q[j];
    if (!(len > 1e-20 * len0) || !(len > 0)) continue;
    len = sqrt(len);
    for (int j = 0; j < 4; ++j) z[nz][j] = q[j] / len;
    ++nz;
  }
  // The reduced matrix over (α_1..α_m, z_1⊗n..z_nz⊗n), zero-padded to 5x5.
  const Real kb = -db;
  MatN<5> Hr = MatN<5>::Zero();
  Real cz[3], bz[2][3];
  for (int i = 0; i < nz; ++i) {
    cz[i] = 0;
    for (int j = 0; j < 4; ++j) cz[i] += c[j] * z[i][j];
    for (int k = 0; k < m; ++k) {
      bz[k][i] = 0;
      for (int j = 0; j < 4; ++j) bz[k][i] += b[k][j] * z[i][j];
    }
  }
  for (int k = 0; k < m; ++k)
    for (int i = 0; i < nz; ++i) Hr(k, m + i) = Hr(m + i, k) = kb * cn * bz[k][i];
  for (int i = 0; i < nz; ++i)
    for (int l = 0; l < nz; ++l) {
      Real v = d2b * cz[i] * cz[l];
      for (int k = 0; k < m; ++k) v += kb * D * bz[k][i] * bz[k][l];
      Hr(m + i, m + l) = v;
    }
  if (m > 0) barrier_hessian_detail::project_psd_leading(&Hr, m + nz);
  // Map back: H = Bm Hr Bmᵀ, Bm's columns the 12-vectors of the basis.
  Eigen::Matrix<Real, 12, 5> Bm = Eigen::Matrix<Real, 12, 5>::Zero();
  for (int k = 0; k < m; ++k)
    for (int j = 0; j < 4; ++j) Bm.template block<3, 1>(3 * j, k) = (c[j] / cn) * e[k];
  for (int i = 0; i < nz; ++i)
    for (int j = 0; j < 4; ++j) Bm.template block<3, 1>(3 * j, m + i) = z[i][j] * n;
  // Coefficient-based products: at these sizes Eigen's default product goes through its blocked
  // GEMM kernel, whose packing costs more than the 1,000 multiply-adds themselves.
  const Eigen::Matrix<Real, 12, 5> BH = Bm.lazyProduct(Hr);
  *H = BH.lazyProduct(Bm.transpose());
}

}  // namespace gd::sim
