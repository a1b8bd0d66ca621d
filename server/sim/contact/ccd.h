#pragma once
/// \file
/// Step safety for self-contact: how far along a Newton step (fraction alpha of the displacement)
/// the positions may move without two primitives coming closer than the fabric thickness.
///
/// Gap of a pair: g = dist - offset (m), dist the point-triangle or segment-segment distance
/// (distance.h), offset the thickness the mid-surfaces must keep. Positions move linearly:
/// x_i(alpha) = x_i + alpha dx_i, alpha in [0, 1].
///
/// Additive CCD by conservative advancement (after Li et al. 2021, "Codimensional IPC" / ACCD):
/// remove the mean displacement (a common translation changes no distance) and bound the relative
/// motion of any two points of the pair by
///   l = |dp| + max_k |dt_k|                 (point-triangle, after removing the mean)
///   l = max(|da0|, |da1|) + max(|db0|, |db1|)   (edge-edge)
/// per unit of alpha, so the gap is l-Lipschitz in alpha: g(alpha + dt) >= g(alpha) - l dt.
/// Starting at g0 = g(0) > 0 the first advance is dt = s g0 / l (the gap stays >= (1 - s) g0 over
/// it, no evaluation needed); later advances are dt = 0.9 g(alpha)/l; each advance is accepted only
/// if the evaluated gap at its end is still >= (1 - s) g0, otherwise the previous alpha is returned.
///
/// Guarantee (up to the rounding of the distance evaluation): over the whole interval [0, alpha]
/// the gap stays > 0 (in fact >= 0.1 (1 - s) g0 everywhere and >= (1 - s) g0 at alpha itself), so
/// the returned fraction never brings the pair closer than the offset and the path there is free of
/// crossings. The answer is conservative: a larger safe alpha may exist (l overestimates the
/// approach speed when the motion is mostly tangential or rotational). alpha >= min(1, s g0 / l) > 0
/// whenever g0 > 0; alpha = 0 when g0 <= 0 (already at or inside the offset) — the caller must not
/// move such a pair closer.
///
/// Cost: one distance evaluation per advance, none for a pair whose cheap distance bound
/// (pair_distance2_lower_bound) already allows the whole step (whole_step_by_bound). A head-on
/// approach stops after 1-3 advances (the bound is tight); motion that is mostly tangential
/// needs up to about l / (0.9 g) advances
/// (sliding a distance l at gap g), hence the max_iter cap, which only makes the answer smaller.

#include <cmath>

#include "sim/contact/distance.h"
#include "sim/types.h"

namespace gd::sim {

/// Default fraction s of the initial gap the CCD may consume (the gap stays >= (1 - s) g0).
inline constexpr Real kCcdGapFraction = Real(0.9);
/// Default cap on conservative-advancement iterations (returns the alpha reached so far).
inline constexpr int kCcdMaxIterations = 1000;
/// The self-contact solver's CCD floor as a fraction of the barrier distance dhat: pairs keep at
/// least this gap (1e-6 m at dhat = 1 mm), far above the rounding of distances and of the exact
/// triangle-triangle test (solver/step_bounds.h self_ccd_inverse_to).
inline constexpr Real kCcdFloorFraction = Real(1e-3);

/// The offset to pass to the CCD of a pair now at distance d0 (m): the floor (m) for a pair more
/// than twice above it, which then keeps at least the floor; half its distance for a pair closer
/// than that, so the working gap (distance - offset) is never less than half the distance. That
/// matters for sliding: conservative advancement needs about (sliding distance) / (working gap)
/// iterations, so a pair held just above a hard floor could not slide along the other layer.
/// Without a floor, repeated steps that each consume 90% of the gap shrink it geometrically
/// (1e-3 m to 1e-13 m in ten, where rounding decides whether the exact test sees a crossing); with
/// it a pair pushed head-on stops near the floor and then closes by at most 45% per iteration while
/// the barrier, steep there, pushes back.
GD_HD Real ccd_floor_offset(Real d0, Real floor) { return d0 > Real(2) * floor ? floor : Real(0.5) * d0; }

/// Global conservative step bound: the largest fraction alpha in [0, 1] such that a pair at gap
/// `gap` (m) keeps at least (1 - fraction) gap when every pair's relative displacement over the full
/// step is at most `max_relative_displacement` (m; e.g. 2 max_i |dx_i| over all vertices):
///   alpha = min(1, fraction · gap / max_relative_displacement).
/// Returns 1 for a zero displacement bound and 0 for gap <= 0. Use with the minimum gap over all
/// candidate pairs (or over all pairs within a broad-phase radius) for a cheap global bound.
GD_HD Real conservative_step_bound(Real gap, Real max_relative_displacement,
                                   Real fraction = kCcdGapFraction) {
  if (!(gap > Real(0))) return Real(0);
  if (!(max_relative_displacement > Real(0))) return Real(1);
  const Real a = fraction * gap / max_relative_displacement;
  return a < Real(1) ? a : Real(1);
}

namespace contact_detail {

/// Conservative advancement given a gap function g(alpha) (returns dist - offset), its start gap
/// g0 and the Lipschitz bound l (m per unit alpha). See the file comment.
template <class GapFn>
GD_HD Real conservative_advancement(const GapFn& gap, Real g0, Real l, Real s, int max_iter) {
  if (!(g0 > Real(0))) return Real(0);
  if (!(l > Real(0))) return Real(1);  // rigid translation (or no motion): distances constant
  const Real target = (Real(1) - s) * g0;
  Real alpha = s * g0 / l;  // first advance: g >= (1 - s) g0 guaranteed by the bound
  if (alpha >= Real(1)) return Real(1);
  Real g = gap(alpha);
  for (int it = 0; it < max_iter; ++it) {
    const Real next = alpha + Real(0.9) * g / l;  // keeps g > 0.1 g(alpha) > 0 over the advance
    const Real a_end = next < Real(1) ? next : Real(1);
    const Real g_end = gap(a_end);
    if (!(g_end >= target)) return alpha;
    alpha = a_end;
    g = g_end;
    if (alpha >= Real(1)) return Real(1);
  }
  return alpha;
}

/// The advancement of a pair whose distance at alpha is dist(alpha): the offset, raised by the
/// CCD floor (ccd_floor_offset) when floor > 0, is subtracted from the distance, which is
/// evaluated once at the start.
template <class DistFn>
GD_HD Real advance_pair(const DistFn& dist, Real offset, Real l, Real s, int max_iter, Real floor) {
  const Real d0 = dist(Real(0));
  if (floor > Real(0)) offset += ccd_floor_offset(d0 - offset, floor);
  auto gap = [&](Real a) { return dist(a) - offset; };
  return conservative_advancement(gap, d0 - offset, l, s, max_iter);
}

/// Whether advance_pair would return the whole step (1) at its first test, decided from a lower
/// bound of the starting distance (pair_distance2_lower_bound, squared) without measuring it:
/// the bound, less a 1e-6 margin, stands for d0 in the floor's offset and the first advance
/// s g0 / l. Where it answers true, advance_pair's own test with the exact d0 (larger) passes too,
/// so the answer is the same; false decides nothing. Saves the distance of most far pairs.
GD_HD bool whole_step_by_bound(Real lower2, Real offset, Real l, Real s, Real floor) {
  const Real lower = sqrt(lower2) * Real(0.999999);
  if (!(lower - offset > Real(2) * floor)) return false;  // the floor's offset needs the exact distance
  const Real g = lower - offset - floor;                  // floor > 0: ccd_floor_offset is the floor here
  return g > Real(0) && s * g >= l;
}

}  // namespace contact_detail

/// Conservative CCD of a point p moving by dp against the triangle (t0, t1, t2) moving by
/// (dt0, dt1, dt2) (all m; positions at alpha: x + alpha dx). Returns alpha in [0, 1] with the
/// guarantee of the file comment: the point-triangle distance stays > offset on [0, alpha] and is
/// >= offset + (1 - s)(dist0 - offset) at alpha. s in (0, 1): fraction of the initial gap that may be
/// consumed (default 0.9); max_iter caps the advancement steps (the alpha reached is returned).
/// floor > 0 raises the offset by ccd_floor_offset(dist0 - offset, floor), from the same distance
/// evaluation the advancement starts with.
GD_HD Real point_triangle_ccd(const Vec3& p, const Vec3& t0, const Vec3& t1, const Vec3& t2, const Vec3& dp,
                              const Vec3& dt0, const Vec3& dt1, const Vec3& dt2, Real offset,
                              Real s = kCcdGapFraction, int max_iter = kCcdMaxIterations, Real floor = 0) {
  const Vec3 mean = Real(0.25) * (dp + dt0 + dt1 + dt2);
  const Vec3 up = dp - mean, u0 = dt0 - mean, u1 = dt1 - mean, u2 = dt2 - mean;
  const Real m01 = u0.norm() > u1.norm() ? u0.norm() : u1.norm();
  const Real l = up.norm() + (m01 > u2.norm() ? m01 : u2.norm());
  auto dist = [&](Real a) {
    return sqrt(point_triangle_distance2(p + a * up, t0 + a * u0, t1 + a * u1, t2 + a * u2, nullptr, nullptr));
  };
  if (contact_detail::whole_step_by_bound(pair_distance2_lower_bound(p, t0, t1, t2, 0), offset, l, s, floor))
    return Real(1);
  return contact_detail::advance_pair(dist, offset, l, s, max_iter, floor);
}

/// Conservative CCD of the segment (a0, a1) moving by (da0, da1) against the segment (b0, b1) moving
/// by (db0, db1) (m). Returns alpha in [0, 1] with the guarantee of the file comment for the
/// segment-segment distance (see point_triangle_ccd for s, max_iter and floor).
GD_HD Real edge_edge_ccd(const Vec3& a0, const Vec3& a1, const Vec3& b0, const Vec3& b1, const Vec3& da0,
                         const Vec3& da1, const Vec3& db0, const Vec3& db1, Real offset,
                         Real s = kCcdGapFraction, int max_iter = kCcdMaxIterations, Real floor = 0) {
  const Vec3 mean = Real(0.25) * (da0 + da1 + db0 + db1);
  const Vec3 ua0 = da0 - mean, ua1 = da1 - mean, ub0 = db0 - mean, ub1 = db1 - mean;
  const Real la = ua0.norm() > ua1.norm() ? ua0.norm() : ua1.norm();
  const Real lb = ub0.norm() > ub1.norm() ? ub0.norm() : ub1.norm();
  const Real l = la + lb;
  auto dist = [&](Real a) {
    return sqrt(edge_edge_distance2(a0 + a * ua0, a1 + a * ua1, b0 + a * ub0, b1 + a * ub1, nullptr, nullptr));
  };
  if (contact_detail::whole_step_by_bound(pair_distance2_lower_bound(a0, a1, b0, b1, 1), offset, l, s, floor))
    return Real(1);
  return contact_detail::advance_pair(dist, offset, l, s, max_iter, floor);
}

}  // namespace gd::sim
