#pragma once
/// \file
/// Lagged, smoothed Coulomb friction of a self-contact pair (IPC friction potential), the
/// 12-coordinate version of energy/table_friction.h.
///
/// Lagging: at the start of the step (positions x^t) the caller fixes, per active contact pair,
///   - lambda: the normal force magnitude (N), contact_normal_force(dist(x^t), ...) (barrier.h;
///     times the mollifier for an edge-edge pair),
///   - w: the signed closest-point weights of the four vertices, so that Σ_i w_i x_i is the
///     separation vector between the two closest points (dimensionless):
///       vertex-face (p, t0, t1, t2):  w = (1, -β0, -β1, -β2), β the barycentric weights of the
///                                     closest point on the triangle;
///       edge-edge (a0, a1, b0, b1):   w = (1 - sa, sa, -(1 - sb), -sb), sa, sb the closest-point
///                                     parameters on the two edges;
///   - T: a 3x2 orthonormal basis of the plane orthogonal to the contact normal.
/// vf_friction_frame / ee_friction_frame compute w and T from x^t.
///
/// Within the step the relative tangential slip is u = Tᵀ Σ_i w_i (x_i - x_i^t) (m) and
///   E = mu lambda f0(|u|),  f0(y) = -y³/(3 eps²) + y²/eps + eps/3 for y < eps, y otherwise,
/// eps = eps_v h (m). This is exactly plane_friction_energy applied to the relative displacement
/// Δ = Σ_i w_i (x_i - x_i^t), whose Jacobian with respect to vertex i is w_i I:
///   ∇_i E = w_i g3,   ∇²_{ij} E = w_i w_j H3   (g3, H3: plane_friction_energy's gradient and
///   Hessian at Δ). The Hessian is PSD everywhere (exact = projected).

#include <cmath>

#include <Eigen/Geometry>

#include "sim/contact/distance.h"
#include "sim/energy/table_friction.h"
#include "sim/types.h"

namespace gd::sim {

/// Lagged geometric data of one contact pair (see the file comment).
struct ContactFrictionFrame {
  VecN<4> w;                     ///< signed closest-point weights of the 4 vertices
  Eigen::Matrix<Real, 3, 2> T;   ///< orthonormal tangent basis (columns), orthogonal to n
  Vec3 n;                        ///< unit contact normal, from the second primitive towards the first
};

/// Friction frame of a vertex-face pair (p; t0, t1, t2) at step-start positions:
/// β = barycentric weights of the closest point c on the closed triangle
/// (point_triangle_closest_feature), w = (1, -β0, -β1, -β2), n = (p - c)/|p - c| (the triangle's
/// unit normal (t1-t0)×(t2-t0) if p lies on the triangle, or any unit vector for a fully
/// degenerate configuration), T = plane_tangent_basis(n). For the face region n is ± the
/// triangle normal; for edge/vertex regions it is the true separation direction.
GD_HD ContactFrictionFrame vf_friction_frame(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2) {
  Vec3 beta;
  point_triangle_closest_feature(p, t0, t1, t2, &beta);
  ContactFrictionFrame f;
  f.w = VecN<4>(Real(1), -beta[0], -beta[1], -beta[2]);
  const Vec3 sep = p - (beta[0] * t0 + beta[1] * t1 + beta[2] * t2);
  Vec3 n = sep;
  if (!(n.squaredNorm() > Real(0))) n = (t1 - t0).cross(t2 - t0);
  if (!(n.squaredNorm() > Real(0))) n = Vec3::UnitZ();
  f.n = n.normalized();
  plane_tangent_basis(f.n, &f.T);
  return f;
}

/// Friction frame of an edge-edge pair (a0, a1; b0, b1) at step-start positions:
/// sa, sb = closest-point parameters on the closed segments (edge_edge_closest_feature),
/// w = (1 - sa, sa, -(1 - sb), -sb), n = (ca - cb)/|ca - cb| with ca, cb the closest points
/// (if they coincide: the unit (a1-a0)×(b1-b0), or a unit vector orthogonal to a1-a0 for parallel
/// edges, or any unit vector for a fully degenerate pair), T = plane_tangent_basis(n).
GD_HD ContactFrictionFrame ee_friction_frame(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1) {
  Real sa, sb;
  edge_edge_closest_feature(a0, a1, b0, b1, &sa, &sb);
  ContactFrictionFrame f;
  f.w = VecN<4>(Real(1) - sa, sa, -(Real(1) - sb), -sb);
  const Vec3 u = a1 - a0;
  Vec3 n = (a0 + sa * u) - (b0 + sb * (b1 - b0));
  if (!(n.squaredNorm() > Real(0))) n = u.cross(b1 - b0);
  if (!(n.squaredNorm() > Real(0))) {
    const Vec3 ref = fabs(u.x()) < fabs(u.y()) ? Vec3(Vec3::UnitX()) : Vec3(Vec3::UnitY());
    n = u.cross(ref);
  }
  if (!(n.squaredNorm() > Real(0))) n = Vec3::UnitZ();
  f.n = n.normalized();
  plane_tangent_basis(f.n, &f.T);
  return f;
}

/// Lagged smoothed friction energy of a contact pair, J (see the file comment):
///   Δ = Σ_i w_i (x_i - x_t_i),  u = Tᵀ Δ,  E = mu lambda f0(|u|).
/// x, x_t: the four vertices now and at step start, stacked vertex-major (m), in the pair's vertex
/// order (p, t0, t1, t2 or a0, a1, b0, b1); w, T from a ContactFrictionFrame; mu friction
/// coefficient; lambda lagged normal force (N); eps = eps_v h > 0 (m). Gradient (N): w_i times the
/// 3-vector mu lambda f1(|u|) T û, so when sliding (|u| >= eps) the force on the first primitive
/// has magnitude mu lambda and opposes the slip, and the forces on the pair sum to
/// (Σ w_i) x that, i.e. zero (Σ w_i = 0) — friction is internal. Hessian (N/m):
/// w_i w_j T mu lambda [f1' ûûᵀ + (f1/|u|)(I - ûûᵀ)] Tᵀ, PSD. Pointers may be null.
GD_HD Real contact_friction_energy(const VecN<12>& x, const VecN<12>& x_t, const VecN<4>& w,
                                   const Eigen::Matrix<Real, 3, 2>& T, Real mu, Real lambda, Real eps,
                                   VecN<12>* grad, MatN<12>* hess) {
  Vec3 delta = Vec3::Zero();
  for (int i = 0; i < 4; ++i) delta += w[i] * (x.segment<3>(3 * i) - x_t.segment<3>(3 * i));
  Vec3 g3;
  Mat3 H3;
  const Real E = plane_friction_energy(delta, Vec3::Zero(), T, mu, lambda, eps, grad ? &g3 : nullptr,
                                       hess ? &H3 : nullptr);
  if (grad)
    for (int i = 0; i < 4; ++i) grad->segment<3>(3 * i) = w[i] * g3;
  if (hess)
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) hess->block<3, 3>(3 * i, 3 * j) = (w[i] * w[j]) * H3;
  return E;
}

}  // namespace gd::sim
