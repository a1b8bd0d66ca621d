#pragma once
/// \file
/// Self-contact barrier potentials (IPC log barrier) of a point-triangle and an edge-edge pair,
/// acting on the gap between the cloth mid-surfaces minus the fabric thickness:
///
///   gap  g = dist - offset,   dist = sqrt(d²) (distance.h),   offset = thickness (m)
///   b(g) = -kappa (g - dhat)² ln(g / dhat)   for 0 < g < dhat,   0 for g >= dhat,   +inf for g <= 0
///
/// so the mid-surfaces are kept at least `offset` apart and feel a force only within `offset + dhat`.
/// kappa has units N/m (b ~ kappa g²), dhat and offset m, energies J. Same barrier as the table
/// (energy/table_barrier.h), here applied to the unsquared gap.
///
/// Chain rule through the distance: with D = sqrt(d²),
///   ∇D = ∇d² / (2D),   ∇²D = ∇²d² / (2D) - ∇d² ∇d²ᵀ / (4D³),
///   ∇E = b'(g) ∇D,     ∇²E = b''(g) ∇D ∇Dᵀ + b'(g) ∇²D.
/// The distance Hessian is that of the closest feature's formula (distance.h); across feature
/// boundaries E is C¹. Since b' < 0, the b' ∇²D term makes the exact Hessian indefinite in
/// general; HessianKind::kProjected returns its PSD projection, computed in the at most 5-dimensional
/// subspace where it lives (barrier_hessian.h) rather than by a 12x12 eigen-decomposition, and
/// kTermwise the sum of the two terms' projections, in closed form (the solver's choice in scenes
/// without colliders, SceneOptions::contact_hessian's kAuto).

#include <cmath>

#include <Eigen/Geometry>

#include "sim/contact/barrier_hessian.h"
#include "sim/contact/distance.h"
#include "sim/energy/log_barrier.h"
#include "sim/energy/psd_project.h"
#include "sim/types.h"

namespace gd::sim {

/// Barrier function of the gap g (m), J:
///   b(g) = -kappa (g - dhat)² ln(g / dhat)  for 0 < g < dhat,  0 for g >= dhat,  +inf for g <= 0.
/// Writes b'(g) (N) and b''(g) (N/m) when non-null (0 for g >= dhat and for g <= 0):
///   b'  = -kappa [2 (g - dhat) ln(g/dhat) + (g - dhat)²/g]
///   b'' = -kappa [2 ln(g/dhat) + 4 (g - dhat)/g - (g - dhat)²/g²]
/// b is C² at dhat; on (0, dhat) b > 0, b' < 0 and b'' > 0.
GD_HD Real contact_barrier(Real g, Real dhat, Real kappa, Real* db, Real* d2b) {
  return log_barrier(g, dhat, kappa, db, d2b);
}

/// Normal contact force magnitude (N) of a pair at mid-surface distance `distance` (m):
/// -b'(distance - offset) >= 0; 0 beyond offset + dhat, +INFINITY at or below the offset.
/// This is the lagged lambda of the friction potential (friction.h); for an edge-edge pair
/// multiply it by the mollifier value ee_mollifier(...) used by ee_contact_energy.
GD_HD Real contact_normal_force(Real distance, Real offset, Real dhat, Real kappa) {
  const Real g = distance - offset;
  if (!(g > Real(0))) return Real(INFINITY);
  Real db;
  contact_barrier(g, dhat, kappa, &db, nullptr);
  return -db;
}

/// IPC's mollifier threshold for an edge pair from REST positions (m⁴):
/// eps_x = 1e-3 |A1 - A0|² |B1 - B0|². Compute once per pair (or per edge pair from rest lengths).
GD_HD Real ee_mollifier_threshold(const Vec3& A0, const Vec3& A1, const Vec3& B0, const Vec3& B1) {
  return Real(1e-3) * (A1 - A0).squaredNorm() * (B1 - B0).squaredNorm();
}

/// IPC's edge-edge mollifier (dimensionless), with x = |(a1 - a0) × (b1 - b0)|² (m⁴):
///   m(x) = (2 - x/eps_x) x/eps_x   for x < eps_x,   1 otherwise.
/// m is C¹ at eps_x, m(0) = 0. It fades the edge-edge barrier out as the edges become parallel,
/// where the line-line distance is ill-defined and its derivatives blow up; parallel contacts are
/// then carried by the point-triangle (and endpoint) pairs. Gradient and Hessian with respect to
/// (a0, a1, b0, b1) when non-null:  ∇m = m'(x) ∇x,  ∇²m = m''(x) ∇x∇xᵀ + m'(x) ∇²x,
/// m' = 2/eps_x - 2x/eps_x², m'' = -2/eps_x². eps_x <= 0 disables it (m = 1, zero derivatives).
GD_HD Real ee_mollifier(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1, Real eps_x,
                        VecN<12>* grad, MatN<12>* hess) {
  const Vec3 u = a1 - a0;
  const Vec3 v = b1 - b0;
  VecN<6> g6;
  MatN<6> H6;
  const bool want = grad || hess;
  const Real x = contact_detail::kernel_cross2(u, v, want ? &g6 : nullptr, hess ? &H6 : nullptr);
  if (!(eps_x > Real(0)) || x >= eps_x) {
    if (grad) grad->setZero();
    if (hess) hess->setZero();
    return Real(1);
  }
  const Real ie = Real(1) / eps_x;
  const Real m = (Real(2) - x * ie) * x * ie;
  if (want) {
    const int C[2][4] = {{-1, 1, 0, 0}, {0, 0, -1, 1}};  // u = a1 - a0, v = b1 - b0
    const Real m1 = Real(2) * ie - Real(2) * x * ie * ie;
    const Real m2 = Real(-2) * ie * ie;
    const VecN<6> gm = m1 * g6;
    MatN<6> Hm;
    if (hess) Hm = m2 * (g6 * g6.transpose()) + m1 * H6;
    contact_detail::map_derivatives<2, 4>(C, gm, hess ? &Hm : nullptr, grad, hess);
  }
  return m;
}

namespace contact_detail {

/// Barrier of a pair given its squared distance d2 with derivatives g2, H2 (12 coordinates):
/// E = b(sqrt(d2) - offset), gradient and Hessian by the chain rule in the file comment. Writes
/// grad/hess (H exact; caller projects) when non-null. Returns +inf (zero derivatives) for a gap
/// <= 0 and 0 (zero derivatives) for a gap >= dhat.
GD_HD Real barrier_of_distance2(Real d2, const VecN<12>& g2, const MatN<12>* H2, Real offset, Real dhat,
                                Real kappa, VecN<12>* grad, MatN<12>* hess) {
  const Real D = sqrt(d2);
  Real db, d2b;
  const Real E = contact_barrier(D - offset, dhat, kappa, &db, &d2b);
  if (!(D > Real(0)) || db == Real(0)) {  // inactive, infinite, or zero distance (offset 0)
    if (grad) grad->setZero();
    if (hess) hess->setZero();
    return E;
  }
  const VecN<12> gD = g2 / (Real(2) * D);
  if (grad) *grad = db * gD;
  if (hess && H2) *hess = d2b * (gD * gD.transpose()) + (db / (Real(2) * D)) * *H2 - (db / D) * (gD * gD.transpose());
  // (∇²D = ∇²d²/(2D) - ∇d²∇d²ᵀ/(4D³) = ∇²d²/(2D) - ∇D∇Dᵀ/D.)
  // Without H2: the Gauss-Newton form b'' ∇D∇Dᵀ (drops b' ∇²D), PSD since b'' > 0.
  if (hess && !H2) *hess = d2b * (gD * gD.transpose());
  return E;
}

/// True when the gap of a pair with squared distance d2 is in (0, dhat), i.e. the barrier is active.
GD_HD bool barrier_active(Real d2, Real offset, Real dhat) {
  const Real g = sqrt(d2) - offset;
  return g > Real(0) && g < dhat;
}

}  // namespace contact_detail

/// Point-triangle (vertex-face) contact energy, J: E = b(dist(p, triangle) - offset) with the
/// barrier b of contact_barrier and dist the point-to-closed-triangle distance (distance.h).
/// Vertex order p, t0, t1, t2 (gradient N, Hessian N/m). Returns 0 (zero derivatives) when the gap
/// is >= dhat and +INFINITY (zero derivatives) when it is <= 0 — the line search must reject such
/// a configuration. grad written when non-null; hess written when non-null and kind != kNone
/// (kExact: the true Hessian, indefinite in general; kProjected: project_psd of it; kTermwise: its
/// two terms b''∇D∇Dᵀ and b'∇²D made PSD each on its own; kGaussNewton: the first alone). dist2, when
/// non-null, gets the squared point-triangle distance (the same bits as point_triangle_distance2).
GD_HD Real vf_contact_energy(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2, Real offset,
                             Real dhat, Real kappa, VecN<12>* grad, MatN<12>* hess, HessianKind kind,
                             Real* dist2 = nullptr) {
  const bool want_hess = hess != nullptr && kind != HessianKind::kNone;
  const PointTriangleRegion region = point_triangle_closest_feature(p, t0, t1, t2);
  // With the Hessian the pair is an active one (within dhat, selected there): the distance's
  // gradient comes with its value in one evaluation (the value's bits are the same either way).
  VecN<12> g2;
  MatN<12> H2;
  const bool closed_form = want_hess && (kind == HessianKind::kProjected || kind == HessianKind::kTermwise);
  const bool exact_h2 = want_hess && kind == HessianKind::kExact;
  const Real d2 = point_triangle_distance2(p, t0, t1, t2, region, want_hess ? &g2 : nullptr, exact_h2 ? &H2 : nullptr);
  if (dist2) *dist2 = d2;
  if (!contact_detail::barrier_active(d2, offset, dhat) || (grad == nullptr && !want_hess)) {
    if (grad) grad->setZero();
    if (want_hess) hess->setZero();
    return contact_barrier(sqrt(d2) - offset, dhat, kappa, nullptr, nullptr);
  }
  if (!want_hess) point_triangle_distance2(p, t0, t1, t2, region, &g2, nullptr);
  const Real E = contact_detail::barrier_of_distance2(d2, g2, exact_h2 ? &H2 : nullptr, offset, dhat, kappa, grad,
                                                      want_hess && !closed_form ? hess : nullptr);
  if (closed_form) {
    Real db, d2b;
    contact_barrier(sqrt(d2) - offset, dhat, kappa, &db, &d2b);
    const Vec3 x[4] = {p, t0, t1, t2};
    closed_form_barrier_hessian(kind, x, vf_region_param(region), db, d2b, hess);
  }
  return E;
}

/// Edge-edge contact energy, J: E = m(x) b(dist(a, b) - offset) with the segment-segment distance
/// (distance.h), the barrier b of contact_barrier and IPC's mollifier m (ee_mollifier; pass
/// eps_x = ee_mollifier_threshold of the rest positions, or <= 0 to disable). Product rule:
///   ∇E = m ∇B + B ∇m,   ∇²E = m ∇²B + B ∇²m + ∇m ∇Bᵀ + ∇B ∇mᵀ   (B = b(dist - offset)).
/// The mollifier keeps E smooth (C¹ in positions; without it the line-line formula's derivatives
/// blow up) as the edges become parallel, where E -> 0. Vertex order a0, a1, b0, b1 (gradient N,
/// Hessian N/m). Returns 0 when the gap is >= dhat and +INFINITY when it is <= 0 (zero
/// derivatives; even for parallel edges, so a penetrating configuration is always rejected).
/// grad/hess/dist2 as in vf_contact_energy. The Hessian kinds: kExact the product rule above;
/// kProjected m times the PSD projection of ∇²B (closed form, barrier_hessian.h), kTermwise m times
/// its termwise projection (the same file), kGaussNewton m times B's Gauss-Newton term. Where the
/// mollifier is active (near-parallel edges, m < 1) the
/// last two drop the terms with ∇m, ∇²m: the gradient, and so the solution, are exact, only the
/// Newton model differs. Projecting the full product instead (a 12x12 eigen-decomposition per
/// pair) cost fold/20000 18% more time per step, with 4.83 against 4.58 Newton iterations
/// (docs/physics.md, eighteenth round).
GD_HD Real ee_contact_energy(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1, Real offset,
                             Real dhat, Real kappa, Real eps_x, VecN<12>* grad, MatN<12>* hess,
                             HessianKind kind, Real* dist2 = nullptr) {
  const bool want_hess = hess != nullptr && kind != HessianKind::kNone;
  const bool exact = want_hess && kind == HessianKind::kExact;
  const EdgeEdgeRegion region = edge_edge_closest_feature(a0, a1, b0, b1);
  // With the Hessian (an active pair) the distance's derivatives come with its value, as in
  // vf_contact_energy.
  VecN<12> g2;
  MatN<12> H2;
  const Real d2 = edge_edge_distance2(a0, a1, b0, b1, region, want_hess ? &g2 : nullptr, exact ? &H2 : nullptr);
  if (dist2) *dist2 = d2;
  if (!contact_detail::barrier_active(d2, offset, dhat)) {
    if (grad) grad->setZero();
    if (want_hess) hess->setZero();
    return contact_barrier(sqrt(d2) - offset, dhat, kappa, nullptr, nullptr);
  }
  const bool want = grad != nullptr || want_hess;
  VecN<12> gm;
  MatN<12> Hm;
  const Real m = ee_mollifier(a0, a1, b0, b1, eps_x, want ? &gm : nullptr, exact ? &Hm : nullptr);
  if (!want) return m * contact_barrier(sqrt(d2) - offset, dhat, kappa, nullptr, nullptr);
  VecN<12> gB;
  MatN<12> HB;
  // kProjected / kTermwise: m times the closed-form projection of ∇²B (whole, or term by term);
  // kGaussNewton: m times B's Gauss-Newton term. All leave the mollifier's derivatives out of the
  // Hessian (see the function comment).
  const bool closed_form = want_hess && (kind == HessianKind::kProjected || kind == HessianKind::kTermwise);
  if (!want_hess) edge_edge_distance2(a0, a1, b0, b1, region, &g2, nullptr);
  const Real B = contact_detail::barrier_of_distance2(d2, g2, exact ? &H2 : nullptr, offset, dhat, kappa, &gB,
                                                      want_hess && !closed_form ? &HB : nullptr);
  if (grad) *grad = m * gB + B * gm;
  if (closed_form) {
    Real db, d2b;
    contact_barrier(sqrt(d2) - offset, dhat, kappa, &db, &d2b);
    const Vec3 x[4] = {a0, a1, b0, b1};
    closed_form_barrier_hessian(kind, x, ee_region_param(region), db, d2b, hess);
    if (m != Real(1)) *hess *= m;
  } else if (exact) {
    const MatN<12> cross = gm * gB.transpose();
    *hess = m * HB + B * Hm + cross + cross.transpose();
  } else if (want_hess) {
    *hess = m * HB;
  }
  return m * B;
}

}  // namespace gd::sim
