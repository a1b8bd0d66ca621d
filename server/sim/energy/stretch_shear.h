#pragma once
/// \file
/// Anisotropic Baraff-Witkin membrane energy (warp stretch, weft stretch, in-plane shear) of one
/// triangle. Pattern (rest) coordinates are 2D: axis 0 = u = warp, axis 1 = v = weft.
///
/// Compression along warp or weft (|w| < 1) is resisted with the stretch stiffness times
/// `compression_ratio` (<= 1): real fabric buckles into wrinkles far smaller than a triangle as
/// soon as it is compressed (critical strain pi^2 B / (k h^2), about 1e-5 for cotton at h = 5 cm),
/// so it carries almost no compressive force; a coarse mesh cannot form those wrinkles and, with
/// the full stiffness, would hold curved cloth up like a shell (docs/physics.md). The energy stays
/// C1 across |w| = 1 (the Hessian jumps there).
///
/// Vertex order: x0, x1, x2 (world positions, m). The deformation gradient is
///   F = [x1 - x0, x2 - x0] * Dm_inv = [w_u  w_v]   (3x2, dimensionless)
/// where Dm_inv is the inverse of the rest edge matrix [X1 - X0, X2 - X0] (2x2, 1/m) built from the
/// pattern coordinates X_i. Because w_u, w_v are linear in the positions,
///   w_u = c_u[0] x0 + c_u[1] x1 + c_u[2] x2,  c_u = (-(d00 + d10), d00, d10),
///   w_v = c_v[0] x0 + c_v[1] x1 + c_v[2] x2,  c_v = (-(d01 + d11), d01, d11),  d = Dm_inv,
/// every derivative is computed in the 6-dimensional (w_u, w_v) space and mapped to the 9 position
/// coordinates (x0, x1, x2, each xyz) with these constant coefficients.

#include <cmath>

#include "sim/types.h"

namespace gd::sim {

/// Rest data of one membrane triangle.
struct StretchShearRest {
  Mat2 Dm_inv;   ///< inverse of the rest edge matrix [X1-X0, X2-X0] in pattern coordinates, 1/m
  Real area;     ///< rest (pattern) area, m^2
  Real k_warp;   ///< warp (u) stretch stiffness, N/m
  Real k_weft;   ///< weft (v) stretch stiffness, N/m
  Real k_shear;  ///< in-plane shear stiffness, N/m
  /// Compressive / tensile stretch stiffness (0, 1]: the warp (weft) term uses k_warp (k_weft)
  /// times this when |w_u| < 1 (|w_v| < 1). 1: the symmetric Baraff-Witkin model.
  Real compression_ratio = 1;
};

/// Stretch stiffness in effect at stretch `len` = |w| (N/m): k, or k * compression_ratio when
/// compressed (len < 1).
GD_HD Real effective_stretch_stiffness(Real k, Real len, Real compression_ratio) {
  return len < Real(1) ? k * compression_ratio : k;
}

/// Columns of the deformation gradient: w_u = F e_u, w_v = F e_v with F = [x1-x0, x2-x0] Dm_inv.
/// Dimensionless (|w_u| = 1 means the warp direction is unstretched). Vertex order x0, x1, x2.
GD_HD void deformation_columns(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Mat2& Dm_inv,
                               Vec3* wu, Vec3* wv) {
  const Vec3 e1 = x1 - x0;
  const Vec3 e2 = x2 - x0;
  *wu = e1 * Dm_inv(0, 0) + e2 * Dm_inv(1, 0);
  *wv = e1 * Dm_inv(0, 1) + e2 * Dm_inv(1, 1);
}

/// Strain measures of a triangle (dimensionless): eps_u = |w_u| - 1 (warp), eps_v = |w_v| - 1
/// (weft), shear = w_u . w_v (about the cosine of the angle between the deformed warp and weft
/// threads; 0 when they stay orthogonal). Any output pointer may be null.
GD_HD void triangle_strains(const Vec3& x0, const Vec3& x1, const Vec3& x2, const Mat2& Dm_inv,
                            Real* eps_u, Real* eps_v, Real* shear) {
  Vec3 wu;
  Vec3 wv;
  deformation_columns(x0, x1, x2, Dm_inv, &wu, &wv);
  if (eps_u) *eps_u = wu.norm() - Real(1);
  if (eps_v) *eps_v = wv.norm() - Real(1);
  if (shear) *shear = wu.dot(wv);
}

namespace detail {

/// Coefficients c_u, c_v with w_u = sum_i c_u[i] x_i and w_v = sum_i c_v[i] x_i (1/m).
GD_HD void membrane_weights(const Mat2& d, Vec3* cu, Vec3* cv) {
  *cu = Vec3(-(d(0, 0) + d(1, 0)), d(0, 0), d(1, 0));
  *cv = Vec3(-(d(0, 1) + d(1, 1)), d(0, 1), d(1, 1));
}

/// Maps a gradient with respect to (w_u, w_v) to the 9 position coordinates (x0, x1, x2).
GD_HD void membrane_map_gradient(const Vec3& cu, const Vec3& cv, const Vec3& gu, const Vec3& gv,
                                 Vec9* grad) {
  for (int i = 0; i < 3; ++i) grad->segment<3>(3 * i) = cu[i] * gu + cv[i] * gv;
}

/// Maps a 6x6 Hessian with respect to (w_u, w_v) to the 9x9 position Hessian:
/// H_x(i, j) = sum_{p,q in {u,v}} c_p[i] c_q[j] H_w(p, q) (3x3 blocks).
GD_HD void membrane_map_hessian(const Vec3& cu, const Vec3& cv, const MatN<6>& Hw, Mat9* hess) {
  const Mat3 Huu = Hw.block<3, 3>(0, 0);
  const Mat3 Huv = Hw.block<3, 3>(0, 3);
  const Mat3 Hvu = Hw.block<3, 3>(3, 0);
  const Mat3 Hvv = Hw.block<3, 3>(3, 3);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      hess->block<3, 3>(3 * i, 3 * j) = (cu[i] * cu[j]) * Huu + (cu[i] * cv[j]) * Huv +
                                         (cv[i] * cu[j]) * Hvu + (cv[i] * cv[j]) * Hvv;
    }
  }
}

/// Hessian of (k/2)(|w| - 1)^2 with respect to w (already multiplied by k):
/// k [ŵŵᵀ + c (I - ŵŵᵀ)], c = 1 - 1/|w| (exact) or max(c, 0) (projected). For |w| ~ 0 the
/// direction is undefined and the block is returned as 0 (degenerate, never reached in practice).
GD_HD Mat3 stretch_block_hessian(Real k, Real len, const Vec3& what, bool projected) {
  if (!(len > Real(1e-12))) return Mat3::Zero();
  Real c = Real(1) - Real(1) / len;
  if (projected && c < Real(0)) c = Real(0);
  const Mat3 P = what * what.transpose();
  return k * (P + c * (Mat3::Identity() - P));
}

}  // namespace detail

/// stretch_shear_energy in the (w_u, w_v) space of the file comment: the energy, and for non-null
/// pointers its gradient (N, ordered w_u, w_v) and Hessian (N/m, 6x6; kind kExact or kProjected
/// as in stretch_shear_energy) with respect to the deformation columns w_u, w_v at (wu, wv). The
/// solver sums the membrane terms of a triangle in this space and maps them to the positions once
/// (membrane_map_gradient, membrane_map_hessian with membrane_weights).
GD_HD Real stretch_shear_energy_w(const Vec3& wu, const Vec3& wv, const StretchShearRest& r, VecN<6>* grad_w,
                                  MatN<6>* hess_w, HessianKind kind) {
  const Real lu = wu.norm();
  const Real lv = wv.norm();
  const Real s = wu.dot(wv);
  const Real du = lu - Real(1);
  const Real dv = lv - Real(1);
  const Real ku = effective_stretch_stiffness(r.k_warp, lu, r.compression_ratio);
  const Real kv = effective_stretch_stiffness(r.k_weft, lv, r.compression_ratio);
  const Real energy = Real(0.5) * r.area * (ku * du * du + kv * dv * dv + r.k_shear * s * s);

  const bool want_hess = hess_w != nullptr && kind != HessianKind::kNone;
  if (grad_w == nullptr && !want_hess) return energy;

  const Vec3 hu = lu > Real(1e-12) ? Vec3(wu / lu) : Vec3(Vec3::Zero());
  const Vec3 hv = lv > Real(1e-12) ? Vec3(wv / lv) : Vec3(Vec3::Zero());
  if (grad_w != nullptr) {
    grad_w->segment<3>(0) = r.area * (ku * du * hu + r.k_shear * s * wv);
    grad_w->segment<3>(3) = r.area * (kv * dv * hv + r.k_shear * s * wu);
  }
  if (want_hess) {
    const bool projected = kind == HessianKind::kProjected;
    MatN<6>& Hw = *hess_w;
    Hw.setZero();
    Hw.block<3, 3>(0, 0) = detail::stretch_block_hessian(r.area * ku, lu, hu, projected);
    Hw.block<3, 3>(3, 3) = detail::stretch_block_hessian(r.area * kv, lv, hv, projected);
    VecN<6> gs;
    gs.segment<3>(0) = wv;
    gs.segment<3>(3) = wu;
    const Real ks = r.area * r.k_shear;
    Hw += ks * (gs * gs.transpose());
    if (!projected) {
      Hw.block<3, 3>(0, 3) += (ks * s) * Mat3::Identity();
      Hw.block<3, 3>(3, 0) += (ks * s) * Mat3::Identity();
    }
  }
  return energy;
}

/// Baraff-Witkin membrane energy of one triangle, J:
///   E = area/2 * [k_u (|w_u|-1)^2 + k_v (|w_v|-1)^2 + k_shear (w_u . w_v)^2]
/// with k_u = k_warp, k_v = k_weft, each times compression_ratio where that direction is compressed.
/// Vertex order x0, x1, x2 (m); gradient (N) ordered (x0, x1, x2) xyz. The Hessian (N/m) is
/// written when `hess` is non-null and kind != kNone:
///  - kExact: the true second derivative; stretch blocks k area [ŵŵᵀ + (1-1/|w|)(I-ŵŵᵀ)], shear
///    k_s area (∇s∇sᵀ + s [[0,I],[I,0]]) with s = w_u.w_v, ∇s = (w_v, w_u);
///  - kProjected: PSD: (1-1/|w|) clamped at >= 0 (no compressive transverse term) and the shear
///    term Gauss-Newton (the s term dropped).
GD_HD Real stretch_shear_energy(const Vec3& x0, const Vec3& x1, const Vec3& x2,
                                const StretchShearRest& r, Vec9* grad, Mat9* hess,
                                HessianKind kind) {
  Vec3 wu;
  Vec3 wv;
  deformation_columns(x0, x1, x2, r.Dm_inv, &wu, &wv);
  const bool want_hess = hess != nullptr && kind != HessianKind::kNone;
  VecN<6> gw;
  MatN<6> Hw;
  const Real energy = stretch_shear_energy_w(wu, wv, r, grad ? &gw : nullptr, want_hess ? &Hw : nullptr, kind);
  if (grad == nullptr && !want_hess) return energy;
  Vec3 cu;
  Vec3 cv;
  detail::membrane_weights(r.Dm_inv, &cu, &cv);
  if (grad != nullptr) detail::membrane_map_gradient(cu, cv, gw.segment<3>(0), gw.segment<3>(3), grad);
  if (want_hess) detail::membrane_map_hessian(cu, cv, Hw, hess);
  return energy;
}

}  // namespace gd::sim
