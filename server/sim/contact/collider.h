#pragma once
/// \file
/// Kinematic colliders: rigid shapes with a pose per time (gripper fingers, robot links, a table
/// with edges, a tilted slope) that cloth vertices must stay outside of, with friction.
///
/// Two layers:
///  - GD_HD (this header, no allocation, runs in CUDA kernels): a flat shape description
///    ColliderShape, the distance of a point given in the collider's LOCAL frame to the shape's
///    surface with gradient and Hessian (box, capsule, plane, triangle mesh), the vertex-collider
///    barrier energy in WORLD coordinates (pose R, t) and the lagged friction against the moving
///    collider surface.
///  - host (class Collider, collider.cpp): construction with input validation (InputError), the
///    pose function of time, a BVH for meshes, signed world-space queries, project_out.
///
/// Conventions. Pose: x_world = R p_local + t (R a rotation). Distances in m. "Distance" is the
/// distance to the shape SURFACE along the closest feature:
///   box, capsule, plane: signed, negative inside (the plane's inside is the side opposite to
///     its normal);
///   mesh: unsigned in the GD_HD layer (the barrier keeps the vertex on whichever side it is
///     on, as IPC does for open surfaces); the host Collider additionally signs it for CLOSED,
///     consistently oriented meshes (generalised winding number), see Collider::query.
/// The gradient of the distance is the unit outward normal at the closest point (direction
/// from the closest surface point to p when outside) and the closest point is p - d ∇d for every
/// shape. The Hessian is that of the closest feature's formula (a face: 0, an edge with unit
/// direction e: (I - e eᵀ - n nᵀ)/D, a vertex or a sphere: (I - n nᵀ)/D with D the Euclidean
/// distance to the feature and n the unit normal); for the inside of a box (SDF = max_i
/// (|p_i| - h_i)) it is 0. The distance is C¹ away from the medial axis (box diagonals inside,
/// capsule axis, mesh medial surfaces), so finite-difference checks must stay off feature
/// boundaries, as for distance.h.
///
/// Energy of a vertex x against a collider at pose (R, t):
///   p = Rᵀ (x - t),  d = dist(p),  g = d - offset,  E = b(g)  (b = contact_barrier, barrier.h)
///   ∇E = b'(g) R ∇d,   ∇²E = R [b''(g) ∇d ∇dᵀ + b'(g) ∇²d] Rᵀ
/// (the distance of the rigidly moved shape is invariant, so the chain rule only rotates). Since
/// b' < 0 and ∇²d is PSD outside convex features, the b' ∇²d term makes the exact Hessian
/// indefinite near edges and corners; HessianKind::kProjected applies project_psd<3>.
/// +INFINITY (zero derivatives) for g <= 0, 0 for g >= dhat.

#include <cmath>
#include <functional>
#include <memory>
#include <vector>

#include <Eigen/Geometry>

#include "sim/contact/barrier.h"
#include "sim/contact/distance.h"
#include "sim/energy/psd_project.h"
#include "sim/energy/table_friction.h"
#include "sim/types.h"

namespace gd::sim {

/// Kind of collider shape.
enum class ColliderType : int {
  kBox = 0,      ///< centred box with half extents (local frame axes)
  kCapsule = 1,  ///< segment (0, 0, ±half_length) swept by a sphere of `radius`
  kPlane = 2,    ///< infinite plane {p : plane_normal · p = plane_offset}, free side along +normal
  kMesh = 3,     ///< triangles [mesh_first_tri, mesh_first_tri + mesh_tri_count) of a ColliderMeshView
};

/// Flat, trivially copyable description of a shape in its local frame (device friendly).
/// Only the fields of `type` are meaningful.
struct ColliderShape {
  ColliderType type = ColliderType::kBox;
  Vec3 half_extents = Vec3::Zero();  ///< box (m), all > 0
  Real radius = 0;                   ///< capsule (m), > 0
  Real half_length = 0;              ///< capsule (m), >= 0 (0: a sphere)
  Vec3 plane_normal = Vec3::UnitZ(); ///< plane unit normal (local), pointing to the free side
  Real plane_offset = 0;             ///< plane: n · p = plane_offset on the plane (m)
  int mesh_first_tri = 0;            ///< mesh: first triangle in ColliderMeshView::triangles
  int mesh_tri_count = 0;            ///< mesh: number of triangles
  /// mesh: the box around every triangle (local frame, centre and half extents; half extents 0:
  /// none). A point farther than mesh_cull outside it gets its distance to the box, a lower bound
  /// of the mesh's, instead of a pass over the triangles: exact for a barrier whose contact
  /// distance is at most mesh_cull, and safe for CCD (the point is at least that far from the
  /// mesh). The solver sets mesh_cull to twice the contact distance; infinity (the default) never
  /// culls.
  Vec3 mesh_center = Vec3::Zero();
  Vec3 mesh_half = Vec3::Zero();
  Real mesh_cull = Real(INFINITY);
  /// mesh: closed and convex (a URDF link's hull; tested for meshes of at most 4096 triangles):
  /// outside it the distance is a convex function, so CCD bounds only the motion towards it, as
  /// for a box (solver/step_bounds.h).
  bool mesh_convex = false;
};

/// Triangle storage of mesh colliders (device or host pointers). Triangle k has the vertices
/// vertices[triangles[k][0..2]]; indices are absolute into `vertices`, so several meshes can
/// share one packed array (see pack_colliders in the host part). Local-frame coordinates (m).
struct ColliderMeshView {
  const Vec3* vertices = nullptr;
  const Eigen::Vector3i* triangles = nullptr;
};

// ------------------------------------------------------------------------------------------------
// Distances in the local frame
// ------------------------------------------------------------------------------------------------

/// Signed distance (m) from p to the surface of the box [-half, half] (half > 0), negative
/// inside. Outside: d = |p - c|, c = clamp(p, -half, half), ∇d = (p - c)/d, ∇²d = (P_A - ∇d ∇dᵀ)/d
/// with P_A the projector onto the axes where |p_i| > half_i (face: 0; edge along axis e:
/// (I - e eᵀ - n nᵀ)/d; corner: (I - n nᵀ)/d). Inside or on the surface: d = max_i (|p_i| - half_i)
/// (<= 0), ∇d = sign(p_k) e_k for the maximising axis k (first on ties; sign(0) = +1), ∇²d = 0.
/// Pointers may be null.
GD_HD Real box_distance(const Vec3& p, const Vec3& half, Vec3* grad, Mat3* hess) {
  Real s[3];
  Real q[3];
  int k = 0;
  bool outside = false;
  for (int i = 0; i < 3; ++i) {
    s[i] = p[i] < Real(0) ? Real(-1) : Real(1);
    q[i] = fabs(p[i]) - half[i];
    if (q[i] > Real(0)) outside = true;
    if (q[i] > q[k]) k = i;
  }
  if (!outside) {
    if (grad) {
      grad->setZero();
      (*grad)[k] = s[k];
    }
    if (hess) hess->setZero();
    return q[k];
  }
  Vec3 r = Vec3::Zero();
  Mat3 P = Mat3::Zero();
  for (int i = 0; i < 3; ++i)
    if (q[i] > Real(0)) {
      r[i] = s[i] * q[i];
      P(i, i) = Real(1);
    }
  const Real d = r.norm();
  const Vec3 n = r / d;
  if (grad) *grad = n;
  if (hess) *hess = (P - n * n.transpose()) / d;
  return d;
}

/// Signed distance (m) from p to the surface of the capsule around the segment (0, 0, ±half_length)
/// with radius `radius`: D - radius with D the distance to the segment. ∇d = (p - c)/D (c the
/// closest segment point), ∇²d = (P - ∇d ∇dᵀ)/D with P = I - e_z e_zᵀ on the cylinder part
/// (|p_z| < half_length) and I on the caps. On the axis (D = 0) the normal is not defined: ∇d =
/// e_x on the cylinder part, ±e_z beyond the ends, ∇²d = 0. Pointers may be null.
GD_HD Real capsule_distance(const Vec3& p, Real radius, Real half_length, Vec3* grad, Mat3* hess) {
  const Real L = half_length;
  const bool cylinder = p.z() > -L && p.z() < L;
  const Real zc = cylinder ? p.z() : (p.z() >= L ? L : -L);
  const Vec3 r(p.x(), p.y(), p.z() - zc);
  const Real D = r.norm();
  if (!(D > Real(0))) {
    if (grad) *grad = cylinder ? Vec3(Vec3::UnitX()) : Vec3(Real(0), Real(0), p.z() < Real(0) ? Real(-1) : Real(1));
    if (hess) hess->setZero();
    return -radius;
  }
  const Vec3 n = r / D;
  if (grad) *grad = n;
  if (hess) {
    Mat3 P = Mat3::Identity();
    if (cylinder) P(2, 2) = Real(0);
    *hess = (P - n * n.transpose()) / D;
  }
  return D - radius;
}

/// Signed distance (m) from p to the plane n · p = offset (n unit): n · p - offset; ∇d = n, ∇²d = 0.
GD_HD Real plane_distance(const Vec3& p, const Vec3& n, Real offset, Vec3* grad, Mat3* hess) {
  if (grad) *grad = n;
  if (hess) hess->setZero();
  return n.dot(p) - offset;
}

namespace collider_detail {

/// Distance of p to the closest feature `region` of triangle (a, b, c) (as classified by
/// point_triangle_closest_feature), recomputed from that feature's own formula for accuracy:
///   face:   d = |ν·(p - a)| with ν the unit normal, ∇d = ±ν, ∇²d = 0;
///   edge:   r = w - (w·e) e (w = p - e0, e unit), d = |r|, ∇d = r/d, ∇²d = (I - e eᵀ - ∇d∇dᵀ)/d;
///   vertex: r = p - v, d = |r|, ∇d = r/d, ∇²d = (I - ∇d∇dᵀ)/d.
/// Returns the unsigned distance. At d = 0, ∇d is the triangle's unit normal (a, b, c right hand;
/// e_z if degenerate) and ∇²d = 0. Pointers may be null.
GD_HD Real triangle_feature_distance(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                                     PointTriangleRegion region, Vec3* grad, Mat3* hess) {
  const Vec3 nu_raw = (b - a).cross(c - a);
  const Vec3 nu = nu_raw.squaredNorm() > Real(0) ? Vec3(nu_raw.normalized()) : Vec3(Vec3::UnitZ());
  Vec3 r;
  bool edge = false;
  Vec3 e = Vec3::Zero();
  switch (region) {
    case PointTriangleRegion::kFace: {
      const Real s = nu.dot(p - a);
      if (grad) *grad = s < Real(0) ? Vec3(-nu) : nu;
      if (hess) hess->setZero();
      return fabs(s);
    }
    case PointTriangleRegion::kEdge01:
    case PointTriangleRegion::kEdge12:
    case PointTriangleRegion::kEdge20: {
      const Vec3& e0 = region == PointTriangleRegion::kEdge01 ? a : (region == PointTriangleRegion::kEdge12 ? b : c);
      const Vec3& e1 = region == PointTriangleRegion::kEdge01 ? b : (region == PointTriangleRegion::kEdge12 ? c : a);
      e = (e1 - e0).normalized();
      const Vec3 w = p - e0;
      r = w - w.dot(e) * e;
      edge = true;
      break;
    }
    case PointTriangleRegion::kVertex0:
      r = p - a;
      break;
    case PointTriangleRegion::kVertex1:
      r = p - b;
      break;
    default:
      r = p - c;
      break;
  }
  const Real d = r.norm();
  if (!(d > Real(0))) {
    if (grad) *grad = nu;
    if (hess) hess->setZero();
    return Real(0);
  }
  const Vec3 n = r / d;
  if (grad) *grad = n;
  if (hess) {
    *hess = (Mat3::Identity() - n * n.transpose()) / d;
    if (edge) *hess -= (e * e.transpose()) / d;
  }
  return d;
}

/// Closest feature of one triangle: writes region and closest point, returns squared distance.
GD_HD Real triangle_closest(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c,
                            PointTriangleRegion* region, Vec3* cp) {
  Vec3 w;
  *region = point_triangle_closest_feature(p, a, b, c, &w);
  *cp = w[0] * a + w[1] * b + w[2] * c;
  return (p - *cp).squaredNorm();
}

}  // namespace collider_detail

/// Unsigned distance (m) from p to the union of triangles [first, first + count) of `mesh`, by
/// brute force over the triangles (the host Collider uses a BVH for the same value), with the
/// derivatives of the closest triangle's closest feature (collider_detail::triangle_feature_distance;
/// on exact ties a face region is preferred, so a point over the diagonal of a quad sees the flat
/// face). +INFINITY (zero derivatives) for an empty range. Pointers may be null.
GD_HD Real mesh_distance(const Vec3& p, const ColliderMeshView& mesh, int first, int count, Vec3* grad,
                         Mat3* hess) {
  Real best = Real(INFINITY);
  int best_k = -1;
  PointTriangleRegion best_region = PointTriangleRegion::kFace;
  for (int k = first; k < first + count; ++k) {
    const Eigen::Vector3i& tri = mesh.triangles[k];
    PointTriangleRegion region;
    Vec3 cp;
    const Real d2 = collider_detail::triangle_closest(p, mesh.vertices[tri[0]], mesh.vertices[tri[1]],
                                                      mesh.vertices[tri[2]], &region, &cp);
    const bool better = d2 < best || (d2 == best && region == PointTriangleRegion::kFace &&
                                      best_region != PointTriangleRegion::kFace);
    if (better) {
      best = d2;
      best_k = k;
      best_region = region;
    }
  }
  if (best_k < 0) {
    if (grad) grad->setZero();
    if (hess) hess->setZero();
    return Real(INFINITY);
  }
  const Eigen::Vector3i& tri = mesh.triangles[best_k];
  return collider_detail::triangle_feature_distance(p, mesh.vertices[tri[0]], mesh.vertices[tri[1]],
                                                    mesh.vertices[tri[2]], best_region, grad, hess);
}

/// Distance (m) from a LOCAL point p to `shape` (signed for box/capsule/plane, unsigned for a mesh;
/// see the file comment), with gradient and Hessian wrt p when non-null. `mesh` is needed only for
/// kMesh (null or an empty range gives +INFINITY: no contact).
GD_HD Real collider_local_distance(const Vec3& p, const ColliderShape& shape, const ColliderMeshView* mesh,
                                   Vec3* grad, Mat3* hess) {
  switch (shape.type) {
    case ColliderType::kBox:
      return box_distance(p, shape.half_extents, grad, hess);
    case ColliderType::kCapsule:
      return capsule_distance(p, shape.radius, shape.half_length, grad, hess);
    case ColliderType::kPlane:
      return plane_distance(p, shape.plane_normal, shape.plane_offset, grad, hess);
    default:
      if (mesh == nullptr || mesh->triangles == nullptr) {
        if (grad) grad->setZero();
        if (hess) hess->setZero();
        return Real(INFINITY);
      }
      if (shape.mesh_half.maxCoeff() > 0) {  // far outside the bounding box: its distance is enough
        const Vec3 out = ((p - shape.mesh_center).cwiseAbs() - shape.mesh_half).cwiseMax(Real(0));
        const Real r = out.norm();
        if (r > shape.mesh_cull) {
          if (grad) *grad = (p - shape.mesh_center).cwiseSign().cwiseProduct(out) / r;
          if (hess) hess->setZero();
          return r;
        }
      }
      return mesh_distance(p, *mesh, shape.mesh_first_tri, shape.mesh_tri_count, grad, hess);
  }
}

/// Distance (m) from a WORLD point x to `shape` at pose (R, t) (x = R p + t), with the world
/// gradient R ∇d and Hessian R ∇²d Rᵀ when non-null.
GD_HD Real collider_world_distance(const Vec3& x, const Mat3& R, const Vec3& t, const ColliderShape& shape,
                                   const ColliderMeshView* mesh, Vec3* grad, Mat3* hess) {
  const Vec3 p = R.transpose() * (x - t);
  Vec3 gl;
  Mat3 Hl;
  const Real d = collider_local_distance(p, shape, mesh, grad ? &gl : nullptr, hess ? &Hl : nullptr);
  if (grad) *grad = R * gl;
  if (hess) *hess = R * Hl * R.transpose();
  return d;
}

/// The world-aligned box around `shape` at pose (R, t): centre *c and half extents *h (m). A box
/// or a mesh's bounding box turned by R, a capsule's box around its segment and sphere. False for
/// a plane (unbounded), and for a mesh without a bounding box (mesh_half all 0).
GD_HD bool collider_world_box(const Mat3& R, const Vec3& t, const ColliderShape& shape, Vec3* c, Vec3* h) {
  Vec3 lc = Vec3::Zero(), lh;
  switch (shape.type) {
    case ColliderType::kBox:
      lh = shape.half_extents;
      break;
    case ColliderType::kCapsule:
      lh = Vec3(shape.radius, shape.radius, shape.half_length + shape.radius);
      break;
    case ColliderType::kMesh:
      if (!(shape.mesh_half.maxCoeff() > 0)) return false;
      lc = shape.mesh_center, lh = shape.mesh_half;
      break;
    default:
      return false;
  }
  *c = R * lc + t;
  *h = R.cwiseAbs() * lh;
  return true;
}

// ------------------------------------------------------------------------------------------------
// Barrier energy
// ------------------------------------------------------------------------------------------------

/// Barrier energy (J) of a distance d (m) with derivatives grad_d, hess_d wrt the vertex (any
/// frame): g = d - offset, E = b(g) (contact_barrier), ∇E = b' ∇d, ∇²E = b'' ∇d∇dᵀ + b' ∇²d.
/// +INFINITY for g <= 0 and 0 for g >= dhat, both with zero derivatives. grad written when
/// non-null, hess when non-null and kind != kNone (kProjected: project_psd<3> of the exact one).
GD_HD Real collider_barrier_energy(Real d, const Vec3& grad_d, const Mat3& hess_d, Real offset, Real dhat,
                                   Real kappa, Vec3* grad, Mat3* hess, HessianKind kind) {
  const bool want_hess = hess != nullptr && kind != HessianKind::kNone;
  Real db, d2b;
  const Real E = contact_barrier(d - offset, dhat, kappa, &db, &d2b);
  if (db == Real(0)) {  // inactive or infinite
    if (grad) grad->setZero();
    if (want_hess) hess->setZero();
    return E;
  }
  if (grad) *grad = db * grad_d;
  if (want_hess) {
    *hess = d2b * (grad_d * grad_d.transpose()) + db * hess_d;
    if (kind == HessianKind::kProjected) project_psd<3>(hess);
  }
  return E;
}

/// Barrier energy (J) of a WORLD vertex x against `shape` at pose (R, t): see the file comment.
/// offset (m): extra clearance (e.g. half the cloth thickness), dhat (m) activation distance,
/// kappa (N/m) stiffness. Gradient (N) / Hessian (N/m) as in collider_barrier_energy. `mesh` only
/// for kMesh. Returns +INFINITY when the vertex is at or below the offset (inside a box, capsule
/// or behind a plane included): the line search must reject such a step.
GD_HD Real point_collider_energy(const Vec3& x, const Mat3& R, const Vec3& t, const ColliderShape& shape,
                                 Real offset, Real dhat, Real kappa, Vec3* grad, Mat3* hess,
                                 HessianKind kind = HessianKind::kProjected,
                                 const ColliderMeshView* mesh = nullptr) {
  const bool want_hess = hess != nullptr && kind != HessianKind::kNone;
  Vec3 gd;
  Mat3 Hd;
  const Real d = collider_world_distance(x, R, t, shape, mesh, &gd, want_hess ? &Hd : nullptr);
  if (!want_hess) Hd.setZero();
  return collider_barrier_energy(d, gd, Hd, offset, dhat, kappa, grad, hess, kind);
}

// ------------------------------------------------------------------------------------------------
// Friction
// ------------------------------------------------------------------------------------------------

/// Lagged smoothed friction (J) of a vertex against a moving collider surface:
///   u = Tᵀ ((x - x_t) - s),  E = mu lambda f0(|u|)   (f0 as in plane_friction_energy)
/// x, x_t: vertex now and at step start (m); s = surface_displacement: how far the collider's
/// surface point under the vertex moves over the step (m, collider_surface_displacement); T: 3x2
/// tangent basis of the lagged contact normal; lambda: lagged normal force (N); eps = eps_v h (m).
/// Gradient (N) has magnitude mu lambda when the relative slip |u| >= eps, opposing it; Hessian
/// PSD (exact = projected). Pointers may be null.
GD_HD Real point_collider_friction(const Vec3& x, const Vec3& x_t, const Vec3& surface_displacement,
                                   const Eigen::Matrix<Real, 3, 2>& T, Real mu, Real lambda, Real eps,
                                   Vec3* grad, Mat3* hess) {
  return plane_friction_energy(x - surface_displacement, x_t, T, mu, lambda, eps, grad, hess);
}

/// Displacement (m) over a step of the collider's material point at world position c when the
/// pose moves from (R0, t0) to (R1, t1):  R1 R0ᵀ (c - t0) + t1 - c.
GD_HD Vec3 collider_surface_displacement(const Vec3& c, const Mat3& R0, const Vec3& t0, const Mat3& R1,
                                         const Vec3& t1) {
  return R1 * (R0.transpose() * (c - t0)) + t1 - c;
}

/// Lagged friction data of one vertex-collider contact (evaluated at step start).
struct ColliderContactFrame {
  Real distance;                ///< distance of x_t to the shape (m; see collider_local_distance)
  Vec3 normal;                  ///< world unit normal at the closest point (∇d)
  Vec3 closest;                 ///< world closest surface point x_t - d n
  Eigen::Matrix<Real, 3, 2> T;  ///< tangent basis of `normal` (plane_tangent_basis)
  Real lambda;                  ///< normal force -b'(d - offset) (N); 0 when inactive or penetrating
  Vec3 surface_displacement;    ///< motion of `closest` from pose 0 to pose 1 (m)
};

/// Friction frame of a vertex at its step-start position x_t against `shape`, whose pose is
/// (R0, t0) at step start and (R1, t1) at step end. lambda is contact_normal_force's value, except
/// that a penetrating start (gap <= 0) gives 0 instead of +INFINITY so kernels stay finite.
/// Skip contacts with lambda == 0.
GD_HD ColliderContactFrame collider_contact_frame(const Vec3& x_t, const Mat3& R0, const Vec3& t0,
                                                  const Mat3& R1, const Vec3& t1, const ColliderShape& shape,
                                                  Real offset, Real dhat, Real kappa,
                                                  const ColliderMeshView* mesh = nullptr) {
  ColliderContactFrame f;
  f.distance = collider_world_distance(x_t, R0, t0, shape, mesh, &f.normal, nullptr);
  if (!(f.normal.squaredNorm() > Real(0))) f.normal = Vec3::UnitZ();  // no mesh given
  f.closest = x_t - f.distance * f.normal;
  if (!(fabs(f.distance) < Real(INFINITY))) f.closest = x_t;
  plane_tangent_basis(f.normal, &f.T);
  const Real g = f.distance - offset;
  f.lambda = g > Real(0) ? contact_normal_force(f.distance, offset, dhat, kappa) : Real(0);
  f.surface_displacement = collider_surface_displacement(f.closest, R0, t0, R1, t1);
  return f;
}

}  // namespace gd::sim

// ================================================================================================
// Host part
// ================================================================================================
namespace gd::sim {

/// Result of a world-space distance query.
struct ColliderQuery {
  Real distance;  ///< signed distance (m): negative inside a box, capsule, closed mesh, behind a plane
  Vec3 closest;   ///< closest surface point (world, m)
  Vec3 normal;    ///< unit outward normal at `closest` (world; gradient of `distance`)
};

/// A rigid collider with a pose over time and a friction coefficient. Construct with the static
/// factories (they throw InputError on bad sizes, normals or meshes). Copies share the immutable
/// mesh data. The pose defaults to the identity; set_pose installs a function of scene time (s).
class Collider {
 public:
  using PoseFunction = std::function<Eigen::Isometry3d(double t)>;

  /// Box centred at the local origin, half extents > 0 (m).
  static Collider box(Vec3 half_extents);
  /// Capsule around the local z axis: radius > 0 (m), half_length >= 0 (m; 0 gives a sphere).
  static Collider capsule(Real radius, Real half_length);
  /// Infinite plane through `point` with normal `normal` (any non-zero length; normalised),
  /// in the local frame; the free side is along +normal.
  static Collider plane(Vec3 point, Vec3 normal);
  /// Triangle mesh in the local frame (m). Needs >= 1 triangle, finite vertices, indices in range,
  /// no repeated index and no zero-area triangle. Closed, consistently oriented meshes (each edge
  /// in exactly two triangles, traversed in opposite directions) get signed queries.
  static Collider mesh(std::vector<Vec3> vertices, std::vector<Eigen::Vector3i> tris);

  ColliderType type() const { return shape_.type; }
  /// Flat description; for a mesh, mesh_first_tri = 0 and indices refer to mesh_vertices().
  const ColliderShape& shape() const { return shape_; }
  const std::vector<Vec3>& mesh_vertices() const;
  const std::vector<Eigen::Vector3i>& mesh_triangles() const;
  /// True for a closed, consistently oriented mesh (queries are signed); false for other shapes.
  bool mesh_closed() const;

  /// Installs the pose function (x_world = pose(t) * x_local). Throws InputError if empty.
  void set_pose(PoseFunction pose);
  /// The pose at time t as the function returns it (identity when none set); not checked.
  Eigen::Isometry3d pose(double t) const;
  /// The pose at time t; throws InputError naming t if it has non-finite entries or its linear
  /// part is not a rotation (|RᵀR - I| > 1e-6 or det R <= 0).
  Eigen::Isometry3d checked_pose(double t) const;

  /// Coulomb friction coefficient (>= 0, finite; InputError otherwise). Default 0.
  void set_friction(Real mu);
  Real friction() const { return mu_; }
  /// Multiplies the barrier stiffness of cloth vertices against this collider (finite, > 0;
  /// InputError otherwise). Default 1: a vertex's own weight is balanced at half the contact
  /// distance. A gripper pad that must squeeze cloth with newtons of force needs far more
  /// (tasks/robot_arms.h: the grip force over the weight of the cloth under a pad).
  void set_stiffness_scale(Real scale);
  Real stiffness_scale() const { return kappa_scale_; }
  /// A yielding collider's pose is a target it may fall short of within a step: where the cloth
  /// cannot get out of its way in time (a gripper pad pushing a stack of pinched layers, which the
  /// predictor can only move one layer at a time), the solver stops it part of the way, where the
  /// step's starting guess keeps half the clearance it had from it at the step's start, and reports
  /// how far it got (Scene::collider_reached); its owner starts the next step from there. Default
  /// false: the pose function is followed exactly.
  void set_yielding(bool yielding) { yielding_ = yielding; }
  bool yielding() const { return yielding_; }
  /// Yielding colliders with the same group id (>= 0) are parts of one rigid body, the two finger
  /// pads of one hand: where the cloth stops one of them short, all of them stop at the same
  /// fraction of their motion over the step. Pads stopped one by one opened the pinch they held by
  /// the lag of the pad pushing the cloth, and a hand sweeping across its pads' faces let the cloth
  /// go (docs/robot.md, "Pads that stop together"). Default -1: no group.
  void set_yield_group(int group) { yield_group_ = group; }
  int yield_group() const { return yield_group_; }

  /// A lower bound of the distance of a world point at `pose`, found without a query: for a mesh
  /// its distance to the box around the mesh (0 inside the box), -infinity for other shapes. The
  /// checks that only ask whether a point is clear of a mesh collider skip the query with it.
  Real distance_bound(const Vec3& x_world, const Eigen::Isometry3d& pose) const;
  /// Whether a world point is inside or on the surface (query(...).distance <= 0), skipping the
  /// query for a point outside a mesh's box.
  bool inside(const Vec3& x_world, const Eigen::Isometry3d& pose) const;

  /// Signed distance, closest point and normal of a world point at time t (checked_pose).
  ColliderQuery query(const Vec3& x_world, double t) const;
  ColliderQuery query(const Vec3& x_world, const Eigen::Isometry3d& pose) const;

  /// Distance in the LOCAL frame with gradient / Hessian (null allowed). Signed for closed meshes
  /// when `signed_mesh`, unsigned (as the GD_HD layer) otherwise. Meshes use the BVH.
  Real local_distance(const Vec3& p, bool signed_mesh, Vec3* grad, Mat3* hess) const;

  /// Barrier energy of a world vertex against this collider at `pose` (same value as
  /// point_collider_energy; meshes unsigned, via the BVH).
  Real energy(const Vec3& x_world, const Eigen::Isometry3d& pose, Real offset, Real dhat, Real kappa,
              Vec3* grad, Mat3* hess, HessianKind kind = HessianKind::kProjected) const;

  /// If x is closer than `gap` (m, >= 0) to the surface (or inside: signed distance), the point at
  /// distance exactly `gap` outside along the outward normal of its closest point; x otherwise.
  /// For a non-convex mesh the step is repeated (up to 16 times) until the gap is reached.
  /// Open meshes are unsigned: "outside" is the side x is on.
  Vec3 project_out(const Vec3& x_world, double t, Real gap) const;
  /// project_out for every point of a flat xyz array except those flagged in `skip` (one per
  /// point), the pose evaluated once and the points in parallel; non-finite points are left as
  /// they are. Throws InputError for a bad gap or pose.
  void project_out(std::vector<double>* x, const std::vector<int>& skip, double t, Real gap) const;
  /// The batch project_out with each point's gap capped by its clearance at the step's start: a point
  /// goes out to min(gap, max(floor, d0)), d0 its signed distance at `start` (same layout as x) from
  /// the surface at time t_start. A collider moving into the cloth then carries the cloth it already
  /// presses at the clearance it had, instead of lifting it off to `gap`: in a pinch, lifting the layer
  /// under a pad off by `gap` moves it that far towards the layer beneath, through it where the two
  /// lie closer (tests/sim/contact/collider_test.cpp). Throws InputError for a bad gap, floor or size.
  void project_out(std::vector<double>* x, const std::vector<int>& skip, double t, Real gap,
                   const std::vector<double>& start, double t_start, Real floor) const;
  /// The same at given poses (`pose` for x, `start_pose` for the start): where the solver stopped a
  /// yielding collider short of its pose function's.
  void project_out(std::vector<double>* x, const std::vector<int>& skip, const Eigen::Isometry3d& pose, Real gap,
                   const std::vector<double>& start, const Eigen::Isometry3d& start_pose, Real floor) const;

  /// Displacement (m) from time t0 to t1 of the collider's surface point closest to x_world at t0.
  Vec3 surface_displacement(const Vec3& x_world, double t0, double t1) const;

 private:
  struct MeshData;
  Collider() = default;
  Vec3 project_out(const Vec3& x_world, const Eigen::Isometry3d& pose, Real gap) const;
  void project_batch(std::vector<double>* x, const std::vector<int>& skip, const Eigen::Isometry3d& P, Real gap,
                     const std::vector<double>* start, const Eigen::Isometry3d& P0, Real floor) const;
  ColliderShape shape_;
  std::shared_ptr<const MeshData> mesh_;
  PoseFunction pose_;
  Real mu_ = 0;
  Real kappa_scale_ = 1;
  bool yielding_ = false;
  int yield_group_ = -1;
};

/// Packed shapes and mesh triangles of several colliders, e.g. for upload to a device: shapes[i]
/// is colliders[i].shape() with mesh_first_tri offset into `triangles`, and triangle indices
/// offset into `vertices`.
struct PackedColliders {
  std::vector<ColliderShape> shapes;
  std::vector<Vec3> vertices;
  std::vector<Eigen::Vector3i> triangles;
  ColliderMeshView view() const { return {vertices.data(), triangles.data()}; }
};
PackedColliders pack_colliders(const std::vector<Collider>& colliders);

}  // namespace gd::sim
