#include "sim/contact/collider.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <vector>

#include "sim/contact/distance.h"
#include "sim/demand.h"
#include "sim/fd_check.h"

namespace gd::sim {
namespace {

using Mat32 = Eigen::Matrix<Real, 3, 2>;
using Tri = Eigen::Vector3i;

constexpr Real kNaN = std::numeric_limits<Real>::quiet_NaN();

Real uniform(std::mt19937& rng, Real a, Real b) { return std::uniform_real_distribution<Real>(a, b)(rng); }

// --- reference ("brute force") distances, written independently of collider.h -------------------

/// Box: outside, distance to the clamped point; inside, minus the distance to the nearest face plane.
Real ref_box_distance(const Vec3& p, const Vec3& h) {
  const Vec3 c = p.cwiseMax(-h).cwiseMin(h);
  if ((p - c).squaredNorm() > 0) return (p - c).norm();
  Real best = INFINITY;
  for (int i = 0; i < 3; ++i) best = std::min(best, h[i] - std::fabs(p[i]));
  return -best;
}

/// Capsule: distance to the segment (distance.h) minus the radius.
Real ref_capsule_distance(const Vec3& p, Real r, Real L) {
  return std::sqrt(point_segment_distance2(p, Vec3(0, 0, -L), Vec3(0, 0, L), nullptr, nullptr)) - r;
}

/// Unsigned distance to a triangle soup, min over point_triangle_distance2.
Real ref_mesh_distance(const Vec3& p, const std::vector<Vec3>& v, const std::vector<Tri>& t) {
  Real best = INFINITY;
  for (const Tri& k : t) best = std::min(best, point_triangle_distance2(p, v[k[0]], v[k[1]], v[k[2]], nullptr, nullptr));
  return std::sqrt(best);
}

// --- meshes ---------------------------------------------------------------------------------------

/// Closed box mesh [-h, h], 8 vertices, 12 triangles with outward normals.
void box_mesh(const Vec3& h, std::vector<Vec3>* v, std::vector<Tri>* t) {
  v->clear();
  t->clear();
  for (int i = 0; i < 8; ++i) v->emplace_back((i & 1 ? 1 : -1) * h.x(), (i & 2 ? 1 : -1) * h.y(), (i & 4 ? 1 : -1) * h.z());
  for (int axis = 0; axis < 3; ++axis)
    for (int side = 0; side < 2; ++side) {
      const int u = (axis + 1) % 3, w = (axis + 2) % 3;
      int q[4];
      const int cyc[4][2] = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
      for (int c = 0; c < 4; ++c) q[c] = (side << axis) | (cyc[c][0] << u) | (cyc[c][1] << w);
      Vec3 out = Vec3::Zero();
      out[axis] = side ? 1 : -1;
      for (const Tri tri : {Tri(q[0], q[1], q[2]), Tri(q[0], q[2], q[3])}) {
        const Vec3 n = ((*v)[tri[1]] - (*v)[tri[0]]).cross((*v)[tri[2]] - (*v)[tri[0]]);
        t->push_back(n.dot(out) > 0 ? tri : Tri(tri[0], tri[2], tri[1]));
      }
    }
}

/// Sphere of radius r: octahedron subdivided `levels` times, vertices pushed to the sphere.
void sphere_mesh(Real r, int levels, std::vector<Vec3>* v, std::vector<Tri>* t) {
  *v = {Vec3(1, 0, 0), Vec3(-1, 0, 0), Vec3(0, 1, 0), Vec3(0, -1, 0), Vec3(0, 0, 1), Vec3(0, 0, -1)};
  *t = {Tri(0, 2, 4), Tri(2, 1, 4), Tri(1, 3, 4), Tri(3, 0, 4), Tri(2, 0, 5), Tri(1, 2, 5), Tri(3, 1, 5), Tri(0, 3, 5)};
  for (int l = 0; l < levels; ++l) {
    std::map<std::pair<int, int>, int> mid;
    auto midpoint = [&](int a, int b) {
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v->push_back(((*v)[a] + (*v)[b]).normalized());
      return mid[key] = static_cast<int>(v->size()) - 1;
    };
    std::vector<Tri> next;
    for (const Tri& k : *t) {
      const int a = midpoint(k[0], k[1]), b = midpoint(k[1], k[2]), c = midpoint(k[2], k[0]);
      next.insert(next.end(), {Tri(k[0], a, c), Tri(a, k[1], b), Tri(c, b, k[2]), Tri(a, b, c)});
    }
    *t = next;
  }
  for (Vec3& p : *v) p *= r;
}

/// Open, non-flat height-field patch over [-s, s]^2 (n x n quads).
void terrain_mesh(Real s, int n, std::vector<Vec3>* v, std::vector<Tri>* t) {
  v->clear();
  t->clear();
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const Real x = -s + 2 * s * i / n, y = -s + 2 * s * j / n;
      v->emplace_back(x, y, 0.1 * s * std::sin(3 * x / s) * std::cos(2 * y / s));
    }
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
      t->push_back(Tri(a, b, d));
      t->push_back(Tri(a, d, c));
    }
}

Eigen::Isometry3d random_pose(std::mt19937& rng) {
  Eigen::Isometry3d P = Eigen::Isometry3d::Identity();
  P.linear() = test::random_rotation(rng);
  P.translation() = 0.3 * test::random_vec3(rng);
  return P;
}

/// A local point at distance d outside the box, in a chosen region (0 face, 1 edge, 2 corner),
/// away from region boundaries; random octant and axis permutation.
Vec3 box_point(std::mt19937& rng, const Vec3& h, int region, Real d) {
  const int a = std::uniform_int_distribution<int>(0, 2)(rng);
  const int b = (a + 1) % 3, c = (a + 2) % 3;
  Vec3 base, n = Vec3::Zero();
  base[a] = h[a];
  if (region == 0) {
    base[b] = uniform(rng, -0.8, 0.8) * h[b];
    base[c] = uniform(rng, -0.8, 0.8) * h[c];
    n[a] = 1;
  } else if (region == 1) {
    base[b] = h[b];
    base[c] = uniform(rng, -0.8, 0.8) * h[c];
    const Real th = uniform(rng, 0.2, 1.37);
    n[a] = std::cos(th);
    n[b] = std::sin(th);
  } else {
    base = h;
    n = Vec3(uniform(rng, 0.3, 1), uniform(rng, 0.3, 1), uniform(rng, 0.3, 1)).normalized();
  }
  Vec3 p = base + d * n;
  for (int i = 0; i < 3; ++i)
    if (rng() & 1) p[i] = -p[i];
  return p;
}

/// A local point at distance d from the capsule surface (cylinder part or a cap).
Vec3 capsule_point(std::mt19937& rng, Real r, Real L, bool cap, Real d) {
  if (!cap) {
    const Real phi = uniform(rng, 0, 2 * M_PI);
    const Vec3 n(std::cos(phi), std::sin(phi), 0);
    return Vec3(0, 0, uniform(rng, -0.8, 0.8) * L) + (r + d) * n;
  }
  Vec3 n = test::random_vec3(rng);
  n.z() = uniform(rng, 0.2, 1);
  n.normalize();
  Vec3 p = Vec3(0, 0, L) + (r + d) * n;
  if (rng() & 1) p.z() = -p.z();
  return p;
}

/// FD check of a local distance function's gradient and Hessian at p.
template <class F>
void expect_distance_derivatives(const F& dist, const Vec3& p, Real step, const char* what) {
  Vec3 g;
  Mat3 H;
  dist(p, &g, &H);
  auto f = [&](const Vec3& y) { return dist(y, nullptr, nullptr); };
  auto gf = [&](const Vec3& y) {
    Vec3 gg;
    dist(y, &gg, nullptr);
    return gg;
  };
  EXPECT_TRUE(test::near_rel(g, test::fd_gradient<3>(f, p, step), 1e-6, 1e-9)) << what << " p = " << p.transpose();
  EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<3, 3>(gf, p, step), 1e-5, 1e-6)) << what << " p = " << p.transpose();
  EXPECT_NEAR(g.norm(), 1.0, 1e-12) << what;
  EXPECT_TRUE(test::is_psd(H, 1e-12) || H.norm() == 0) << what;  // convex features outside
}

// =================================================================================================
// Distances
// =================================================================================================

TEST(ColliderDistance, BoxMatchesReferenceInsideOutsideEdgesCorners) {
  std::mt19937 rng(1);
  const Vec3 h(0.1, 0.05, 0.02);
  for (int it = 0; it < 2000; ++it) {
    const Vec3 p = test::random_vec3(rng).cwiseProduct(2.5 * h);
    Vec3 g;
    const Real d = box_distance(p, h, &g, nullptr);
    EXPECT_NEAR(d, ref_box_distance(p, h), 1e-15);
    // The closest point p - d g lies on the surface.
    EXPECT_NEAR(ref_box_distance(p - d * g, h), 0.0, 1e-15);
  }
  // Specific regions.
  for (int region = 0; region < 3; ++region)
    for (int it = 0; it < 20; ++it) {
      const Real d = uniform(rng, 1e-4, 0.05);
      const Vec3 p = box_point(rng, h, region, d);
      EXPECT_NEAR(box_distance(p, h, nullptr, nullptr), d, 1e-15) << region;
    }
  // Inside: the nearest face, gradient its normal.
  Vec3 g;
  EXPECT_NEAR(box_distance(Vec3(0.09, 0.0, 0.0), h, &g, nullptr), -0.01, 1e-15);  // z face is 0.02 away
  EXPECT_TRUE(test::near_rel(g, Vec3(Vec3::UnitX()), 0));
  EXPECT_NEAR(box_distance(Vec3(0.05, 0.0, 0.015), h, &g, nullptr), -0.005, 1e-15);
  EXPECT_TRUE(test::near_rel(g, Vec3(Vec3::UnitZ()), 0));
  EXPECT_NEAR(box_distance(Vec3(0, -0.045, 0.001), h, &g, nullptr), -0.005, 1e-15);
  EXPECT_TRUE(test::near_rel(g, Vec3(-Vec3::UnitY()), 0));
  EXPECT_NEAR(box_distance(Vec3::Zero(), h, nullptr, nullptr), -0.02, 1e-15);
  // Corner, exactly.
  EXPECT_NEAR(box_distance(h + Vec3(0.03, 0.04, 0), h, &g, nullptr), 0.05, 1e-15);
  EXPECT_TRUE(test::near_rel(g, Vec3(0.6, 0.8, 0), 1e-14));
}

TEST(ColliderDistance, BoxDerivativesMatchFiniteDifferences) {
  std::mt19937 rng(2);
  const Vec3 h(0.1, 0.05, 0.02);
  auto dist = [&](const Vec3& p, Vec3* g, Mat3* H) { return box_distance(p, h, g, H); };
  for (int region = 0; region < 3; ++region)
    for (int it = 0; it < 20; ++it) {
      const Real d = uniform(rng, 1e-3, 0.05);
      expect_distance_derivatives(dist, box_point(rng, h, region, d), 1e-6 * d, "box outside");
    }
  // Inside, away from the medial surfaces: the SDF is linear there.
  for (int it = 0; it < 20; ++it) {
    const Vec3 p(uniform(rng, -0.05, 0.05), uniform(rng, -0.02, 0.02), 0.015 * (rng() & 1 ? 1 : -1));
    Vec3 g;
    Mat3 H;
    EXPECT_NEAR(dist(p, &g, &H), -0.005, 1e-15);
    auto f = [&](const Vec3& y) { return dist(y, nullptr, nullptr); };
    EXPECT_TRUE(test::near_rel(g, test::fd_gradient<3>(f, p, 1e-7), 1e-7));
    EXPECT_EQ(H.norm(), 0.0);
  }
  // Outside Hessians: face 0, edge rank 1, corner rank 2.
  Mat3 H;
  box_distance(Vec3(0.15, 0, 0), h, nullptr, &H);
  EXPECT_EQ(H.norm(), 0.0);
  box_distance(Vec3(0.13, 0.09, 0), h, nullptr, &H);
  EXPECT_NEAR(H.trace(), 1.0 / 0.05, 1e-12);
  EXPECT_NEAR(H(2, 2), 0.0, 1e-15);  // no curvature along the edge
  box_distance(h + Vec3(0.03, 0.04, 0.12), h, nullptr, &H);
  EXPECT_NEAR(H.trace(), 2.0 / 0.13, 1e-12);
}

TEST(ColliderDistance, CapsuleMatchesReferenceAndDerivatives) {
  std::mt19937 rng(3);
  const Real r = 0.02, L = 0.05;
  for (int it = 0; it < 2000; ++it) {
    const Vec3 p = test::random_vec3(rng).cwiseProduct(Vec3(0.05, 0.05, 0.1));
    Vec3 g;
    const Real d = capsule_distance(p, r, L, &g, nullptr);
    EXPECT_NEAR(d, ref_capsule_distance(p, r, L), 1e-15);
    EXPECT_NEAR(ref_capsule_distance(p - d * g, r, L), 0.0, 1e-15);
  }
  auto dist = [&](const Vec3& p, Vec3* g, Mat3* H) { return capsule_distance(p, r, L, g, H); };
  for (bool cap : {false, true})
    for (int it = 0; it < 20; ++it) {
      const Real d = uniform(rng, 1e-3, 0.05);
      const Vec3 p = capsule_point(rng, r, L, cap, d);
      EXPECT_NEAR(dist(p, nullptr, nullptr), d, 1e-15);
      expect_distance_derivatives(dist, p, 1e-6 * d, cap ? "capsule cap" : "capsule cylinder");
    }
  // Inside, both parts; the derivatives are those of D - r (C^2 off the axis).
  Vec3 g;
  EXPECT_NEAR(dist(Vec3(0.015, 0, 0.01), &g, nullptr), -0.005, 1e-15);
  EXPECT_TRUE(test::near_rel(g, Vec3(Vec3::UnitX()), 1e-15));
  EXPECT_NEAR(dist(Vec3(0, 0, 0.06), &g, nullptr), -0.01, 1e-15);
  EXPECT_TRUE(test::near_rel(g, Vec3(Vec3::UnitZ()), 1e-15));
  EXPECT_NEAR(dist(Vec3(0, 0, 0.0), &g, nullptr), -r, 1e-15);  // on the axis: some unit normal
  EXPECT_NEAR(g.norm(), 1.0, 1e-15);
  // A sphere (half_length 0).
  EXPECT_NEAR(capsule_distance(Vec3(0.03, 0.04, 0), 0.02, 0, nullptr, nullptr), 0.03, 1e-15);
}

TEST(ColliderDistance, PlaneBothSides) {
  const Collider c = Collider::plane(Vec3(0, 0, 0.1), Vec3(0, 1, 1));  // normalised internally
  const ColliderShape& s = c.shape();
  EXPECT_NEAR(s.plane_normal.norm(), 1.0, 1e-15);
  Vec3 g;
  Mat3 H;
  const Real k = std::sqrt(0.5);
  EXPECT_NEAR(collider_local_distance(Vec3(0.3, 0.2, 0.1), s, nullptr, &g, &H), 0.2 * k, 1e-15);
  EXPECT_NEAR(collider_local_distance(Vec3(0.3, -0.2, 0.1), s, nullptr, &g, &H), -0.2 * k, 1e-15);
  EXPECT_TRUE(test::near_rel(g, Vec3(0, k, k), 1e-15));
  EXPECT_EQ(H.norm(), 0.0);
  const ColliderQuery q = c.query(Vec3(0.3, -0.2, 0.1), 0.0);
  EXPECT_NEAR(q.distance, -0.2 * k, 1e-15);
  EXPECT_NEAR(plane_distance(q.closest, s.plane_normal, s.plane_offset, nullptr, nullptr), 0.0, 1e-15);
}

TEST(ColliderDistance, ClosedBoxMeshMatchesBox) {
  std::mt19937 rng(4);
  const Vec3 h(0.1, 0.05, 0.02);
  std::vector<Vec3> v;
  std::vector<Tri> t;
  box_mesh(h, &v, &t);
  const Collider c = Collider::mesh(v, t);
  EXPECT_TRUE(c.mesh_closed());
  const ColliderMeshView view{c.mesh_vertices().data(), c.mesh_triangles().data()};
  for (int it = 0; it < 1000; ++it) {
    const Vec3 p = test::random_vec3(rng).cwiseProduct(2.5 * h);
    const Real db = box_distance(p, h, nullptr, nullptr);
    Vec3 gm, gb, gc;
    const Real dm = mesh_distance(p, view, 0, 12, &gm, nullptr);  // GD_HD brute force, unsigned
    const Real dc = c.local_distance(p, true, &gc, nullptr);      // BVH, signed (closed)
    box_distance(p, h, &gb, nullptr);
    EXPECT_NEAR(dm, std::fabs(db), 1e-15);
    EXPECT_NEAR(dm, ref_mesh_distance(p, v, t), 1e-15);
    if (db > 0) {
      EXPECT_NEAR(dc, db, 1e-15);
      EXPECT_TRUE(test::near_rel(gm, gb, 1e-12 + 1e-16 / db)) << p.transpose();
      EXPECT_TRUE(test::near_rel(gc, gb, 1e-12 + 1e-16 / db)) << p.transpose();
    } else {
      EXPECT_NEAR(dc, db, 1e-15);  // the box SDF inside is minus the distance to the surface
      if (-db > 1e-9) {
        EXPECT_TRUE(test::near_rel(gc, gb, 1e-9)) << p.transpose();  // outward
      }
    }
  }
  // Derivatives of the mesh distance (outside: face, edge, corner of the box) match the box's.
  auto dist = [&](const Vec3& p, Vec3* g, Mat3* H) { return mesh_distance(p, view, 0, 12, g, H); };
  for (int region = 0; region < 3; ++region)
    for (int it = 0; it < 20; ++it) {
      const Real d = uniform(rng, 1e-3, 0.05);
      Vec3 p = box_point(rng, h, region, d);
      Mat3 Hm, Hb;
      mesh_distance(p, view, 0, 12, nullptr, &Hm);
      box_distance(p, h, nullptr, &Hb);
      EXPECT_TRUE(test::near_rel(Hm, Hb, 1e-9, 1e-9)) << region;
      expect_distance_derivatives(dist, p, 1e-6 * d, "box mesh");
    }
}

TEST(ColliderDistance, MeshFarCullIsExactNearTheMeshAndALowerBoundBeyondIt) {
  std::mt19937 rng(14);
  const Vec3 h(0.1, 0.05, 0.02);
  std::vector<Vec3> v;
  std::vector<Tri> t;
  box_mesh(h, &v, &t);
  for (Vec3& p : v) p += Vec3(0.3, -0.2, 0.1);  // off the local origin: the cull box is the mesh's
  const Collider c = Collider::mesh(v, t);
  EXPECT_TRUE(c.shape().mesh_convex);
  EXPECT_TRUE(c.shape().mesh_center.isApprox(Vec3(0.3, -0.2, 0.1)));
  EXPECT_TRUE(c.shape().mesh_half.isApprox(h));
  ColliderShape culled = c.shape(), full = c.shape();
  culled.mesh_cull = 0.02;  // as the solver sets it: twice a 1 cm contact distance
  const ColliderMeshView view{c.mesh_vertices().data(), c.mesh_triangles().data()};
  int near = 0, far = 0;
  for (int it = 0; it < 2000; ++it) {
    const Vec3 p = Vec3(0.3, -0.2, 0.1) + test::random_vec3(rng).cwiseProduct(h + Vec3::Constant(0.1));
    Vec3 gc, gf;
    Mat3 Hc, Hf;
    const Real dc = collider_local_distance(p, culled, &view, &gc, &Hc);
    const Real df = collider_local_distance(p, full, &view, &gf, &Hf);
    ASSERT_EQ(df, mesh_distance(p, view, 0, 12, nullptr, nullptr));  // infinity never culls
    if (df <= 0.02) {  // within the cull distance: the mesh's own distance and derivatives
      ++near;
      EXPECT_EQ(dc, df);
      EXPECT_EQ(gc, gf);
      EXPECT_EQ(Hc, Hf);
    } else {
      EXPECT_LE(dc, df + 1e-15);  // beyond it: a lower bound that stays beyond the cull distance
      EXPECT_GT(dc, 0.02 - 1e-15);
      if (dc < df) ++far;
      EXPECT_NEAR(gc.norm(), 1.0, 1e-12);
    }
    // The energy of a barrier within the cull distance is the same either way (zero beyond it).
    const Real e_c = point_collider_energy(p, Mat3::Identity(), Vec3::Zero(), culled, 0, 0.01, 1.0, nullptr, nullptr,
                                           HessianKind::kProjected, &view);
    const Real e_f = point_collider_energy(p, Mat3::Identity(), Vec3::Zero(), full, 0, 0.01, 1.0, nullptr, nullptr,
                                           HessianKind::kProjected, &view);
    EXPECT_EQ(e_c, e_f);
  }
  EXPECT_GT(near, 100);
  EXPECT_GT(far, 100);  // the lower bound was used
  // A non-convex mesh (two boxes' surfaces, an L) is flagged so: CCD keeps the Lipschitz bound.
  std::vector<Vec3> v2;
  std::vector<Tri> t2;
  box_mesh(h, &v2, &t2);
  std::vector<Vec3> v3 = v2;
  for (Vec3& p : v3) p += Vec3(0.15, 0.08, 0);
  const std::vector<Tri> first = t2;
  for (const Tri& tri : first) t2.push_back(tri + Tri::Constant(8));
  v2.insert(v2.end(), v3.begin(), v3.end());
  EXPECT_FALSE(Collider::mesh(v2, t2).shape().mesh_convex);
}

TEST(ColliderDistance, MeshBvhMatchesBruteForce) {
  std::mt19937 rng(5);
  std::vector<Vec3> v;
  std::vector<Tri> t;
  sphere_mesh(0.1, 4, &v, &t);  // 2048 triangles
  const Collider sphere = Collider::mesh(v, t);
  EXPECT_TRUE(sphere.mesh_closed());
  const ColliderMeshView view{sphere.mesh_vertices().data(), sphere.mesh_triangles().data()};
  const int n = static_cast<int>(t.size());
  for (int it = 0; it < 150; ++it) {
    const Vec3 p = 0.2 * test::random_vec3(rng);
    Vec3 g1, g2;
    const Real brute = mesh_distance(p, view, 0, n, &g1, nullptr);
    const Real bvh = sphere.local_distance(p, false, &g2, nullptr);
    EXPECT_NEAR(brute, bvh, 1e-15);  // may pick another of several (near-)tied triangles
    EXPECT_NEAR(brute, ref_mesh_distance(p, v, t), 1e-15);
    // Signed: negative inside the polyhedron; close to the sphere's |p| - r (chord error < 1e-3).
    const Real s = sphere.local_distance(p, true, nullptr, nullptr);
    EXPECT_NEAR(s, p.norm() - 0.1, 1e-3) << p.transpose();
    if (p.norm() < 0.098) EXPECT_LT(s, 0);
    if (p.norm() > 0.1) EXPECT_GT(s, 0);
  }
  // Open mesh: unsigned both sides, and never flagged closed.
  terrain_mesh(0.2, 10, &v, &t);
  const Collider terrain = Collider::mesh(v, t);
  EXPECT_FALSE(terrain.mesh_closed());
  for (int it = 0; it < 100; ++it) {
    const Vec3 p = Vec3(0.15, 0.15, 0.05).cwiseProduct(test::random_vec3(rng));
    const Real d = terrain.local_distance(p, true, nullptr, nullptr);
    EXPECT_NEAR(d, ref_mesh_distance(p, v, t), 1e-15);
    EXPECT_GE(d, 0);
  }
}

// =================================================================================================
// Barrier energy
// =================================================================================================

struct EnergyCase {
  const char* name;
  Collider collider;
  std::function<Vec3(std::mt19937&, Real)> point;  // local point at distance d
};

std::vector<EnergyCase> energy_cases() {
  const Vec3 h(0.1, 0.05, 0.02);
  std::vector<Vec3> v;
  std::vector<Tri> t;
  box_mesh(h, &v, &t);
  std::vector<EnergyCase> out;
  for (int region = 0; region < 3; ++region)
    out.push_back({"box", Collider::box(h), [h, region](std::mt19937& rng, Real d) { return box_point(rng, h, region, d); }});
  for (bool cap : {false, true})
    out.push_back({"capsule", Collider::capsule(0.02, 0.05),
                   [cap](std::mt19937& rng, Real d) { return capsule_point(rng, 0.02, 0.05, cap, d); }});
  out.push_back({"plane", Collider::plane(Vec3(0, 0, 0.05), Vec3(0.3, -0.2, 1)), [](std::mt19937& rng, Real d) {
                   const Vec3 n = Vec3(0.3, -0.2, 1).normalized();
                   const Vec3 r = test::random_vec3(rng);
                   return Vec3(Vec3(0, 0, 0.05) + (r - n.dot(r) * n) + d * n);
                 }});
  for (int region = 1; region < 3; ++region)  // box mesh edges and corners (faces as for the box)
    out.push_back({"box mesh", Collider::mesh(v, t),
                   [h, region](std::mt19937& rng, Real d) { return box_point(rng, h, region, d); }});
  return out;
}

TEST(ColliderEnergy, WorldDerivativesMatchFiniteDifferencesUnderRandomPose) {
  std::mt19937 rng(6);
  const Real dhat = 1e-3, kappa = 1e4;
  int count = 0;
  for (const EnergyCase& c : energy_cases()) {
    const ColliderMeshView view{c.collider.mesh_vertices().data(), c.collider.mesh_triangles().data()};
    const ColliderMeshView* mesh = c.collider.type() == ColliderType::kMesh ? &view : nullptr;
    const ColliderShape& s = c.collider.shape();
    for (int it = 0; it < 15; ++it) {
      const Eigen::Isometry3d P = random_pose(rng);
      const Mat3 R = P.linear();
      const Vec3 tr = P.translation();
      const Real offset = (it % 3 == 0) ? 2e-4 : 0.0;
      const Real d = offset + dhat * uniform(rng, 0.02, 0.95);
      const Vec3 x = P * c.point(rng, d - offset + offset);
      Vec3 g, gp;
      Mat3 H, Hp;
      const Real E = point_collider_energy(x, R, tr, s, offset, dhat, kappa, &g, &H, HessianKind::kExact, mesh);
      const Real Ep = point_collider_energy(x, R, tr, s, offset, dhat, kappa, &gp, &Hp, HessianKind::kProjected, mesh);
      ASSERT_GT(E, 0) << c.name;
      EXPECT_EQ(E, Ep);
      EXPECT_TRUE(test::near_rel(g, gp, 0));
      auto f = [&](const Vec3& y) {
        return point_collider_energy(y, R, tr, s, offset, dhat, kappa, nullptr, nullptr, HessianKind::kNone, mesh);
      };
      auto gf = [&](const Vec3& y) {
        Vec3 gg;
        point_collider_energy(y, R, tr, s, offset, dhat, kappa, &gg, nullptr, HessianKind::kNone, mesh);
        return gg;
      };
      const Real step = 1e-5 * (d - offset);
      EXPECT_TRUE(test::near_rel(g, test::fd_gradient<3>(f, x, step), 1e-5)) << c.name;
      EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<3, 3>(gf, x, step), 1e-5)) << c.name;
      EXPECT_TRUE(test::is_psd(Hp)) << c.name;
      EXPECT_TRUE(test::near_rel(Hp, H, 1e-9) || test::min_eigenvalue(H) < 0) << c.name;  // projection only if needed
      // Pushes the vertex away from the surface (force along the outward normal).
      const ColliderQuery q = c.collider.query(x, P);
      EXPECT_NEAR(q.distance, d, 1e-12) << c.name;
      EXPECT_NEAR((-g).normalized().dot(q.normal), 1.0, 1e-9) << c.name;
      EXPECT_NEAR(-g.dot(q.normal), contact_normal_force(d, offset, dhat, kappa), 1e-9 * g.norm());
      // Host Collider::energy agrees (BVH for meshes).
      Vec3 gh;
      Mat3 Hh;
      EXPECT_NEAR(c.collider.energy(x, P, offset, dhat, kappa, &gh, &Hh), Ep, 1e-12 * Ep);
      EXPECT_TRUE(test::near_rel(gh, gp, 1e-12));
      EXPECT_TRUE(test::near_rel(Hh, Hp, 1e-9));
      ++count;
    }
  }
  EXPECT_GE(count, 100);
}

TEST(ColliderEnergy, EdgesAndCornersNeedProjection) {
  // Near a box edge the exact Hessian b'' n nᵀ + b' (I - e eᵀ - n nᵀ)/d is indefinite.
  const Collider box = Collider::box(Vec3(0.1, 0.1, 0.1));
  const Real dhat = 1e-3, kappa = 1e4;
  const Vec3 x = Vec3(0.1, 0.1, 0) + 0.5 * dhat * Vec3(1, 1, 0).normalized();
  Mat3 H, Hp;
  point_collider_energy(x, Mat3::Identity(), Vec3::Zero(), box.shape(), 0, dhat, kappa, nullptr, &H, HessianKind::kExact);
  point_collider_energy(x, Mat3::Identity(), Vec3::Zero(), box.shape(), 0, dhat, kappa, nullptr, &Hp, HessianKind::kProjected);
  EXPECT_LT(test::min_eigenvalue(H), 0);
  EXPECT_TRUE(test::is_psd(Hp));
  Vec3 g;
  Mat3 Hn = Mat3::Constant(7);
  point_collider_energy(x, Mat3::Identity(), Vec3::Zero(), box.shape(), 0, dhat, kappa, &g, &Hn, HessianKind::kNone);
  EXPECT_EQ(Hn(0, 0), 7);  // kNone leaves the Hessian alone
}

TEST(ColliderEnergy, InfiniteInsideZeroBeyondDhat) {
  std::mt19937 rng(7);
  const Real dhat = 1e-3, kappa = 1e4;
  for (const EnergyCase& c : energy_cases()) {
    const ColliderMeshView view{c.collider.mesh_vertices().data(), c.collider.mesh_triangles().data()};
    const ColliderMeshView* mesh = c.collider.type() == ColliderType::kMesh ? &view : nullptr;
    const Eigen::Isometry3d P = random_pose(rng);
    Vec3 g;
    Mat3 H;
    auto energy = [&](const Vec3& local, Real offset) {
      return point_collider_energy(P * local, P.linear(), P.translation(), c.collider.shape(), offset, dhat, kappa,
                                   &g, &H, HessianKind::kProjected, mesh);
    };
    // Beyond dhat (+ offset): exactly zero with zero derivatives.
    for (Real d : {1.001 * dhat, 1.5 * dhat, 0.1}) {
      EXPECT_EQ(energy(c.point(rng, d), 0), 0.0) << c.name;
      EXPECT_EQ(g.norm() + H.norm(), 0.0);
      EXPECT_EQ(energy(c.point(rng, d + 3e-4), 3e-4), 0.0) << c.name;
    }
    // At or below the offset: +inf with finite (zero) derivatives.
    for (Real d : {0.0, 0.5e-4, 0.99999e-4}) {
      const Real E = energy(c.point(rng, d), 1e-4);
      EXPECT_TRUE(std::isinf(E) && E > 0) << c.name << " d = " << d;
      EXPECT_EQ(g.norm() + H.norm(), 0.0);
    }
    // Exactly on the surface (identity pose, no rounding): +inf.
    const Vec3 on = c.point(rng, 0.0);
    const Real E0 = point_collider_energy(on, Mat3::Identity(), Vec3::Zero(), c.collider.shape(), 0, dhat, kappa, &g,
                                          &H, HessianKind::kProjected, mesh);
    EXPECT_TRUE(std::isinf(E0) || c.collider.query(on, 0.0).distance != 0) << c.name;
    // Inside (signed shapes): +inf. The mesh layer is unsigned: a vertex inside a closed mesh
    // is kept inside (IPC semantics); Collider::query still reports it as inside.
    const Vec3 inside = c.point(rng, -0.005);
    const Real E = energy(inside, 0);
    if (c.collider.type() == ColliderType::kMesh) {
      EXPECT_EQ(E, 0.0);
      EXPECT_LT(c.collider.query(P * inside, P).distance, 0);
    } else {
      EXPECT_TRUE(std::isinf(E) && E > 0) << c.name;
    }
  }
}

TEST(ColliderEnergy, PackedCollidersAgreeWithHost) {
  std::mt19937 rng(8);
  std::vector<Vec3> v;
  std::vector<Tri> t;
  std::vector<Collider> cs;
  cs.push_back(Collider::box(Vec3(0.1, 0.2, 0.3)));
  box_mesh(Vec3(0.05, 0.05, 0.05), &v, &t);
  cs.push_back(Collider::mesh(v, t));
  cs.push_back(Collider::capsule(0.01, 0.1));
  terrain_mesh(0.2, 4, &v, &t);
  cs.push_back(Collider::mesh(v, t));
  const PackedColliders packed = pack_colliders(cs);
  ASSERT_EQ(packed.shapes.size(), 4u);
  EXPECT_EQ(packed.shapes[1].mesh_first_tri, 0);
  EXPECT_EQ(packed.shapes[3].mesh_first_tri, 12);
  EXPECT_EQ(packed.triangles.size(), 12u + 32u);
  const ColliderMeshView view = packed.view();
  const Real dhat = 0.05, kappa = 1e3;  // large dhat: most samples are active
  int active = 0;
  for (int it = 0; it < 200; ++it) {
    const Eigen::Isometry3d P = random_pose(rng);
    const Vec3 x = P * (0.25 * test::random_vec3(rng));
    for (size_t i = 0; i < cs.size(); ++i) {
      Vec3 g1, g2;
      const Real E1 = cs[i].energy(x, P, 0, dhat, kappa, &g1, nullptr);
      const Real E2 = point_collider_energy(x, P.linear(), P.translation(), packed.shapes[i], 0, dhat, kappa, &g2,
                                            nullptr, HessianKind::kNone, &view);
      if (std::isinf(E1)) {
        EXPECT_TRUE(std::isinf(E2));
        continue;
      }
      EXPECT_NEAR(E1, E2, 1e-12 * (1 + E1)) << i;
      EXPECT_TRUE(test::near_rel(g1, g2, 1e-10, 1e-12)) << i;
      active += E1 > 0;
    }
  }
  EXPECT_GT(active, 50);
}

// =================================================================================================
// Friction
// =================================================================================================

TEST(ColliderFriction, SlidingAgainstMovingSurfaceAndStaticRegime) {
  const Collider box = Collider::box(Vec3(0.1, 0.1, 0.05));
  const Real dhat = 1e-3, kappa = 1e4, mu = 0.4, eps = 1e-5;
  // The collider translates by s over the step; the vertex rests just above its top face.
  const Vec3 s(0.01, -0.004, 0);
  const Vec3 x_t(0.02, 0.03, 0.05 + 0.3 * dhat);
  const ColliderContactFrame f = collider_contact_frame(x_t, Mat3::Identity(), Vec3::Zero(), Mat3::Identity(), s,
                                                        box.shape(), 0, dhat, kappa);
  EXPECT_NEAR(f.distance, 0.3 * dhat, 1e-15);
  EXPECT_TRUE(test::near_rel(f.normal, Vec3(Vec3::UnitZ()), 0));
  EXPECT_TRUE(test::near_rel(f.closest, Vec3(0.02, 0.03, 0.05), 1e-15));
  EXPECT_TRUE(test::near_rel(f.surface_displacement, s, 1e-14));
  EXPECT_NEAR(f.lambda, contact_normal_force(0.3 * dhat, 0, dhat, kappa), 1e-12 * f.lambda);
  EXPECT_GT(f.lambda, 0);
  EXPECT_NEAR((f.T.transpose() * f.normal).norm(), 0, 1e-15);
  EXPECT_TRUE(test::near_rel(Mat32(f.T).transpose() * f.T, Mat2(Mat2::Identity()), 1e-15));

  Vec3 g;
  Mat3 H;
  // Vertex held still while the surface slides under it: dragged along with force mu lambda.
  point_collider_friction(x_t, x_t, f.surface_displacement, f.T, mu, f.lambda, eps, &g, &H);
  EXPECT_NEAR(g.norm(), mu * f.lambda, 1e-12 * mu * f.lambda);
  EXPECT_TRUE(test::near_rel(Vec3(-g), Vec3(mu * f.lambda * s.normalized()), 1e-12));
  EXPECT_TRUE(test::is_psd(H));
  // Vertex sliding the other way on a still surface: opposes its motion.
  point_collider_friction(x_t + s, x_t, Vec3::Zero(), f.T, mu, f.lambda, eps, &g, nullptr);
  EXPECT_TRUE(test::near_rel(g, Vec3(mu * f.lambda * s.normalized()), 1e-12));
  // Moving with the surface: no force; nearly with it: a small, viscous-like force.
  point_collider_friction(x_t + s, x_t, s, f.T, mu, f.lambda, eps, &g, &H);
  EXPECT_LT(g.norm(), 1e-6 * mu * f.lambda);  // zero up to the rounding of (x_t + s) - s
  EXPECT_TRUE(test::is_psd(H));
  EXPECT_NEAR(H.trace(), 2 * mu * f.lambda * 2 / eps, 1e-9 * H.norm());  // isotropic 2/eps limit in the plane
  point_collider_friction(x_t + s + Vec3(1e-3 * eps, 0, 0), x_t, s, f.T, mu, f.lambda, eps, &g, nullptr);
  EXPECT_GT(g.norm(), 0);
  EXPECT_LT(g.norm(), 0.01 * mu * f.lambda);
  // Normal motion does not count as slip.
  point_collider_friction(x_t + s + Vec3(0, 0, 1e-4), x_t, s, f.T, mu, f.lambda, eps, &g, nullptr);
  EXPECT_LT(g.norm(), 1e-12 * mu * f.lambda);
}

TEST(ColliderFriction, RotatingColliderAndFiniteDifferences) {
  std::mt19937 rng(9);
  const Collider cap = Collider::capsule(0.02, 0.05);
  const Real dhat = 1e-3, kappa = 1e4, mu = 0.3, eps = 1e-5;
  for (int it = 0; it < 20; ++it) {
    const Eigen::Isometry3d P0 = random_pose(rng);
    Eigen::Isometry3d P1 = P0;
    P1.linear() = Eigen::AngleAxisd(0.05, test::random_vec3(rng).normalized()).toRotationMatrix() * P0.linear();
    P1.translation() += 0.01 * test::random_vec3(rng);
    const Vec3 x_t = P0 * capsule_point(rng, 0.02, 0.05, it % 2, 0.5 * dhat);
    const ColliderContactFrame f = collider_contact_frame(x_t, P0.linear(), P0.translation(), P1.linear(),
                                                          P1.translation(), cap.shape(), 0, dhat, kappa);
    // The surface point moves rigidly with the collider.
    EXPECT_TRUE(test::near_rel(Vec3(f.closest + f.surface_displacement), Vec3(P1 * (P0.inverse() * f.closest)), 1e-13));
    // Host: the same displacement through the pose function.
    Collider moving = Collider::capsule(0.02, 0.05);
    moving.set_pose([P0, P1](double t) { return t < 0.5 ? P0 : P1; });
    EXPECT_TRUE(test::near_rel(moving.surface_displacement(x_t, 0.0, 1.0), f.surface_displacement, 1e-12));
    // FD check of the friction potential with a moving surface and a nonzero slip.
    const Vec3 x = x_t + f.surface_displacement + 3 * eps * test::random_vec3(rng);
    Vec3 g;
    Mat3 H;
    point_collider_friction(x, x_t, f.surface_displacement, f.T, mu, f.lambda, eps, &g, &H);
    auto fe = [&](const Vec3& y) {
      return point_collider_friction(y, x_t, f.surface_displacement, f.T, mu, f.lambda, eps, nullptr, nullptr);
    };
    auto gf = [&](const Vec3& y) {
      Vec3 gg;
      point_collider_friction(y, x_t, f.surface_displacement, f.T, mu, f.lambda, eps, &gg, nullptr);
      return gg;
    };
    EXPECT_TRUE(test::near_rel(g, test::fd_gradient<3>(fe, x, 1e-3 * eps), 1e-6, 1e-9 * mu * f.lambda));
    EXPECT_TRUE(test::near_rel(H, test::fd_jacobian<3, 3>(gf, x, 1e-3 * eps), 1e-5, 1e-6 * mu * f.lambda / eps));
    EXPECT_TRUE(test::is_psd(H));
    EXPECT_LE(g.norm(), mu * f.lambda * (1 + 1e-12));
  }
}

TEST(ColliderFriction, PenetratingOrFarStartGivesNoFriction) {
  const Collider box = Collider::box(Vec3(0.1, 0.1, 0.1));
  const Real dhat = 1e-3, kappa = 1e4;
  const Mat3 I = Mat3::Identity();
  for (Real z : {0.05, 0.1, 0.1 + 2 * dhat}) {
    const ColliderContactFrame f =
        collider_contact_frame(Vec3(0, 0, z), I, Vec3::Zero(), I, Vec3::Zero(), box.shape(), 0, dhat, kappa);
    EXPECT_EQ(f.lambda, 0.0) << z;
    EXPECT_TRUE(f.T.allFinite());
  }
}

// =================================================================================================
// Input errors
// =================================================================================================

TEST(ColliderInput, BadShapesThrowInputError) {
  EXPECT_THROW(Collider::box(Vec3(0.1, 0, 0.1)), InputError);
  EXPECT_THROW(Collider::box(Vec3(0.1, -1, 0.1)), InputError);
  EXPECT_THROW(Collider::box(Vec3(0.1, kNaN, 0.1)), InputError);
  EXPECT_THROW(Collider::box(Vec3(0.1, INFINITY, 0.1)), InputError);
  EXPECT_THROW(Collider::capsule(0, 0.1), InputError);
  EXPECT_THROW(Collider::capsule(-0.01, 0.1), InputError);
  EXPECT_THROW(Collider::capsule(kNaN, 0.1), InputError);
  EXPECT_THROW(Collider::capsule(0.01, -0.1), InputError);
  EXPECT_THROW(Collider::capsule(0.01, kNaN), InputError);
  EXPECT_NO_THROW(Collider::capsule(0.01, 0));  // a sphere
  EXPECT_THROW(Collider::plane(Vec3::Zero(), Vec3::Zero()), InputError);
  EXPECT_THROW(Collider::plane(Vec3::Zero(), Vec3(0, 0, 1e-300)), InputError);
  EXPECT_THROW(Collider::plane(Vec3::Zero(), Vec3(0, kNaN, 1)), InputError);
  EXPECT_THROW(Collider::plane(Vec3(kNaN, 0, 0), Vec3(0, 0, 1)), InputError);
  const std::vector<Vec3> v = {Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, 1, 0)};
  EXPECT_THROW(Collider::mesh({}, {}), InputError);
  EXPECT_THROW(Collider::mesh(v, {}), InputError);
  EXPECT_THROW(Collider::mesh({}, {Tri(0, 1, 2)}), InputError);
  EXPECT_THROW(Collider::mesh(v, {Tri(0, 1, 3)}), InputError);
  EXPECT_THROW(Collider::mesh(v, {Tri(0, -1, 2)}), InputError);
  EXPECT_THROW(Collider::mesh(v, {Tri(0, 1, 1)}), InputError);
  EXPECT_THROW(Collider::mesh({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(2, 0, 0)}, {Tri(0, 1, 2)}), InputError);
  EXPECT_THROW(Collider::mesh({Vec3(0, 0, 0), Vec3(1, 0, 0), Vec3(0, kNaN, 0)}, {Tri(0, 1, 2)}), InputError);
  EXPECT_NO_THROW(Collider::mesh(v, {Tri(0, 1, 2)}));
  try {
    Collider::mesh(v, {Tri(0, 1, 2), Tri(0, 1, 7)});
    ADD_FAILURE() << "no throw";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("triangle 1"), std::string::npos) << e.what();
  }
  Collider c = Collider::box(Vec3(0.1, 0.1, 0.1));
  EXPECT_THROW(c.set_pose(nullptr), InputError);
  EXPECT_THROW(c.set_friction(-0.1), InputError);
  EXPECT_THROW(c.set_friction(kNaN), InputError);
  c.set_friction(0.5);
  EXPECT_EQ(c.friction(), 0.5);
  EXPECT_THROW(c.project_out(Vec3::Zero(), 0.0, -1e-3), InputError);
  EXPECT_THROW(c.project_out(Vec3::Zero(), 0.0, kNaN), InputError);
}

TEST(ColliderInput, NonFiniteOrNonRigidPoseThrowsNamingTheTime) {
  Collider c = Collider::capsule(0.02, 0.05);
  EXPECT_TRUE(c.pose(3.0).isApprox(Eigen::Isometry3d::Identity()));  // default identity
  c.set_pose([](double t) {
    Eigen::Isometry3d P = Eigen::Isometry3d::Identity();
    P.translation() = Vec3(t, 0, 0);
    if (t > 0.4 && t < 0.6) P.translation().y() = kNaN;
    if (t > 0.9) P.linear() *= 1.5;  // not a rigid motion
    return P;
  });
  EXPECT_NO_THROW(c.checked_pose(0.25));
  EXPECT_NO_THROW(c.query(Vec3(1, 1, 1), 0.25));
  EXPECT_FALSE(c.pose(0.5).matrix().allFinite());  // pose() is unchecked
  try {
    c.checked_pose(0.5);
    ADD_FAILURE() << "no throw";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("t=0.5"), std::string::npos) << e.what();
  }
  EXPECT_THROW(c.query(Vec3(1, 1, 1), 0.5), InputError);
  EXPECT_THROW(c.project_out(Vec3(1, 1, 1), 0.5, 1e-3), InputError);
  EXPECT_THROW(c.surface_displacement(Vec3(1, 1, 1), 0.25, 0.5), InputError);
  try {
    c.checked_pose(1.0);
    ADD_FAILURE() << "no throw";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("t=1 "), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("rotation"), std::string::npos) << e.what();
  }
  Collider mirrored = Collider::box(Vec3(0.1, 0.1, 0.1));
  mirrored.set_pose([](double) {
    Eigen::Isometry3d P = Eigen::Isometry3d::Identity();
    P.linear()(2, 2) = -1;
    return P;
  });
  EXPECT_THROW(mirrored.checked_pose(0), InputError);
}

// =================================================================================================
// project_out
// =================================================================================================

TEST(ColliderProjectOut, PutsPointsExactlyAtTheGap) {
  std::mt19937 rng(10);
  std::vector<Vec3> v;
  std::vector<Tri> t;
  struct Case {
    const char* name;
    Collider c;
    Vec3 extent;  // sampling box half size (local)
    bool convex;  // one projection step is exact
    bool terrain = false;  // sample z around the terrain height instead
  };
  std::vector<Case> cs;
  cs.push_back({"box", Collider::box(Vec3(0.1, 0.05, 0.02)), Vec3(0.12, 0.07, 0.04), true});
  cs.push_back({"capsule", Collider::capsule(0.02, 0.05), Vec3(0.03, 0.03, 0.08), true});
  cs.push_back({"sphere", Collider::capsule(0.03, 0), Vec3(0.04, 0.04, 0.04), true});
  cs.push_back({"plane", Collider::plane(Vec3(0, 0, 0.01), Vec3(0.2, 0.1, 1)), Vec3(0.1, 0.1, 0.05), true});
  box_mesh(Vec3(0.1, 0.05, 0.02), &v, &t);
  cs.push_back({"box mesh", Collider::mesh(v, t), Vec3(0.12, 0.07, 0.04), true});
  sphere_mesh(0.05, 2, &v, &t);
  cs.push_back({"sphere mesh", Collider::mesh(v, t), Vec3(0.06, 0.06, 0.06), true});
  terrain_mesh(0.2, 8, &v, &t);
  cs.push_back({"terrain (open)", Collider::mesh(v, t), Vec3(0.15, 0.15, 0.003), false, true});
  const Real gap = 2e-3;
  for (auto& [name, c0, extent, convex, terrain] : cs) {
    Collider c = c0;
    const Eigen::Isometry3d P = random_pose(rng);
    c.set_pose([P](double) { return P; });
    int moved = 0;
    for (int it = 0; it < 200; ++it) {
      Vec3 local = extent.cwiseProduct(test::random_vec3(rng));
      if (terrain) local.z() += 0.02 * std::sin(3 * local.x() / 0.2) * std::cos(2 * local.y() / 0.2);
      if (it == 0) local = Vec3::Zero();  // centre: medial for box/capsule/sphere
      if (it == 1) local = Vec3(0.1, 0.05, 0.02);  // a box corner, exactly on the surface
      const Vec3 x = P * local;
      const ColliderQuery before = c.query(x, 0.0);
      const Vec3 y = c.project_out(x, 0.0, gap);
      const ColliderQuery after = c.query(y, 0.0);
      if (before.distance >= gap) {
        EXPECT_EQ((y - x).norm(), 0.0) << name;
        continue;
      }
      ++moved;
      EXPECT_NEAR(after.distance, gap, 1e-13) << name << " from d = " << before.distance << " at "
                                              << local.transpose();
      // Moved along the outward normal of its closest point, by gap - d.
      // (Not for a point exactly on a mesh corner, where the normal is rounding noise and the
      // iteration corrects the direction.)
      if (convex && it != 1) EXPECT_NEAR((y - x).norm(), gap - before.distance, 1e-12) << name;
      // The pose is honoured: the same in the local frame with an identity pose.
      EXPECT_NEAR(c0.query(P.inverse() * y, 0.0).distance, gap, 1e-13) << name;
    }
    EXPECT_GT(moved, 20) << name;
  }
}


// The batch form (the solver's predictor) gives each point what the single-point form gives, bit
// for bit, leaves skipped and non-finite points alone and evaluates the pose once.
TEST(ColliderProjectOut, TheBatchFormMatchesPointByPointAndSkipsWhatItIsTold) {
  std::mt19937 rng(11);
  std::vector<Vec3> v;
  std::vector<Tri> t;
  sphere_mesh(0.05, 2, &v, &t);
  Collider c = Collider::mesh(v, t);
  const Eigen::Isometry3d P = random_pose(rng);
  int pose_calls = 0;
  c.set_pose([P, &pose_calls](double) {
    ++pose_calls;
    return P;
  });
  const int n = 3000;  // over the batch's parallel threshold
  std::vector<double> x(3 * n);
  std::vector<int> skip(n, 0);
  for (int i = 0; i < n; ++i) {
    const Vec3 p = P * (Vec3(0.06, 0.06, 0.06).cwiseProduct(test::random_vec3(rng)));
    for (int k = 0; k < 3; ++k) x[3 * i + k] = p[k];
    skip[i] = i % 7 == 0;
  }
  x[3 * 5] = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> y = x;
  pose_calls = 0;
  c.project_out(&y, skip, 0.0, 2e-3);
  EXPECT_EQ(pose_calls, 1);
  int moved = 0;
  for (int i = 0; i < n; ++i) {
    const Vec3 p(x[3 * i], x[3 * i + 1], x[3 * i + 2]), q(y[3 * i], y[3 * i + 1], y[3 * i + 2]);
    if (i == 5) {
      EXPECT_TRUE(std::isnan(y[3 * i])) << "a non-finite point is left as it is";
      continue;
    }
    if (skip[i]) {
      EXPECT_EQ(p, q) << i;
      continue;
    }
    EXPECT_EQ(q, c.project_out(p, 0.0, 2e-3)) << i;
    moved += p != q;
  }
  EXPECT_GT(moved, n / 4);
  EXPECT_THROW(c.project_out(&y, std::vector<int>(n - 1, 0), 0.0, 2e-3), InputError);
  EXPECT_THROW(c.project_out(&y, skip, 0.0, -1.0), InputError);
}


// With the points' start positions, a point goes out to min(gap, its clearance at the start, at
// least the floor): a box moving 0.6 mm into cloth it presses at 0.1 mm carries that cloth at 0.1
// mm (the clearance kept) instead of lifting it off to the 0.5 mm gap; a point that started
// farther out than the gap goes to the gap as before; one that started touching goes to the floor;
// a point the moved box does not reach stays where it is.
TEST(ColliderProjectOut, KeepsEachPointsClearanceFromTheStartWhereItWasLess) {
  Collider c = Collider::box(Vec3(0.02, 0.02, 0.005));
  // The box rises 0.6 mm from t = 0 to t = 1 (its top face from z = 0 to z = 0.6 mm).
  c.set_pose([](double t) { return Eigen::Isometry3d(Eigen::Translation3d(Vec3(0, 0, -0.005 + 0.6e-3 * t))); });
  const Real gap = 0.5e-3, floor = 1e-6;
  // Start heights above the top face: pressed (0.1 mm), outside the gap (0.8 mm), touching (0),
  // far (3 mm), and one beside the box (x = 5 cm), 0.1 mm up.
  const std::vector<Vec3> start = {{0, 0, 0.1e-3}, {0.01, 0, 0.8e-3}, {0, 0.01, 0}, {0.005, 0.005, 3e-3},
                                   {0.05, 0, 0.1e-3}};
  std::vector<double> x0, x;
  for (const Vec3& p : start)
    for (int k = 0; k < 3; ++k) x0.push_back(p[k]);
  x = x0;  // the predictor left the points where they were
  const std::vector<int> skip(start.size(), 0);
  c.project_out(&x, skip, 1.0, gap, x0, 0.0, floor);
  auto z = [&](int i) { return x[3 * i + 2]; };
  EXPECT_NEAR(z(0), 0.6e-3 + 0.1e-3, 1e-12) << "pressed cloth keeps its 0.1 mm";
  EXPECT_NEAR(z(1), 0.6e-3 + gap, 1e-12) << "a point from outside the gap goes to the gap";
  EXPECT_NEAR(z(2), 0.6e-3 + floor, 1e-12) << "a touching point goes to the floor";
  EXPECT_EQ(z(3), 3e-3) << "out of reach";
  EXPECT_EQ(z(4), 0.1e-3) << "beside the box";
  for (size_t i = 0; i < start.size(); ++i) {
    EXPECT_EQ(x[3 * i], x0[3 * i]) << i;  // moved along the top face's normal only
    EXPECT_EQ(x[3 * i + 1], x0[3 * i + 1]) << i;
  }
  // Without the start the same call lifts the pressed point off to the gap.
  std::vector<double> y = x0;
  c.project_out(&y, skip, 1.0, gap);
  EXPECT_NEAR(y[2], 0.6e-3 + gap, 1e-12);
  EXPECT_THROW(c.project_out(&y, skip, 1.0, gap, std::vector<double>(3), 0.0, floor), InputError);
  EXPECT_THROW(c.project_out(&y, skip, 1.0, gap, x0, 0.0, -1.0), InputError);
  // At given poses (a yielding collider stopped part of the way): the box stopped at t = 0.5, its
  // top face at 0.3 mm.
  std::vector<double> w = x0;
  c.project_out(&w, skip, c.checked_pose(0.5), gap, x0, c.checked_pose(0.0), floor);
  EXPECT_NEAR(w[2], 0.3e-3 + 0.1e-3, 1e-12) << "pressed cloth keeps its 0.1 mm from the stopped face";
  EXPECT_NEAR(w[3 * 2 + 2], 0.3e-3 + floor, 1e-12);
}

}  // namespace
}  // namespace gd::sim
