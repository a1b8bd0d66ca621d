// The surface samples' term (element_terms.h, triangle_sample_terms): each sample's barrier and
// lagged friction against a thin collider, mapped to its triangle's corners. Finite differences of
// its energy give its gradient, of its gradient its Hessian (the samples under a pad's face: the
// projected Hessian is the exact one there), and the Hessian is PSD everywhere; a triangle far from
// the pad and a sample switched off add nothing.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "sim/contact/surface_samples.h"
#include "sim/fd_check.h"
#include "sim/solver/element_terms.h"

namespace gd::sim {
namespace surface_sample_terms {

using test::fd_gradient;
using test::fd_jacobian;
using test::near_rel;

/// One triangle (2 cm legs) sampled 4 mm apart, under a pad (a box 2 x 4 x 0.8 cm) at `pose`
/// (start and end), with the View and Params triangle_sample_terms reads.
struct PadOverTriangle {
  std::vector<int> tris = {0, 1, 2};
  SurfaceSamples s;
  std::vector<int> on, sampled = {1};
  std::vector<double> pose, mu, kappa = {3.0};
  ColliderShape shape;
  detail::View V;
  detail::Params P;

  PadOverTriangle(const Eigen::Isometry3d& start, const Eigen::Isometry3d& end, double friction) {
    const std::vector<double> x = {0, 0, 0, 0.02, 0, 0, 0, 0.02, 0};
    s = sample_surface(x, tris, {2e-5, 2e-5, 2e-5}, 0.004);
    on.assign(s.size(), 1);
    for (const Eigen::Isometry3d& p : {start, end}) {
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) pose.push_back(p.linear()(r, c));
      for (int r = 0; r < 3; ++r) pose.push_back(p.translation()[r]);
    }
    mu = {friction};
    shape.type = ColliderType::kBox;
    shape.half_extents = Vec3(0.01, 0.02, 0.004);
    V.tris = tris.data();
    V.n_col = 1;
    V.col_shape = &shape;
    V.col_pose = pose.data();
    V.col_mu = mu.data();
    V.col_kappa = kappa.data();
    V.col_sampled = sampled.data();
    V.n_samp = s.size();
    V.samp_ptr = s.tri_ptr.data();
    V.samp_tri = s.tri.data();
    V.samp_w = s.w.data();
    V.samp_mass = s.mass.data();
    V.samp_on = on.data();
    P.dhat = 1e-3;
    P.kappa_per_mass = 1e4;
    P.friction_eps = 1e-6;
  }
  double energy(const Vec9& x, const Vec9& y, Vec9* g = nullptr, Mat9* H = nullptr) const {
    const Vec3 xs[3] = {x.segment<3>(0), x.segment<3>(3), x.segment<3>(6)};
    const Vec3 ys[3] = {y.segment<3>(0), y.segment<3>(3), y.segment<3>(6)};
    if (g) g->setZero();
    if (H) H->setZero();
    return detail::triangle_sample_terms(V, P, 0, xs, ys, g, H);
  }
};

/// The pad's bottom face `gap` above the plane z = 0 over the point (0.007, 0.007), turned about z.
Eigen::Isometry3d pad_over(double gap) {
  Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
  p.translate(Vec3(0.007, 0.007, gap + 0.004));
  p.rotate(Eigen::AngleAxisd(0.4, Vec3::UnitZ()));
  return p;
}

Vec9 triangle(const Vec3& shift, double tilt) {
  Vec9 x;
  x << 0, 0, 0, 0.02, 0, tilt * 0.02, 0, 0.02, -0.5 * tilt * 0.02;
  for (int a = 0; a < 3; ++a) x.segment<3>(3 * a) += shift;
  return x;
}

TEST(SurfaceSampleTerms, GradientAndHessianMatchFiniteDifferencesUnderAPadsFace) {
  const PadOverTriangle S(pad_over(4e-4), pad_over(4e-4), 0.0);
  for (const double tilt : {0.0, 0.01, -0.015}) {
    SCOPED_TRACE(::testing::Message() << "tilt " << tilt);
    const Vec9 x = triangle(Vec3(0, 0, -1e-4), tilt), y = x;
    Vec9 g;
    Mat9 H;
    const double e = S.energy(x, y, &g, &H);
    ASSERT_GT(e, 0);  // the samples under the pad are within dhat of it
    const double h = test::fd_step(0.02);
    const auto E = [&](const Vec9& z) { return S.energy(z, y); };
    const auto G = [&](const Vec9& z) {
      Vec9 gz;
      S.energy(z, y, &gz);
      return gz;
    };
    EXPECT_TRUE(near_rel(g, fd_gradient<9>(E, x, h), 1e-5, 1e-9));
    EXPECT_TRUE(near_rel(H, fd_jacobian<9, 9>(G, x, h), 1e-4, 1e-3));
    EXPECT_TRUE(test::is_psd(H));
  }
}

TEST(SurfaceSampleTerms, FrictionGradientMatchesFiniteDifferencesAgainstAMovingPad) {
  Eigen::Isometry3d end = pad_over(4e-4);
  end.pretranslate(Vec3(0.001, -0.0005, 0));  // the pad slides 1.1 mm over the step
  const PadOverTriangle S(pad_over(4e-4), end, 0.4);
  const Vec9 y = triangle(Vec3(0, 0, -1e-4), 0.0);
  const Vec9 x = triangle(Vec3(2e-4, 1e-4, -1.2e-4), 0.0);  // the cloth dragged part of the way
  Vec9 g, g0;
  Mat9 H;
  const double e = S.energy(x, y, &g, &H);
  const PadOverTriangle frictionless(pad_over(4e-4), end, 0.0);
  frictionless.energy(x, y, &g0);
  ASSERT_GT((g - g0).norm(), 1e-3 * g0.norm());  // friction takes part
  const auto E = [&](const Vec9& z) { return S.energy(z, y); };
  EXPECT_GT(e, 0);
  EXPECT_TRUE(near_rel(g, fd_gradient<9>(E, x, test::fd_step(0.02)), 1e-5, 1e-9));
  EXPECT_TRUE(test::is_psd(H));
  // The pad drags the cloth its way: the friction's force on the corners, -(g - g0), has a
  // positive component along the pad's slide.
  Vec3 drag = Vec3::Zero();
  for (int a = 0; a < 3; ++a) drag -= (g - g0).segment<3>(3 * a);
  EXPECT_GT(drag.dot(Vec3(0.001, -0.0005, 0)), 0);
}

TEST(SurfaceSampleTerms, FarTrianglesAndSwitchedOffSamplesAddNothing) {
  PadOverTriangle S(pad_over(4e-4), pad_over(4e-4), 0.3);
  const Vec9 x = triangle(Vec3(0, 0, -1e-4), 0.0);
  Vec9 g;
  Mat9 H;
  ASSERT_GT(S.energy(x, x, &g, &H), 0);
  const Vec9 far = triangle(Vec3(0, 0, -0.01), 0.0);  // 1 cm below: beyond dhat
  EXPECT_EQ(S.energy(far, far, &g, &H), 0.0);
  EXPECT_EQ(g.norm(), 0.0);
  EXPECT_EQ(H.norm(), 0.0);
  std::fill(S.on.begin(), S.on.end(), 0);
  EXPECT_EQ(S.energy(x, x, &g, &H), 0.0);
  S.on.assign(S.on.size(), 1);
  S.sampled[0] = 0;  // a collider the samples are not held out of
  EXPECT_EQ(S.energy(x, x, &g, &H), 0.0);
}

TEST(SurfaceSampleTerms, ASampleInsideThePadMakesTheEnergyInfinite) {
  const PadOverTriangle S(pad_over(-2e-4), pad_over(-2e-4), 0.0);  // the pad's face 0.2 mm below the plane
  const Vec9 x = triangle(Vec3::Zero(), 0.0);
  EXPECT_FALSE(std::isfinite(S.energy(x, x)));
}

}  // namespace surface_sample_terms
}  // namespace gd::sim
