#include "sim/contact/barrier.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <random>

#include "sim/fd_check.h"

namespace gd::sim {
namespace {

using V12 = VecN<12>;
using M12 = MatN<12>;

using test::stack4;

using test::seg;

// Unit vector orthogonal to v.
Vec3 orthogonal_unit(const Vec3& v, std::mt19937& rng) {
  Vec3 r = test::random_vec3(rng);
  return (r - r.dot(v) / v.squaredNorm() * v).normalized();
}

TEST(ContactBarrier, ScalarBarrierDerivatives) {
  const Real dhat = 1e-3, kappa = 1e4;
  for (Real g : {1e-7, 1e-5, 2e-4, 5e-4, 9.9e-4}) {
    Real db, d2b;
    const Real b = contact_barrier(g, dhat, kappa, &db, &d2b);
    EXPECT_GT(b, 0);
    EXPECT_LT(db, 0);
    EXPECT_GT(d2b, 0);
    const Real h = 1e-6 * g;
    Real dbp, dbm;
    const Real bp = contact_barrier(g + h, dhat, kappa, &dbp, nullptr);
    const Real bm = contact_barrier(g - h, dhat, kappa, &dbm, nullptr);
    EXPECT_NEAR(db, (bp - bm) / (2 * h), 1e-6 * std::abs(db));
    EXPECT_NEAR(d2b, (dbp - dbm) / (2 * h), 1e-5 * std::abs(d2b));
    EXPECT_NEAR(contact_normal_force(g + 2e-4, 2e-4, dhat, kappa), -db, 1e-9 * std::abs(db));
  }
  Real db = 1, d2b = 1;
  EXPECT_EQ(contact_barrier(dhat, dhat, kappa, &db, &d2b), 0.0);
  EXPECT_EQ(db, 0.0);
  EXPECT_EQ(d2b, 0.0);
  EXPECT_TRUE(std::isinf(contact_barrier(0.0, dhat, kappa, &db, &d2b)));
  EXPECT_TRUE(std::isinf(contact_barrier(-1e-9, dhat, kappa, nullptr, nullptr)));
  EXPECT_TRUE(std::isinf(contact_normal_force(1e-4, 1e-4, dhat, kappa)));
  EXPECT_EQ(contact_normal_force(1.2e-3, 1e-4, dhat, kappa), 0.0);
}

struct Cfg {
  Real offset, dhat, kappa;
};
constexpr Cfg kCfgs[] = {{2.6e-4, 1e-3, 1e5}, {1.9e-4, 5e-4, 3e3}, {0.0, 1e-3, 1e4}};

// FD check of a 12-coordinate energy, skipped (returns false) when the closest-feature region
// changes within the stencil. db, d2b: the barrier's b'(gap) and b''(gap) at x (for the termwise
// Hessian's reference; used where there is no projected_reference). A model other than the exact
// Hessian's projections (the mollified edge-edge barrier) gives both of its references.
template <class E, class R>
bool fd_check_energy(const E& energy, const R& region_of, const V12& x, Real h, Real tol_h, Real db, Real d2b,
                     const std::function<M12()>& projected_reference = nullptr,
                     const std::function<M12()>& termwise_reference = nullptr) {
  const auto r0 = region_of(x);
  for (int i = 0; i < 12; ++i)
    for (Real s : {-h, h}) {
      V12 y = x;
      y[i] += s;
      if (region_of(y) != r0) return false;
    }
  V12 g;
  M12 H;
  const Real e = energy(x, &g, &H, HessianKind::kExact);
  EXPECT_GT(e, 0);
  auto f = [&](const V12& y) { return energy(y, nullptr, nullptr, HessianKind::kNone); };
  auto gf = [&](const V12& y) {
    V12 gg;
    energy(y, &gg, nullptr, HessianKind::kNone);
    return gg;
  };
  EXPECT_TRUE(test::near_rel(g, test::fd_gradient<12>(f, x, h), 1e-5)) << "region " << int(r0);
  EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<12, 12>(gf, x, h), tol_h)) << "region " << int(r0);
  M12 Hp;
  V12 gp;
  EXPECT_EQ(energy(x, &gp, &Hp, HessianKind::kProjected), e);
  EXPECT_EQ((gp - g).norm(), 0.0);
  EXPECT_TRUE(test::is_psd(Hp, 1e-9));
  // The termwise Hessian: the same energy and gradient, PSD, and within tol of `reference`.
  auto termwise_matches = [&](const M12& reference, Real tol) {
    M12 Ht;
    V12 gt;
    EXPECT_EQ(energy(x, &gt, &Ht, HessianKind::kTermwise), e);
    EXPECT_EQ((gt - g).norm(), 0.0);
    EXPECT_LE((Ht - reference).norm(), tol) << "region " << int(r0);
    EXPECT_TRUE(test::is_psd(Ht, 1e-9));
    return Ht;
  };
  if (projected_reference) {  // a model other than the projected exact Hessian
    const M12 reference = projected_reference();
    // Near-parallel edges: the eigenvalues span ~18 decades (the line-line distance's curvature
    // grows as 1/sin² of the angle), so the two computations agree to ~1e-7 of the largest.
    EXPECT_LE((Hp - reference).norm(), 1e-6 * reference.norm()) << "region " << int(r0);
    if (termwise_reference) {
      const M12 termwise = termwise_reference();
      termwise_matches(termwise, 1e-6 * termwise.norm());
    }
  } else {
    // The closed-form projection (barrier_hessian.h) is the eigen-projection of the exact Hessian.
    M12 reference = H;
    project_psd<12>(&reference);
    EXPECT_LE((Hp - reference).norm(), 1e-7 * H.norm()) << "region " << int(r0);
    // Projection only removes the negative part: Hp - H is positive semi-definite (to the closed
    // form's rounding, ~1e-9 of |H| where the barrier's curvature spans many decades).
    EXPECT_GE(test::min_eigenvalue(M12(Hp - H)), -1e-8 * H.norm());
    // Term by term (barrier_hessian.h): b'' ∇D ∇Dᵀ + project_psd(b' ∇²D), with ∇D = ∇E / b'.
    const V12 grad_d = g / db;
    M12 curvature = H - d2b * grad_d * grad_d.transpose();
    project_psd<12>(&curvature);
    const M12 Ht = termwise_matches(M12(d2b * grad_d * grad_d.transpose() + curvature), 1e-7 * H.norm());
    // Above the exact Hessian (only negative parts dropped): Newton's model descends.
    EXPECT_GE(test::min_eigenvalue(M12(Ht - H)), -1e-8 * H.norm());
  }
  // Translation invariance: the gradient blocks sum to zero.
  EXPECT_LT((seg(g, 0) + seg(g, 1) + seg(g, 2) + seg(g, 3)).norm(), 1e-9 * g.norm());
  return true;
}

TEST(ContactBarrier, VertexFaceEnergyMatchesFiniteDifferences) {
  std::mt19937 rng(201);
  std::uniform_real_distribution<Real> u01(0, 1);
  std::array<int, 7> checked{};
  for (const Cfg& c : kCfgs) {
    for (int it = 0; it < 90; ++it) {
      // A 1 cm triangle near the origin (keeps the tiny FD steps well above the coordinate ulp).
      const Vec3 o = 0.01 * test::random_vec3(rng);
      const Vec3 t0 = o + 0.01 * test::random_vec3(rng), t1 = o + 0.01 * test::random_vec3(rng),
                 t2 = o + 0.01 * test::random_vec3(rng);
      // Closest point on a random feature, then a random direction at distance offset + gap.
      Vec3 w(u01(rng), u01(rng), u01(rng));
      const int kind = it % 3, k = (it / 3) % 3;
      if (kind == 1) w[k] = 0;                  // on an edge
      if (kind == 2) w = Vec3::Unit(k);         // at a vertex
      w /= w.sum();
      const Vec3 cpt = w[0] * t0 + w[1] * t1 + w[2] * t2;
      const Real gap = c.dhat * std::pow(10.0, -3 * u01(rng));
      const Vec3 p = cpt + (c.offset + gap) * test::random_vec3(rng).normalized();
      const Real dist = std::sqrt(point_triangle_distance2(p, t0, t1, t2, nullptr, nullptr));
      if (!(dist - c.offset > 1e-3 * gap) || dist - c.offset >= c.dhat) continue;
      const V12 x = stack4(p, t0, t1, t2);
      auto energy = [&](const V12& y, V12* g, M12* H, HessianKind k) {
        return vf_contact_energy(seg(y, 0), seg(y, 1), seg(y, 2), seg(y, 3), c.offset, c.dhat, c.kappa, g, H, k);
      };
      auto region = [](const V12& y) { return point_triangle_closest_feature(seg(y, 0), seg(y, 1), seg(y, 2), seg(y, 3)); };
      Real db = 0, d2b = 0;
      contact_barrier(dist - c.offset, c.dhat, c.kappa, &db, &d2b);
      // The barrier varies on the scale of min(gap, dhat - gap).
      if (fd_check_energy(energy, region, x, 1e-4 * std::min(dist - c.offset, c.dhat - (dist - c.offset)), 1e-4, db,
                          d2b))
        checked[static_cast<int>(region(x))]++;
    }
  }
  for (int k = 0; k < 7; ++k) EXPECT_GE(checked[k], 3) << "region " << k;
}

TEST(ContactBarrier, EdgeEdgeEnergyMatchesFiniteDifferences) {
  std::mt19937 rng(203);
  std::uniform_real_distribution<Real> u01(0, 1);
  std::array<int, 9> checked{};
  int mollified = 0;
  for (const Cfg& c : kCfgs) {
    for (int it = 0; it < 120; ++it) {
      const Vec3 o = 0.01 * test::random_vec3(rng);
      const Vec3 a0 = o + 0.01 * test::random_vec3(rng), a1 = o + 0.01 * test::random_vec3(rng);
      const Vec3 u = a1 - a0;
      const Real gap = c.dhat * std::pow(10.0, -3 * u01(rng));
      const Real sa = it % 4 == 3 ? Real((it / 4) % 2) : u01(rng);
      const Vec3 ca = a0 + sa * u;
      Vec3 n, v;
      const int kind = it % 4;
      if (kind <= 1) {  // interior-interior: common normal n ⟂ u, b ⟂ n through cb
        n = orthogonal_unit(u, rng);
        const Vec3 w = u.normalized().cross(n);
        const Real ang = kind == 0 ? 3.14159 * (u01(rng) - 0.5) : 2e-3 * (u01(rng) - 0.5);  // kind 1: nearly parallel
        v = 0.01 * (0.5 + u01(rng)) * (std::cos(ang) * u.normalized() + std::sin(ang) * w);
      } else {  // endpoint configurations: random direction, random b
        n = test::random_vec3(rng).normalized();
        v = 0.01 * test::random_vec3(rng);
      }
      const Vec3 cb = ca - (c.offset + gap) * n;
      const Real sb = kind >= 2 ? Real((it / 8) % 2) : u01(rng);
      const Vec3 b0 = cb - sb * v, b1 = cb + (1 - sb) * v;
      const Real dist = std::sqrt(edge_edge_distance2(a0, a1, b0, b1, nullptr, nullptr));
      if (!(dist - c.offset > 1e-3 * gap) || dist - c.offset >= c.dhat) continue;
      // eps_x from "rest" = current lengths.
      const Real eps_x = ee_mollifier_threshold(a0, a1, b0, b1);
      const bool moll = u.cross(v).squaredNorm() < eps_x;
      const V12 x = stack4(a0, a1, b0, b1);
      auto energy = [&](const V12& y, V12* g, M12* H, HessianKind k) {
        return ee_contact_energy(seg(y, 0), seg(y, 1), seg(y, 2), seg(y, 3), c.offset, c.dhat, c.kappa, eps_x, g, H, k);
      };
      auto region = [&](const V12& y) {
        // Also keep the stencil on one side of the mollifier threshold.
        const Real xm = (seg(y, 1) - seg(y, 0)).cross(seg(y, 3) - seg(y, 2)).squaredNorm();
        return static_cast<int>(edge_edge_closest_feature(seg(y, 0), seg(y, 1), seg(y, 2), seg(y, 3))) +
               (xm < eps_x ? 100 : 0);
      };
      SCOPED_TRACE(::testing::Message() << "gap " << dist - c.offset << " moll " << moll << " x/eps " << u.cross(v).squaredNorm() / eps_x << " it " << it);
      // Where the mollifier is active the projected Hessian is m times the projection of the
      // unmollified barrier's exact Hessian (ee_contact_energy's comment).
      // Term by term likewise: m times b'' ∇D ∇Dᵀ + project_psd(b' ∇²D) of the unmollified barrier.
      Real db = 0, d2b = 0;
      contact_barrier(dist - c.offset, c.dhat, c.kappa, &db, &d2b);
      std::function<M12()> reference, termwise;
      if (moll) {
        reference = [&] {
          M12 Hb;
          ee_contact_energy(a0, a1, b0, b1, c.offset, c.dhat, c.kappa, 0.0, nullptr, &Hb, HessianKind::kExact);
          project_psd<12>(&Hb);
          return M12(ee_mollifier(a0, a1, b0, b1, eps_x, nullptr, nullptr) * Hb);
        };
        termwise = [&] {
          V12 gb;
          M12 Hb;
          ee_contact_energy(a0, a1, b0, b1, c.offset, c.dhat, c.kappa, 0.0, &gb, &Hb, HessianKind::kExact);
          const V12 grad_d = gb / db;
          M12 curvature = Hb - d2b * grad_d * grad_d.transpose();
          project_psd<12>(&curvature);
          return M12(ee_mollifier(a0, a1, b0, b1, eps_x, nullptr, nullptr) *
                     (d2b * grad_d * grad_d.transpose() + curvature));
        };
      }
      if (fd_check_energy(energy, region, x, 1e-4 * std::min(dist - c.offset, c.dhat - (dist - c.offset)), 2e-4, db,
                          d2b, reference, termwise)) {
        checked[region(x) % 100]++;
        mollified += moll;
      }
    }
  }
  for (int k = 0; k < 9; ++k) EXPECT_GE(checked[k], 2) << "region " << k;
  EXPECT_GE(mollified, 10);
}

TEST(ContactBarrier, MollifierDerivativesAndLimits) {
  std::mt19937 rng(207);
  for (int it = 0; it < 40; ++it) {
    const Vec3 a0 = test::random_vec3(rng), a1 = test::random_vec3(rng), b0 = test::random_vec3(rng);
    const Vec3 u = a1 - a0;
    const Vec3 w = orthogonal_unit(u, rng);
    const Vec3 b1 = b0 + 0.7 * u + (0.02 * (it + 1) / 40.0) * u.norm() * w;
    const Real eps_x = ee_mollifier_threshold(a0, a1, b0, b1);
    const V12 x = stack4(a0, a1, b0, b1);
    auto f = [&](const V12& y) { return ee_mollifier(seg(y, 0), seg(y, 1), seg(y, 2), seg(y, 3), eps_x, nullptr, nullptr); };
    auto gf = [&](const V12& y) {
      V12 g;
      ee_mollifier(seg(y, 0), seg(y, 1), seg(y, 2), seg(y, 3), eps_x, &g, nullptr);
      return g;
    };
    V12 g;
    M12 H;
    const Real m = ee_mollifier(a0, a1, b0, b1, eps_x, &g, &H);
    EXPECT_GT(m, 0);
    EXPECT_LE(m, 1);
    if (m < 1) {
      EXPECT_TRUE(test::near_rel(g, test::fd_gradient<12>(f, x, 1e-7), 1e-6));
      EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<12, 12>(gf, x, 1e-7), 1e-5));
    } else {
      EXPECT_EQ(g.norm(), 0.0);
    }
  }
  // Exactly parallel: m = 0. Disabled: m = 1.
  EXPECT_EQ(ee_mollifier(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(2, 1, 0), 1e-3, nullptr, nullptr), 0.0);
  EXPECT_EQ(ee_mollifier(Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(2, 1, 0), 0.0, nullptr, nullptr), 1.0);
}

TEST(ContactBarrier, ZeroBeyondDhatInfiniteAtContact) {
  const Vec3 t0(0, 0, 0), t1(0.01, 0, 0), t2(0, 0.01, 0);
  const Real offset = 2e-4, dhat = 1e-3, kappa = 1e4;
  V12 g;
  M12 H;
  for (Real z : {offset + dhat, offset + 1.01 * dhat, 0.5}) {
    g.setOnes();
    H.setOnes();
    EXPECT_EQ(vf_contact_energy(Vec3(0.002, 0.003, z), t0, t1, t2, offset, dhat, kappa, &g, &H, HessianKind::kExact), 0.0);
    EXPECT_EQ(g.norm(), 0.0);
    EXPECT_EQ(H.norm(), 0.0);
    EXPECT_EQ(ee_contact_energy(Vec3(0.002, -0.003, z), Vec3(0.002, 0.003, z), t0, t1, offset, dhat, kappa, 1e-12, &g, &H,
                                HessianKind::kProjected),
              0.0);
    EXPECT_EQ(g.norm(), 0.0);
  }
  // (At exactly dist = offset the answer depends on the rounding of sqrt(d²); stay just inside.)
  for (Real z : {(1 - 1e-9) * offset, 0.5 * offset, 0.0, -0.5 * offset}) {
    const Real e = vf_contact_energy(Vec3(0.002, 0.003, z), t0, t1, t2, offset, dhat, kappa, &g, &H, HessianKind::kExact);
    EXPECT_TRUE(std::isinf(e) && e > 0) << z;
    EXPECT_TRUE(g.allFinite());
    EXPECT_TRUE(H.allFinite());
    // Edge-edge: even exactly parallel edges (mollifier 0) report +inf when penetrating.
    EXPECT_TRUE(std::isinf(ee_contact_energy(Vec3(0, -0.003, z), Vec3(0, 0.003, z), t0, t2, offset, dhat, kappa,
                                             1e-12, &g, &H, HessianKind::kExact)));
  }
  // Monotone growth towards the offset; face distance.
  Real prev = 0;
  for (Real gap : {0.9e-3, 0.5e-3, 1e-4, 1e-6, 1e-9}) {
    const Real e = vf_contact_energy(Vec3(0.002, 0.003, offset + gap), t0, t1, t2, offset, dhat, kappa, &g, nullptr,
                                     HessianKind::kNone);
    EXPECT_GT(e, prev);
    EXPECT_LT(g[2], 0);  // pushes the vertex up, away from the face
    EXPECT_NEAR(-g[2], contact_normal_force(offset + gap, offset, dhat, kappa), 1e-9 * std::abs(g[2]));
    prev = e;
  }
  // kNone leaves the Hessian untouched.
  H.setConstant(7);
  vf_contact_energy(Vec3(0.002, 0.003, offset + 1e-4), t0, t1, t2, offset, dhat, kappa, &g, &H, HessianKind::kNone);
  EXPECT_EQ(H(0, 0), 7);
}

}  // namespace
}  // namespace gd::sim

namespace gd::sim {
namespace {

// The Gauss-Newton pair Hessian is (b'' - b'/d) ∇d∇dᵀ: symmetric, PSD, rank one along the
// gradient, and equal to the exact Hessian wherever the distance is linear (the point's own block
// above a face).
TEST(ContactBarrier, GaussNewtonHessianIsRankOnePsdAlongTheGradient) {
  const Vec3 t0(0, 0, 0), t1(0.01, 0, 0), t2(0, 0.01, 0);
  const Real dhat = 1e-3, kappa = 10;
  for (const Real gap : {2e-4, 5e-4, 9e-4}) {
    const Vec3 p(0.003, 0.002, gap);  // above the face interior
    VecN<12> g;
    MatN<12> Hgn, Hex;
    vf_contact_energy(p, t0, t1, t2, 0.0, dhat, kappa, &g, &Hgn, HessianKind::kGaussNewton);
    vf_contact_energy(p, t0, t1, t2, 0.0, dhat, kappa, nullptr, &Hex, HessianKind::kExact);
    EXPECT_TRUE(Hgn.isApprox(Hgn.transpose(), 1e-12));
    const Eigen::SelfAdjointEigenSolver<MatN<12>> es(Hgn);
    EXPECT_GE(es.eigenvalues().minCoeff(), -1e-9 * es.eigenvalues().maxCoeff());
    // Rank one, along the gradient.
    EXPECT_LT(es.eigenvalues()(10), 1e-9 * es.eigenvalues()(11));
    const VecN<12> v = es.eigenvectors().col(11);
    EXPECT_NEAR(std::abs(v.dot(g.normalized())), 1.0, 1e-9);
    // Face interior: d = n.(p - t0) is linear in p (∇²_pp d = 0), so the point's own block of
    // the Gauss-Newton Hessian equals the exact one.
    const Mat3 pp_gn = Hgn.topLeftCorner<3, 3>(), pp_ex = Hex.topLeftCorner<3, 3>();
    EXPECT_TRUE(pp_gn.isApprox(pp_ex, 1e-9));
  }
}

}  // namespace
}  // namespace gd::sim
