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
///
/// Term by term (termwise_barrier_hessian, the solver's default in scenes without colliders). The two terms of
/// ∇²E = b'' ∇D ∇Dᵀ + b' ∇²D projected each on its own: the first is PSD already (∇D = c⊗n);
/// in the second, with the Gram matrix of the β_k (b_k·b_l) = W diag(σ²) Wᵀ, the directions
/// a_k = Σ_l W_lk α_l and p_k = Σ_l W_lk β_l / σ_k are orthonormal, the a's orthogonal to the p's
/// (ê ⊥ n), and (-b')[ |c| Σ (αβᵀ + βαᵀ) + D Σ ββᵀ ] = -b' Σ_k [ |c| σ_k (a_k p_kᵀ + p_k a_kᵀ) +
/// D σ_k² p_k p_kᵀ ]: m uncoupled 2x2 blocks [[0, |c|σ], [|c|σ, Dσ²]], whose positive
/// eigenpair is closed-form. No eigen-solver; at most three rank-one terms. The sum is PSD and
/// at least the exact Hessian (H - ∇²E is the dropped negative parts), so Newton's direction
/// descends; it differs from the exact projection where ∇D has a component along the p_k.

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

/// The closest-point structure of one pair at its positions (the file comment's notation): the
/// weights c of r = Σ c_j x_j, |c|, the distance D and normal n = r/D, the orthonormal feature
/// directions ê_k and their 4-vectors b_k, k < m.
struct BarrierFrame {
  Real c[4];
  Real cn;
  Real D;
  Vec3 n;
  Vec3 e[2];
  Real b[2][4];
  int m;
};

/// Fills F for the pair x in region R; false when the closest points coincide or the feature is
/// degenerate (the Hessian is then taken as zero).
GD_HD bool barrier_frame(const Vec3 x[4], const RegionParam& R, BarrierFrame* F) {
  const int m = R.m;
  F->m = m;
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
    if (!(G[0][0] > 0)) return false;
    w[0] = -u[0].dot(r0) / G[0][0];
  } else if (m == 2) {
    const Real det = G[0][0] * G[1][1] - G[0][1] * G[1][0];
    if (!(det > 0)) return false;
    const Real q0 = -u[0].dot(r0), q1 = -u[1].dot(r0);
    w[0] = (G[1][1] * q0 - G[0][1] * q1) / det;
    w[1] = (G[0][0] * q1 - G[1][0] * q0) / det;
  }
  Real* c = F->c;
  Vec3 r = Vec3::Zero();
  for (int j = 0; j < 4; ++j) {
    c[j] = R.c0[j];
    for (int k = 0; k < m; ++k) c[j] += w[k] * R.c1[k][j];
    r += c[j] * x[j];
  }
  F->D = r.norm();
  if (!(F->D > 0)) return false;
  F->n = r / F->D;
  Real cn = 0;
  for (int j = 0; j < 4; ++j) cn += c[j] * c[j];
  F->cn = sqrt(cn);
  // S = L⁻ᵀ with G = L Lᵀ: orthonormal feature directions ê_k and the 4-vectors b_k.
  Real S[2][2] = {{0, 0}, {0, 0}};
  if (m == 1) {
    S[0][0] = 1 / sqrt(G[0][0]);
  } else if (m == 2) {
    const Real l11 = sqrt(G[0][0]), l21 = G[1][0] / l11;
    const Real l22sq = G[1][1] - l21 * l21;
    if (!(l22sq > 0)) return false;
    const Real l22 = sqrt(l22sq);
    S[0][0] = 1 / l11, S[0][1] = -l21 / (l11 * l22), S[1][1] = 1 / l22;
  }
  for (int k = 0; k < m; ++k) {
    F->e[k] = Vec3::Zero();
    for (int l = 0; l < m; ++l) F->e[k] += S[l][k] * u[l];
    for (int j = 0; j < 4; ++j) {
      F->b[k][j] = 0;
      for (int l = 0; l < m; ++l) F->b[k][j] += S[l][k] * R.c1[l][j];
    }
  }
  return true;
}

/// The curvature term's axes (file comment, "Term by term"): the β Gram matrix [b_k·b_l] =
/// W diag(σ²) Wᵀ, and per k the unit directions a_k (its vertex j block (c_j/|c|) ê'_k) and p_k
/// (block pw_k[j] n), and the 2x2 block [[0, |c|σ_k], [|c|σ_k, Dσ_k²]]'s positive eigenvalue l+_k.
struct BetaAxes {
  Real sigma[2];
  Vec3 e[2];      ///< ê'_k = Σ_l W_lk ê_l
  Real pw[2][4];  ///< p_k's weights, Σ_l W_lk b_l / σ_k (unit 4-vectors)
  Real s[2], t[2], lp[2];
};

GD_HD BetaAxes beta_axes(const BarrierFrame& F) {
  BetaAxes A;
  const int m = F.m;
  Real g[2][2] = {{0, 0}, {0, 0}};
  for (int k = 0; k < m; ++k)
    for (int l = 0; l < m; ++l)
      for (int j = 0; j < 4; ++j) g[k][l] += F.b[k][j] * F.b[l][j];
  Real sigma2[2] = {g[0][0], 0}, W[2][2] = {{1, 0}, {0, 1}};
  if (m == 2) {
    const Real mean = (g[0][0] + g[1][1]) / 2, half = (g[0][0] - g[1][1]) / 2;
    const Real rad = sqrt(half * half + g[0][1] * g[0][1]);
    sigma2[0] = mean + rad;
    sigma2[1] = fmax(Real(0), mean - rad);
    if (rad > 0) {  // the larger eigenvalue's vector, from the better-conditioned row
      Real v0 = half >= 0 ? sigma2[0] - g[1][1] : g[0][1];
      Real v1 = half >= 0 ? g[0][1] : sigma2[0] - g[0][0];
      const Real len = sqrt(v0 * v0 + v1 * v1);
      v0 /= len, v1 /= len;
      W[0][0] = v0, W[1][0] = v1, W[0][1] = -v1, W[1][1] = v0;
    }
  }
  for (int k = 0; k < m; ++k) {
    A.sigma[k] = sqrt(fmax(sigma2[k], Real(0)));
    A.e[k] = W[0][k] * F.e[0];
    if (m == 2) A.e[k] += W[1][k] * F.e[1];
    for (int j = 0; j < 4; ++j) {
      Real bk = W[0][k] * F.b[0][j];
      if (m == 2) bk += W[1][k] * F.b[1][j];
      A.pw[k][j] = A.sigma[k] > 0 ? bk / A.sigma[k] : Real(0);
    }
    A.s[k] = F.cn * A.sigma[k];
    A.t[k] = F.D * sigma2[k];
    A.lp[k] = (A.t[k] + sqrt(A.t[k] * A.t[k] + 4 * A.s[k] * A.s[k])) / 2;
  }
  return A;
}

/// H = Σ_t weight[t] v_t v_tᵀ over the pair's 12 coordinates, each v_t given per vertex j as
/// (c_j / |c|) Σ_k ea[t][k] ê'_k + normal[t][j] n; at most three terms.
GD_HD void sum_rank_one(const BarrierFrame& F, const BetaAxes& A, int terms, const Real* weight,
                        const Real (*ea)[2], const Real (*normal)[4], MatN<12>* H) {
  Vec3 v[3][4];
  for (int t = 0; t < terms; ++t) {
    Vec3 along = Vec3::Zero();
    for (int k = 0; k < F.m; ++k) along += ea[t][k] * A.e[k];
    for (int j = 0; j < 4; ++j) v[t][j] = (F.c[j] / F.cn) * along + normal[t][j] * F.n;
  }
  for (int i = 0; i < 4; ++i)
    for (int j = i; j < 4; ++j) {
      Mat3 block = Mat3::Zero();
      for (int t = 0; t < terms; ++t) block += weight[t] * v[t][i] * v[t][j].transpose();
      H->template block<3, 3>(3 * i, 3 * j) = block;
      if (j != i) H->template block<3, 3>(3 * j, 3 * i) = block.transpose();
    }
}

/// PSD projection of the Hessian of E = b(D) over the pair's 12 coordinates, D the region's
/// distance: db = b'(D) (<= 0) and d2b = b''(D) (>= 0). Writes zero when the closest points
/// coincide or the feature is degenerate.
GD_HD void projected_barrier_hessian(const Vec3 x[4], const RegionParam& R, Real db, Real d2b, MatN<12>* H) {
  H->setZero();
  BarrierFrame F;
  if (!barrier_frame(x, R, &F)) return;
  const int m = F.m;
  const Real* c = F.c;
  const Real cn = F.cn, D = F.D;
  const Vec3 n = F.n;
  const Vec3* e = F.e;
  const Real(*b)[4] = F.b;
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

/// The Hessian of E = b(D) with its two terms made PSD each on its own (file comment, "Term by
/// term"): b'' ∇D ∇Dᵀ plus the positive part of b' ∇²D, in closed form. db, d2b as in
/// projected_barrier_hessian; zero where the frame is degenerate.
GD_HD void termwise_barrier_hessian(const Vec3 x[4], const RegionParam& R, Real db, Real d2b, MatN<12>* H) {
  H->setZero();
  BarrierFrame F;
  if (!barrier_frame(x, R, &F)) return;
  const int m = F.m;
  const BetaAxes A = beta_axes(F);
  // H = d2b ∇D∇Dᵀ + Σ_k -db λ_k q_k q_kᵀ, q_k the unit positive eigenvector (|c|σ a_k + λ p_k) / norm.
  Real weight[3] = {d2b, 0, 0}, ea[3][2] = {{0, 0}, {0, 0}, {0, 0}}, normal[3][4];
  for (int j = 0; j < 4; ++j) normal[0][j] = F.c[j];
  int terms = 1;
  for (int k = 0; k < m; ++k) {
    if (!(A.sigma[k] > 0)) continue;
    const Real norm = sqrt(A.s[k] * A.s[k] + A.lp[k] * A.lp[k]);
    for (int l = 0; l < 2; ++l) ea[terms][l] = l == k ? A.s[k] / norm : Real(0);
    for (int j = 0; j < 4; ++j) normal[terms][j] = A.lp[k] / norm * A.pw[k][j];
    weight[terms++] = -db * A.lp[k];
  }
  sum_rank_one(F, A, terms, weight, ea, normal, H);
}

/// The closed-form Hessian of E = b(D) of either kind: kTermwise's, else the exact projection.
GD_HD void closed_form_barrier_hessian(HessianKind kind, const Vec3 x[4], const RegionParam& R, Real db, Real d2b,
                                       MatN<12>* H) {
  if (kind == HessianKind::kTermwise) {
    termwise_barrier_hessian(x, R, db, d2b, H);
  } else {
    projected_barrier_hessian(x, R, db, d2b, H);
  }
}

}  // namespace gd::sim
